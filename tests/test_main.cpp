#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstdio>
#include <cstdlib>
#include <exception>

#include "core/log.hpp"
#include "core/parallel.hpp"

int main(int argc, char** argv) {
  tetfsi::logger().set_level(spdlog::level::warn);
  // TETFSI_THREADS=N runs the tests' own parallel loops at N threads too, as it does the
  // `tetfsi` runs they start (`TETFSI_THREADS=1 make test`: the whole suite at one thread).
  if (const char* t = std::getenv("TETFSI_THREADS"); t != nullptr && *t != '\0') {
    try {
      tetfsi::set_thread_count(tetfsi::requested_thread_count(""));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      return 2;
    }
  }
  doctest::Context ctx;
  ctx.applyCommandLine(argc, argv);
  return ctx.run();
}
