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

#include "core/checkpoint.hpp"

namespace tetfsi::tools {

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

}  // namespace tetfsi::tools
