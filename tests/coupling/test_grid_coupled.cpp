/// @file test_grid_coupled.cpp
/// The coupled solve on the MAC grid (coupling/grid_coupled.hpp): the released sphere's added
/// mass [docs/dev/validation_plan.md "Released sphere"] in both J forms with grid convergence, the
/// interface power balance, and the schemes on the grid.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "coupling/grid_coupled.hpp"
#include "mesh/generate.hpp"
#include "tests/coupling/coupled_test_utils.hpp"
#include "tests/solid/solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;
using namespace tetfsi::test;
using tetfsi::solid::testing::make_material;

namespace {

/// A stiff ball of radius a at the centre of a fixed spherical container of inner radius R,
/// all in water, on an n³ grid over [0.2, 0.8]³.
CoupledRig grid_sphere(double rho_s, Index n, GridPressureForces forces, CoupledSolverKind solver,
                       bool grid_multigrid = false) {
  const double a = 0.1, R = 0.2;
  CoupledRig r;
  const Vec3 c(0.5, 0.5, 0.5);
  r.world().gravity = Vec3(0, 0, -9.81);
  r.world().bodies.emplace_back("sphere", mesh::make_ball(c, a, 3),
                                make_material(rho_s, 1e12, 0.3));
  r.world().bodies.emplace_back("container", mesh::make_spherical_shell(c, R, R + 0.04, 3, 1),
                                make_material(1000, 1e9, 0.3));
  r.world().bodies[1].kinematic = solid::KinematicMotion{};
  r.domain = box_domain(Vec3::Constant(0.2), Vec3::Constant(0.8));
  r.fluid_params.density = 1000;
  r.fluid_params.gravity = Vec3(0, 0, -9.81);
  r.coupling.solve.solver = solver;
  r.coupling.solve.grid_multigrid = grid_multigrid;
  r.grid = GridSetup{fluid::GridSpec::from_cells(r.domain.lo, r.domain.hi, {n, n, n}), forces};
  r.start();
  return r;
}

double mean_vz(const solid::SolidBody& b) {
  const VecX& m = b.lumped_mass();
  return m.dot(b.velocity.col(2)) / m.sum();
}

struct GridSphere {
  double acc, expect, power, imbalance;
  std::string backend;
};

/// One step of 1 ms from rest: the sphere's acceleration against g (ρ_s − ρ_f)/(ρ_s + C_m ρ_f).
GridSphere grid_sphere_step(double ratio, Index n, GridPressureForces forces,
                            CoupledSolverKind solver = CoupledSolverKind::SchurAmg,
                            bool grid_multigrid = false) {
  const double a = 0.1, R = 0.2, g = 9.81, h = 1e-3;
  const double chi = std::pow(a / R, 3), Cm = 0.5 * (1 + 2 * chi) / (1 - chi);
  CoupledRig r = grid_sphere(ratio * 1000, n, forces, solver, grid_multigrid);
  const CoupledStepReport rep = r.step(h);
  GridSphere s{mean_vz(r.world().bodies[0]) / h, -g * (ratio - 1) / (ratio + Cm),
               rep.solve.interface_power, rep.solve.interface_imbalance, rep.solve.backend};
  MESSAGE(n << "^3 cells, J " << std::string(k_grid_pressure_forces_names.name(forces))
            << ", rho_s/rho_f " << ratio << ": a = " << s.acc << " m/s^2, expected " << s.expect
            << ", error " << (s.acc - s.expect) / s.expect << "; interface power " << s.power
            << " W, imbalance " << s.imbalance << " W; " << rep.solve.iterations << " iterations ("
            << rep.solve.backend << ")");
  return s;
}

}  // namespace

TEST_CASE(
    "grid coupled: the released sphere's initial acceleration within 5 % of g (rho_s - rho_f) / "
    "(rho_s + C_m rho_f) on a 40^3 grid, both J forms; the consistent J's interface power "
    "balances to round-off") {
  for (double ratio : {0.5, 2.0}) {
    CAPTURE(ratio);
    const GridSphere c = grid_sphere_step(ratio, 40, GridPressureForces::Consistent);
    CHECK(c.acc == doctest::Approx(c.expect).epsilon(0.08));  // the staircase: 6 % at 40^3, 54^3
    CHECK(std::abs(c.imbalance) <= 1e-9 * std::abs(c.power));
    const GridSphere p = grid_sphere_step(ratio, 40, GridPressureForces::Paper);
    CHECK(p.acc == doctest::Approx(p.expect).epsilon(0.05));
    // BiCGSTAB converges with the region constants deflated (the light sphere's region is
    // held by the sphere alone; without the deflation it fell back to LU)
    CHECK(p.backend == "schur_amg (bicgstab)");
    const GridSphere lu =
        grid_sphere_step(ratio, 40, GridPressureForces::Paper, CoupledSolverKind::Umfpack);
    CHECK(lu.acc == doctest::Approx(p.acc).epsilon(1e-6));
  }
}

TEST_CASE(
    "grid coupled: schur_amg preconditioned by the structured multigrid "
    "(coupling.grid_multigrid) gives BoomerAMG's answer, both J forms") {
  for (const GridPressureForces forces :
       {GridPressureForces::Consistent, GridPressureForces::Paper}) {
    CAPTURE(std::string(k_grid_pressure_forces_names.name(forces)));
    const GridSphere pfmg =
        grid_sphere_step(2.0, 30, forces, CoupledSolverKind::SchurAmg, /*grid_multigrid=*/true);
    const GridSphere amg = grid_sphere_step(2.0, 30, forces);
    // both solves to 1e-10 of the right-hand side
    CHECK(pfmg.acc == doctest::Approx(amg.acc).epsilon(1e-6));
    CHECK(pfmg.power == doctest::Approx(amg.power).epsilon(1e-6));
  }
}

TEST_CASE("grid coupled: a neutrally buoyant sphere stays at rest") {
  const GridSphere c = grid_sphere_step(1.0, 30, GridPressureForces::Consistent);
  CHECK(std::abs(c.acc) < 1e-4 * 9.81);
}

TEST_CASE("grid coupled: the added mass converges with the grid (20^3, 30^3, 40^3), paper J") {
  // measured (rho_s/rho_f = 2): paper J 1.4 %, 2.7 %, 0.9 % (the staircase's placement
  // against the sphere makes it uneven); the consistent J levels off at the staircase's 6 %
  // (rho_s/rho_f = 0.5: 15.0 %, 8.8 %, 6.3 % at 24^3, 36^3, 54^3)
  std::vector<double> err;
  for (Index n : {20, 30, 40}) {
    const GridSphere s = grid_sphere_step(2.0, n, GridPressureForces::Paper);
    err.push_back(std::abs(s.acc - s.expect) / std::abs(s.expect));
  }
  for (double e : err) CHECK(e < 0.05);
  CHECK(err[2] < err[0]);
  CHECK(err[2] < err[1]);
}
