/// Tests of the iterated coupled schemes (coupling/coupled_step.cpp: bfgs, modified_newton,
/// newton) [BatheSonnad80, Eqs. (6)–(15)]: they converge to the simultaneous answer, BFGS
/// learns the added mass the starting matrix of Eq. (15) leaves out, modified Newton cannot.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "tests/coupling/coupled_test_utils.hpp"
#include "tests/solid/solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;
using namespace tetfsi::test;
using solid::testing::make_material;

namespace {

/// A light clamped plate (ρ_s = 100, 0.4 × 0.4 × 0.02 m: 0.32 kg, no damping) in a unit box
/// of water open at the top, pushed up by its buoyancy; ~5 kg of added mass.
CoupledRig plate(Scheme scheme, double rtol = 1e-3, double etol = 1e-5, double E = 2e5) {
  CoupledRig r;
  r.world().gravity = Vec3(0, 0, -9.81);
  r.world().bodies.emplace_back(
      "plate", mesh::make_box(Vec3(0.3, 0.3, 0.45), Vec3(0.7, 0.7, 0.47), Vec3i(6, 6, 1)),
      make_material(100, E, 0.3));
  solid::SolidBody& b = r.world().bodies[0];
  for (Index i = 0; i < b.num_nodes(); ++i) {
    const double x = b.rest_positions()(i, 0);
    if (x < 0.3 + 1e-9 || x > 0.7 - 1e-9) b.pin_node(i);
  }
  r.world().trapezoid = solid::Trapezoid::Midpoint;  // the linearisation of the trapezoidal rule
  r.world().equilibrium.rtol = rtol;
  r.world().equilibrium.etol = etol;
  water_box_open_top(r);
  r.sizing = sizing(0.05, 0.15);
  r.coupling.scheme = scheme;
  r.start();
  return r;
}

double max_abs(const MatX3& m) {
  return m.cwiseAbs().maxCoeff();
}

}  // namespace

TEST_CASE("iterated schemes: newton and bfgs converge to the simultaneous answer") {
  // A stiff plate (E = 2 GPa), so that the simultaneous step's linearisation of K(d) is
  // accurate: the linearised midpoint rule is the linearisation of the trapezoidal rule the
  // iterated schemes solve, and what is left is that linearisation's error (measured, |u −
  // u_sim| / max|u| of newton at h = 1/120: 2.2e-3 at E = 20 MPa, 4.9e-5 at 2 GPa). At the
  // first step all runs mesh the same positions: a remesh around positions that differ
  // by round-off can connect the points differently, after which the runs differ by the
  // discretisation (measured: newton vs bfgs 1e-9 of |u| while the meshes agree, 1.6e-3 after
  // they part on the soft plate; the pressure then differs where the cells differ).
  const double h = 1.0 / 120, E = 2e9;
  CoupledRig sim = plate(Scheme::Simultaneous, 1e-3, 1e-5, E),
             newton = plate(Scheme::Newton, 1e-9, 1e-18, E),
             bfgs = plate(Scheme::Bfgs, 1e-9, 1e-18, E), loose = plate(Scheme::Bfgs, 1e-3, 1e-5, E);
  for (int n = 0; n < 2; ++n) {
    sim.step(h);
    const CoupledStepReport rn = newton.step(h), rb = bfgs.step(h), rl = loose.step(h);
    REQUIRE(rn.equilibrium.converged);
    const MatX3& u = sim.world().bodies[0].velocity;
    const double scale = max_abs(u);
    const double dn = max_abs(newton.world().bodies[0].velocity - u) / scale,
                 db = max_abs(bfgs.world().bodies[0].velocity - u) / scale,
                 dl = max_abs(loose.world().bodies[0].velocity - u) / scale,
                 nb = max_abs(newton.world().bodies[0].velocity - bfgs.world().bodies[0].velocity) /
                      scale;
    const VecX& p = sim.fluid().state().p;
    const double dp = (bfgs.fluid().state().p - p).cwiseAbs().maxCoeff() / p.cwiseAbs().maxCoeff();
    MESSAGE("step " << n + 1 << " (|u| " << scale << " m/s): newton " << rn.equilibrium.iterations
                    << " iterations (" << rn.fluid_solves << " fluid solves), bfgs "
                    << rb.equilibrium.iterations << " at RTOL 1e-9, " << rl.equilibrium.iterations
                    << " at RTOL 1e-3 (" << rl.fluid_solves
                    << " fluid solves); |u - u_sim| / max|u|: newton " << dn << ", bfgs " << db
                    << ", bfgs at RTOL 1e-3 " << dl << "; newton vs bfgs " << nb
                    << "; pressure (bfgs) " << dp);
    if (n == 0) {  // the same mesh for all four
      CHECK(dn < 2e-4);
      CHECK(db < 2e-4);
      CHECK(dl < 3e-3);  // RTOL = 1e-3
      CHECK(dp < 1e-4);
      CHECK(nb < 1e-7);
    }
    CHECK(rl.equilibrium.iterations <= 8);
  }
}

TEST_CASE("iterated schemes: modified Newton cannot learn the added mass - BFGS does") {
  // 0.32 kg of plate moving ~5 kg of water: the fixed matrix of Eq. (15) underestimates the
  // response by ~15x, a fixed-point iteration that amplifies its error each iteration.
  const double h = 1.0 / 30;
  CoupledRig mn = plate(Scheme::ModifiedNewton), bf = plate(Scheme::Bfgs);
  const MatX3 d0 = mn.world().bodies[0].displacement;
  try {
    mn.step(h);
    FAIL("expected modified Newton to fail");
  } catch (const SolverError& e) {
    const std::string msg = e.what();
    MESSAGE(msg);
    CHECK(msg.find("modified_newton") != std::string::npos);
    CHECK((msg.find("did not converge in 30 iterations") != std::string::npos ||
           msg.find("diverged") != std::string::npos));
  }
  CHECK(mn.world().bodies[0].displacement == d0);  // left at tⁿ
  CHECK(mn.world().time == 0.0);
  const CoupledStepReport r = bf.step(h);
  CHECK(r.equilibrium.converged);
  CHECK(r.equilibrium.updates >= 1);
}

