#pragma once
/// @file enum_names.hpp
/// One enum <-> name table per enum, the single source of its parse, to_string and names list:
///
///     inline constexpr EnumNames<Compression, 3> k_compression_names{
///         "compression", {{{Compression::LZ4, "lz4"}, {Compression::ZLib, "zlib"},
///                          {Compression::None, "none"}}}};
///     k_compression_names.parse("zlib");   // Compression::ZLib
///     k_compression_names.parse("lz5");    // InputError "unknown compression 'lz5': use lz4,
///                                          //   zlib or none"
///     k_compression_names.name(Compression::None);  // "none"
///     k_compression_names.names();         // {"lz4", "zlib", "none"} (table order)
///
/// A table may list only some values of an enum (a subset accepted in one place); name() of a
/// value it lacks is an InternalError (a bug: the caller passed a value the table does not
/// cover), parse() of an unknown name an InputError (bad input).
#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"

namespace tetfsi {

template <class E>
struct EnumName {
  E value;
  const char* name;
};

/// "a", "a or b", "a, b or c": how a list of choices reads in a message.
inline std::string or_list(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? " or " : ", ";
    out += names[i];
  }
  return out;
}

template <class E, std::size_t N>
struct EnumNames {
  const char* what;  ///< what the names name, for messages: "compression", "linear solver"
  std::array<EnumName<E>, N> table;

  /// The value named `name`. @throws InputError "unknown <what> '<name>': use a, b or c".
  E parse(std::string_view name) const {
    for (const auto& e : table)
      if (name == e.name) return e.value;
    throw InputError(fmt::format("unknown {} '{}': use {}", what, name, or_list(names())));
  }

  /// Whether `name` is one of the names.
  bool contains(std::string_view name) const {
    for (const auto& e : table)
      if (name == e.name) return true;
    return false;
  }

  /// The name of `value`. @throws InternalError if the table does not list it.
  const char* name(E value) const {
    for (const auto& e : table)
      if (e.value == value) return e.name;
    throw InternalError(
        fmt::format("no name for {} value {}", what, static_cast<long long>(value)));
  }

  /// Every name, in table order.
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    out.reserve(N);
    for (const auto& e : table) out.emplace_back(e.name);
    return out;
  }
};

}  // namespace tetfsi
