// Tests of core/timer.hpp / core/timer.cpp.
#include <doctest/doctest.h>

#include "core/timer.hpp"

using namespace tetfsi;

TEST_SUITE("unit") {
  TEST_CASE("PhaseTimes accumulates per phase in first-use order") {
    PhaseTimes t;
    CHECK(t.entries().empty());
    CHECK(t.get("missing") == 0.0);
    t.add("solve", 1.5);
    t.add("assemble", 0.25);
    t.add("solve", 2.0);
    REQUIRE(t.entries().size() == 2);
    CHECK(t.entries()[0].first == "solve");
    CHECK(t.entries()[1].first == "assemble");
    CHECK(t.get("solve") == doctest::Approx(3.5).epsilon(1e-15));
    CHECK(t.get("assemble") == doctest::Approx(0.25).epsilon(1e-15));
    t.reset();
    REQUIRE(t.entries().size() == 2);  // names and order kept
    CHECK(t.entries()[0].first == "solve");
    CHECK(t.get("solve") == 0.0);
    CHECK(t.get("assemble") == 0.0);
  }

  TEST_CASE("ScopedTimer adds its elapsed time once on stop or destruction") {
    PhaseTimes t;
    double stopped = 0.0;
    {
      ScopedTimer a(t, "a");
      ScopedTimer b(t, "b");
      stopped = b.stop();
      CHECK(stopped >= 0.0);
      CHECK(b.stop() == 0.0);  // later stops add nothing
      CHECK(t.get("b") == doctest::Approx(stopped).epsilon(1e-15));
      CHECK(t.entries().size() == 1);  // "a" still running
    }
    REQUIRE(t.entries().size() == 2);
    CHECK(t.entries()[0].first == "b");  // order of first add, not of construction
    CHECK(t.entries()[1].first == "a");
    CHECK(t.get("b") == doctest::Approx(stopped).epsilon(1e-15));  // not added again
    CHECK(t.get("a") >= 0.0);
    const double before = now_seconds();
    CHECK(now_seconds() >= before);  // steady clock is monotonic
  }

}  // TEST_SUITE
