#pragma once
/// @file error.hpp
/// One error family for tetfsi and the always-on check macro.
///
/// Every error carries a one-line message that names the file, key or element at fault and
/// says what to do. The CLI prints `error: <message>` and exits non-zero.
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace tetfsi {

/// Base class of every error tetfsi throws on purpose.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& msg) : std::runtime_error(msg) {}
};
/// Bad user input: scene files, command-line values, unreadable files.
class InputError : public Error {
 public:
  using Error::Error;
};
/// Broken geometry: inverted or degenerate elements, open surfaces, bad indices.
class MeshError : public Error {
 public:
  using Error::Error;
};
/// A linear or nonlinear solve that failed or diverged.
class SolverError : public Error {
 public:
  using Error::Error;
};
/// An internal invariant did not hold (a bug, not bad input).
class InternalError : public Error {
 public:
  using Error::Error;
};

}  // namespace tetfsi

/// Always-on check (Release too): throws tetfsi::InternalError with file:line and message.
/// The message is a fmt format string: `TETFSI_CHECK(n > 0, "need n > 0, got {}", n)`.
#define TETFSI_CHECK(cond, ...)                                                                  \
  do {                                                                                           \
    if (!(cond)) [[unlikely]] {                                                                  \
      throw ::tetfsi::InternalError(::fmt::format("{}:{}: check '{}' failed: {}", __FILE__,      \
                                                  __LINE__, #cond, ::fmt::format(__VA_ARGS__))); \
    }                                                                                            \
  } while (0)

/// Check that throws a chosen error type with just the message (for user-facing checks).
#define TETFSI_REQUIRE(ErrorType, cond, ...)       \
  do {                                             \
    if (!(cond)) [[unlikely]] {                    \
      throw ErrorType(::fmt::format(__VA_ARGS__)); \
    }                                              \
  } while (0)
