// core/types.hpp: floor_index against the cast of std::floor it stands for.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/types.hpp"

using namespace tetfsi;

TEST_CASE("floor_index: the cast of std::floor, at integers, beside them and at random") {
  std::vector<double> q{0.0,  -0.0,   0.5,     -0.5, 1.0,  -1.0,         2.999999999999, -3.0,
                        -3.5, 1e-300, -1e-300, 1e9,  -1e9, 2147483646.5, -2147483647.5};
  // each integer and its neighbours one unit in the last place away
  for (int k = -40; k <= 40; ++k) {
    const double x = k;
    q.push_back(x);
    q.push_back(std::nextafter(x, -1e300));
    q.push_back(std::nextafter(x, 1e300));
    q.push_back(x / 7.0);  // quotients as the grid's, rounded
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-1e6, 1e6);
  for (int n = 0; n < 100000; ++n) q.push_back(uni(rng));
  int differ = 0;
  for (const double x : q) differ += floor_index(x) == static_cast<Index>(std::floor(x)) ? 0 : 1;
  CHECK(differ == 0);
  CHECK(floor_index(-0.25) == -1);  // a negative non-integer rounds down, not toward zero
  CHECK(floor_index(-2.0) == -2);
  CHECK(floor_index(2.75) == 2);
}
