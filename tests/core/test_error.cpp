// Tests of core/error.hpp: the error family and the check macros.
#include <doctest/doctest.h>

#include <string>

#include "core/error.hpp"

using namespace tetfsi;

TEST_SUITE("unit") {
  TEST_CASE("TETFSI_CHECK throws InternalError with location and formatted message") {
    CHECK_NOTHROW(TETFSI_CHECK(1 + 1 == 2, "never {}", "shown"));
    try {
      const int n = -3;
      TETFSI_CHECK(n > 0, "need n > 0, got {}", n);
      FAIL("no throw");
    } catch (const InternalError& e) {
      const std::string msg = e.what();
      CHECK(msg.find("test_error.cpp") != std::string::npos);
      CHECK(msg.find("n > 0") != std::string::npos);
      CHECK(msg.find("got -3") != std::string::npos);
    }
  }

  TEST_CASE("TETFSI_REQUIRE throws the chosen type with just the message") {
    try {
      TETFSI_REQUIRE(InputError, false, "bad key '{}'", "dt");
      FAIL("no throw");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()) == "bad key 'dt'");
    }
    // Every tetfsi error is a tetfsi::Error and a std::runtime_error.
    CHECK_THROWS_AS(TETFSI_REQUIRE(SolverError, false, "x"), Error);
    CHECK_THROWS_AS(TETFSI_REQUIRE(MeshError, false, "x"), std::runtime_error);
  }

}  // TEST_SUITE
