/// Tests of the interface half cells' lengths with the spreading of the body's normals
/// (coupling/half_cells.hpp); on a fluid mesh, tests/coupling/test_coupled.cpp.
#include <doctest/doctest.h>

#include <cmath>

#include "coupling/half_cells.hpp"
#include "mesh/generate.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;

namespace {

/// 3 ∫₀¹ (1 − t)² (1 + e t)⁻⁴ dt by Simpson's rule on 20,000 intervals: δ_eff/δ off a sphere
/// (e = δ/a) or inside one (e = −δ/a).
double sphere_factor(double e) {
  const int n = 20000;
  auto f = [e](double t) { return (1 - t) * (1 - t) / std::pow(1 + e * t, 4); };
  double s = f(0) + f(1);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4 : 2) * f(static_cast<double>(i) / n);
  return 3 * s / (3.0 * n);
}

}  // namespace

TEST_CASE(
    "half cells: a triangle on a sphere offset along the sphere's normals grows as "
    "(1 + s/a)^2, outward and inward") {
  const double a = 0.1;
  const Vec3 c(0.5, 0.4, 0.3);
  const mesh::SurfaceMesh s = mesh::make_icosphere(c, a, 2);
  double worst = 0.0;
  for (Index t = 0; t < s.num_triangles(); ++t) {
    Vec3 p[3], n[3];
    for (int k = 0; k < 3; ++k) {
      p[k] = s.vertices.row(s.triangles(t, k)).transpose();
      n[k] = (p[k] - c) / a;
    }
    const TubeSpreading out = tube_spreading(p[0], p[1], p[2], n[0], n[1], n[2]);
    const TubeSpreading in = tube_spreading(p[0], p[1], p[2], -n[0], -n[1], -n[2]);
    worst = std::max({worst, std::abs(out.c1 * a / 2 - 1), std::abs(out.c2 * a * a - 1),
                      std::abs(in.c1 * a / 2 + 1), std::abs(in.c2 * a * a - 1)});
  }
  MESSAGE("worst relative error of c1 = +-2/a, c2 = 1/a^2: " << worst);
  CHECK(worst < 1e-12);
  // a plane does not spread
  const TubeSpreading flat = tube_spreading(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0),
                                            Vec3::UnitZ(), Vec3::UnitZ(), Vec3::UnitZ());
  CHECK(flat.c1 == 0.0);
  CHECK(flat.c2 == 0.0);
}

TEST_CASE(
    "half cells: delta_eff / delta is 1 on a plane, the sphere's integral off a convex and "
    "inside a concave sphere (1/(1 +- delta/a)), at most 4") {
  const double a = 0.1;
  CHECK(half_cell_spreading(TubeSpreading{}, 0.01) == 1.0);
  for (double delta : {0.001, 0.005, 0.01, 0.02}) {
    const double e = delta / a;
    const double convex = half_cell_spreading({2 / a, 1 / (a * a)}, delta),
                 concave = half_cell_spreading({-2 / a, 1 / (a * a)}, delta);
    MESSAGE("delta/a = " << e << ": convex " << convex << " (integral " << sphere_factor(e)
                         << "), concave " << concave << " (" << sphere_factor(-e) << ")");
    CHECK(std::abs(convex - sphere_factor(e)) < 1e-6);
    CHECK(std::abs(concave - sphere_factor(-e)) < 1e-6);
    // the integral is 1/(1 + e): δ_eff = δ a/(a + δ) off a sphere, δ a/(a − δ) inside one
    CHECK(std::abs(sphere_factor(e) - 1 / (1 + e)) < 1e-12);
    CHECK(std::abs(sphere_factor(-e) - 1 / (1 - e)) < 1e-12);
    CHECK(convex < 1.0);
    CHECK(concave > 1.0);
  }
  // a cavity of radius 1.1 δ: the tube would close within the half cell; held at A(0)/2
  const double tight = half_cell_spreading({-2 / a, 1 / (a * a)}, 0.9 * a);
  MESSAGE("delta = 0.9 a inside a sphere: " << tight);
  CHECK(tight > 2.0);
  CHECK(tight <= 4.0);
}
