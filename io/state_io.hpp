#pragma once
/// @file state_io.hpp
/// Scalar fields of the run's plain structs to and from checkpoint records
/// (core/checkpoint.hpp), one record per field, named `prefix + field`. A struct lists its
/// fields once, in a `visit(s, f)` calling f("name", s.member) for each, and both directions
/// use that list:
/// ```cpp
/// template <class S, class F> void visit_fields(S& s, F&& f) { f("steps", s.steps); ... }
/// visit_fields(summary, RecordSaver{w, "run/equilibrium/"});
/// visit_fields(summary, RecordLoader{r, "run/equilibrium/"});
/// ```
/// Doubles keep their bits (a resumed run's summary is the continuous run's); integers of
/// any width go through i64; strings are text records.
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "core/checkpoint.hpp"

namespace tetfsi::app {

struct RecordSaver {
  CheckpointWriter& w;
  std::string prefix;
  template <class T>
  void operator()(const char* name, const T& v) const {
    if constexpr (std::is_floating_point_v<T>)
      w.put(prefix + name, static_cast<double>(v));
    else if constexpr (std::is_integral_v<T>)
      w.put(prefix + name, static_cast<std::int64_t>(v));
    else
      w.put(prefix + name, std::string(v));
  }
};

struct RecordLoader {
  const CheckpointReader& r;
  std::string prefix;
  template <class T>
  void operator()(const char* name, T& v) const {
    if constexpr (std::is_floating_point_v<T>)
      v = static_cast<T>(r.get_double(prefix + name));
    else if constexpr (std::is_same_v<T, bool>)
      v = r.get_int(prefix + name) != 0;
    else if constexpr (std::is_integral_v<T>)
      v = static_cast<T>(r.get_int(prefix + name));
    else
      v = r.get_text(prefix + name);
  }
};

/// A list of strings (none holding '\n') as one text record, a line each, and back.
inline void put_lines(CheckpointWriter& w, const std::string& key,
                      const std::vector<std::string>& lines) {
  std::string s;
  for (const std::string& x : lines) s += x + '\n';
  w.put(key, s);
}

inline std::vector<std::string> get_lines(const CheckpointReader& r, const std::string& key) {
  const std::string s = r.get_text(key);
  std::vector<std::string> v;
  std::size_t start = 0;
  while (start < s.size()) {
    const std::size_t end = s.find('\n', start);
    v.push_back(s.substr(start, end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return v;
}

}  // namespace tetfsi::app