TEST_CASE("iterated schemes: a liquid sealed in a body is refused with a clear error") {
  CoupledRig r;
  r.world().gravity = Vec3::Zero();
  r.world().bodies.emplace_back("balloon",
                                mesh::make_spherical_shell(Vec3(0.5, 0.5, 0.5), 0.15, 0.2, 2, 1),
                                make_material(1000, 1e5, 0.3));
  r.domain = box_domain(Vec3::Zero(), Vec3::Ones());
  r.fluid_params.density = 1000;
  r.fluid_params.gravity = Vec3::Zero();
  r.sizing = sizing(0.06, 0.2);
  r.coupling.scheme = Scheme::Bfgs;
  r.start();
  try {
    r.step(0.02);
    FAIL("expected an InputError");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("balloon") != std::string::npos);
    CHECK(msg.find("coupling.scheme simultaneous") != std::string::npos);
  }
  CHECK(parse_scheme("bfgs") == Scheme::Bfgs);
  CHECK(is_iterated(Scheme::Newton));
  CHECK_FALSE(is_iterated(Scheme::Splitting));
  CHECK_THROWS_AS(parse_scheme("gauss_seidel"), InputError);
}

TEST_CASE(
    "iterated schemes: with solid.starting_matrix added_mass modified Newton converges on the "
    "light plate and BFGS needs fewer iterations than with Eq. (15) alone") {
  // The lumped added mass (row sums of the fluid's response to the plate's unit
  // translations) overestimates the added mass of every bending mode a little, so the fixed
  // matrix's iteration contracts instead of amplifying its error ~15x per iteration.
  const double h = 1.0 / 30;
  CoupledRig mn = plate(Scheme::ModifiedNewton), bf = plate(Scheme::Bfgs),
             bf0 = plate(Scheme::Bfgs), tight = plate(Scheme::Bfgs, 1e-9, 1e-18);
  mn.world().equilibrium.starting_matrix = StartingMatrix::AddedMass;
  bf.world().equilibrium.starting_matrix = StartingMatrix::AddedMass;
  const CoupledStepReport rm = mn.step(h), rb = bf.step(h), r0 = bf0.step(h);
  tight.step(h);
  MESSAGE("modified Newton with the added mass: "
          << rm.equilibrium.iterations << " iterations; BFGS " << rb.equilibrium.iterations
          << " (without: " << r0.equilibrium.iterations << ")");
  CHECK(rm.equilibrium.converged);
  CHECK(rb.equilibrium.converged);
  CHECK(rb.equilibrium.iterations < r0.equilibrium.iterations);
  // the same step's answer as BFGS at RTOL 1e-9, to what RTOL 1e-3 leaves in the velocity
  const MatX3& u = tight.world().bodies[0].velocity;
  const auto err = [&](const CoupledRig& r) {
    return max_abs(r.sim->world().bodies[0].velocity - u) / max_abs(u);
  };
  MESSAGE("|u - u_tight| / max|u|: modified Newton " << err(mn) << ", BFGS with the added mass "
                                                     << err(bf) << ", without " << err(bf0));
  CHECK(err(mn) < 5e-3);
  CHECK(err(bf) < 5e-3);
}

TEST_CASE(
    "iterated schemes: with solid.starting_matrix coupled modified Newton and BFGS take "
    "Newton's iterations on the light plate and agree with the tight answer") {
  // The whole added mass in the kept matrix: what is left between the iterate and the
  // equilibrium is the change of the plate's stiffness within the step, as for Newton.
  const double h = 1.0 / 30;
  const int steps = 3;
  CoupledRig mn = plate(Scheme::ModifiedNewton), bf = plate(Scheme::Bfgs),
             nt = plate(Scheme::Newton), tight = plate(Scheme::Bfgs, 1e-9, 1e-18);
  mn.world().equilibrium.starting_matrix = StartingMatrix::Coupled;
  bf.world().equilibrium.starting_matrix = StartingMatrix::Coupled;
  int most_mn = 0, most_bf = 0, most_nt = 0;
  for (int k = 0; k < steps; ++k) {
    const CoupledStepReport rm = mn.step(h), rb = bf.step(h), rn = nt.step(h);
    tight.step(h);
    REQUIRE(rm.equilibrium.converged);
    REQUIRE(rb.equilibrium.converged);
    most_mn = std::max(most_mn, rm.equilibrium.iterations);
    most_bf = std::max(most_bf, rb.equilibrium.iterations);
    most_nt = std::max(most_nt, rn.equilibrium.iterations);
  }
  const MatX3& u = tight.world().bodies[0].velocity;
  const auto err = [&](const CoupledRig& r) {
    return max_abs(r.sim->world().bodies[0].velocity - u) / max_abs(u);
  };
  MESSAGE("most iterations per step over "
          << steps << " steps: modified Newton " << most_mn << ", BFGS " << most_bf << ", Newton "
          << most_nt << "; |u - u_tight| / max|u|: " << err(mn) << ", " << err(bf) << ", "
          << err(nt));
  CHECK(most_mn <= most_nt + 1);
  CHECK(most_bf <= most_nt + 1);
  CHECK(err(mn) < 5e-3);
  CHECK(err(bf) < 5e-3);
}
