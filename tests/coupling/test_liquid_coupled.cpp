/// @file test_liquid_coupled.cpp
/// A liquid with a free surface coupled to a soft body in the simultaneous solve
/// [Chentanez06, Eq. (7)] on the MAC grid: the load of a liquid column on the body's top.
#include <doctest/doctest.h>

#include <cmath>

#include "coupling/grid_coupled.hpp"
#include "mesh/generate.hpp"
#include "tests/coupling/coupled_test_utils.hpp"
#include "tests/solid/solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;
using namespace tetfsi::test;
using tetfsi::solid::testing::make_material;

TEST_CASE("liquid coupled: a soft slab under a liquid column of height H feels rho g H on top") {
  const double g = 9.81, rho = 1000, top = 0.16, surface = 0.36, H = surface - top;
  CoupledRig r;
  r.world().gravity = Vec3(0, 0, -g);
  r.world().bodies.emplace_back(
      "slab", mesh::make_box(Vec3(0.1, 0.1, 0.1), Vec3(0.3, 0.3, top), Vec3i(4, 4, 2)),
      make_material(1000, 2e5, 0.3, 2.0, 0.002));
  solid::SolidBody& slab = r.world().bodies[0];
  const MatX3 rest = slab.positions();
  for (Index v = 0; v < rest.rows(); ++v)
    if (rest(v, 2) < 0.1 + 1e-9) slab.pin_node(v);
  r.domain = box_domain(Vec3::Zero(), Vec3(0.4, 0.4, 0.5));
  r.fluid_params.density = rho;
  r.fluid_params.gravity = Vec3(0, 0, -g);
  r.fluid_params.liquid.enabled = true;
  fluid::LiquidRegion pool;
  pool.name = "pool";
  pool.lo = Vec3::Zero();
  pool.hi = Vec3(0.4, 0.4, surface);
  r.fluid_params.liquid.regions = {pool};
  r.grid = GridSetup{fluid::GridSpec::from_cells(r.domain.lo, r.domain.hi, {20, 20, 25}),
                     GridPressureForces::Paper};
  r.start();
  const double area = 0.2 * 0.2;
  double f_top = 0, drift = 0;
  for (int step = 1; step <= 40; ++step) {
    const CoupledStepReport rep = r.step(0.01);
    drift = std::max(drift, std::abs(rep.fluid.liquid_volume_drift));
    REQUIRE(rep.fluid.liquid_volume ==
            doctest::Approx(0.4 * 0.4 * surface - 0.2 * 0.2 * 0.06).epsilon(0.02));
    // no liquid cell inside the body: every cell holding a pressure unknown is outside it
    const fluid::GridCells& gc = r.grid_fluid().cells();
    Index inside = 0;
    for (Index c = 0; c < gc.grid.num_cells(); ++c) inside += gc.fluid(c) && gc.cell_body[c] >= 0;
    REQUIRE(inside == 0);
    const VecX f = r.sim->fluid_forces()[0];
    f_top = 0;
    for (Index v = 0; v < rest.rows(); ++v)
      if (rest(v, 2) > top - 1e-9) f_top += f[3 * v + 2];
  }
  const double load = -f_top / area;
  MESSAGE("top load " << load << " Pa, rho g H = " << rho * g * H << " Pa, error "
                      << load / (rho * g * H) - 1 << "; worst volume drift " << drift);
  CHECK(load == doctest::Approx(rho * g * H).epsilon(0.03));
  CHECK(drift < 0.01);
}
