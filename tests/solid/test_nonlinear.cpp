// Tests of solid/nonlinear_trapezoid.cpp (the nonlinear trapezoidal rule of [BatheSonnad80,
// Eqs. (1)–(7)] iterated by Newton, modified Newton and BFGS), SolidWorld's nonlinear
// integrators, and solve_static_iterated on Turek–Hron CSM1.
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/timer.hpp"
#include "solid/nonlinear_trapezoid.hpp"
#include "solid/static_solve.hpp"
#include "solid/world.hpp"
#include "solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

namespace {

/// A 0.1 × 0.1 × 0.4 m soft column clamped at its foot, with a deformed, moving state.
SolidBody column(double alpha = 0.0, double beta = 0.0) {
  SolidBody b = make_box_body("column", Vec3(0, 0, 0), Vec3(0.1, 0.1, 0.4), Vec3i(2, 2, 6),
                              make_material(1000.0, 1e5, 0.3, alpha, beta));
  for (Index i : nodes_at(b, 2, 0.0, 1.0)) b.pin_node(i);
  return b;
}

void pluck(SolidBody& b, double speed) {
  for (Index i = 0; i < b.num_nodes(); ++i) {
    const double z = b.rest_positions()(i, 2);
    if (b.is_fixed(3 * i)) continue;
    b.velocity(i, 0) = speed * z / 0.4;
    b.velocity(i, 1) = 0.3 * speed * z * z / 0.16;
  }
}

double energy(const SolidBody& b) {
  return b.kinetic_energy() + b.elastic_energy();
}

const IterationMethod kMethods[3] = {IterationMethod::Newton, IterationMethod::ModifiedNewton,
                                     IterationMethod::Bfgs};

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("nonlinear trapezoid: the tangent is -dg/du by finite differences") {
    SolidBody b = column(2.0, 0.003);
    pluck(b, 0.8);
    for (Index i = 0; i < b.num_nodes(); ++i)  // a large deformation: a sheared, bent column
      if (!b.is_fixed(3 * i))
        b.displacement(i, 0) = 0.15 * std::pow(b.rest_positions()(i, 2) / 0.4, 2);
    const double h = 0.01;
    const TrapezoidalEquilibrium eq(b, h, b.external_forces(Vec3(0, 0, -9.81)));
    VecX u = flat(b.velocity) * 1.3;
    for (Index i = 0; i < u.size(); ++i)
      if (b.is_fixed(i)) u[i] = 0.0;
    const MatX T = MatX(eq.tangent(u));
    CHECK((T - T.transpose()).norm() <= 1e-12 * T.norm());
    double worst = 0.0;
    for (Index j = 0; j < u.size(); j += 7) {
      if (b.is_fixed(j)) continue;
      const double eps = 1e-6;
      VecX up = u, um = u;
      up[j] += eps;
      um[j] -= eps;
      const VecX fd = -(eq.residual(up) - eq.residual(um)) / (2 * eps);
      worst = std::max(worst, (fd - T.col(j)).norm() / T.col(j).norm());
    }
    MESSAGE("tangent vs central differences: worst column relative error " << worst);
    CHECK(worst < 1e-6);
    // fixed DOFs: zero residual, eliminated rows
    const VecX g = eq.residual(u);
    for (Index i = 0; i < u.size(); ++i)
      if (b.is_fixed(i)) CHECK(g[i] == 0.0);
    // the seed's start: d¹ = dⁿ
    CHECK((eq.displacement(eq.start()) - VecX(flat(b.displacement))).norm() == 0.0);
  }

  TEST_CASE("nonlinear trapezoid: a free body falls with exactly g, all three methods") {
    for (IterationMethod m : kMethods) {
      SolidWorld w;
      w.bodies.push_back(make_box_body("cube", Vec3(0, 0, 1), Vec3(0.1, 0.1, 1.1), Vec3i(1, 1, 1),
                                       make_material(1000.0, 1e6, 0.3)));
      w.integrator = m == IterationMethod::Newton           ? Integrator::Newton
                     : m == IterationMethod::ModifiedNewton ? Integrator::ModifiedNewton
                                                            : Integrator::Bfgs;
      PhaseTimes times;
      for (int s = 0; s < 10; ++s) w.step(0.05, times);
      const double t = 0.5, z = -0.5 * 9.81 * t * t;
      CHECK(w.bodies[0].displacement.col(2).mean() == doctest::Approx(z).epsilon(1e-9));
      CHECK(w.bodies[0].velocity.col(2).mean() == doctest::Approx(-9.81 * t).epsilon(1e-9));
      CHECK(w.bodies[0].elastic_energy() < 1e-12);
    }
  }

  TEST_CASE("nonlinear trapezoid: small undamped swings conserve energy (average acceleration)") {
    SolidWorld w;
    w.gravity = Vec3::Zero();
    w.bodies.push_back(column());
    pluck(w.bodies[0], 0.01);  // ~1 mm: linear
    w.integrator = Integrator::Bfgs;
    w.equilibrium.rtol = 1e-9;
    w.equilibrium.etol = 1e-16;
    const double e0 = energy(w.bodies[0]);
    PhaseTimes times;
    double worst = 0.0;
    for (int s = 0; s < 200; ++s) {
      w.step(0.01, times);  // ~ 12 steps per period of the first bending mode
      worst = std::max(worst, std::abs(energy(w.bodies[0]) - e0) / e0);
    }
    MESSAGE("200 steps of 0.01 s: worst relative energy change " << worst);
    CHECK(worst < 1e-5);
    // the linearized paper rule loses energy on the same swing (Newmark γ = 1)
    SolidWorld lin;
    lin.gravity = Vec3::Zero();
    lin.bodies.push_back(column());
    pluck(lin.bodies[0], 0.01);
    for (int s = 0; s < 200; ++s) lin.step(0.01, times);
    CHECK(energy(lin.bodies[0]) < 0.7 * e0);
  }

  TEST_CASE("nonlinear trapezoid: Newton, modified Newton and BFGS agree on a large swing") {
    std::vector<std::vector<double>> tip(3);
    std::vector<double> avg(3), worst_e(3);
    for (int k = 0; k < 3; ++k) {
      SolidWorld w;
      w.gravity = Vec3::Zero();
      w.bodies.push_back(column(0.0, 0.001));
      pluck(w.bodies[0], 1.5);  // tip travels ~ 0.15 m on a 0.4 m column: geometric nonlinearity
      w.integrator = k == 0   ? Integrator::Newton
                     : k == 1 ? Integrator::ModifiedNewton
                              : Integrator::Bfgs;
      w.equilibrium.rtol = 1e-7;
      w.equilibrium.etol = 1e-14;
      w.equilibrium.max_iterations = 100;
      const Index a = closest_node(w.bodies[0], Vec3(0.1, 0.1, 0.4));
      PhaseTimes times;
      int total = 0;
      for (int s = 0; s < 40; ++s) {
        const SolidStepReport r = w.step(0.01, times);
        total += r.equilibrium_iterations;
        tip[k].push_back(w.bodies[0].displacement(a, 0));
      }
      avg[k] = total / 40.0;
      MESSAGE(std::string(to_string(w.integrator))
              << ": " << avg[k] << " iterations per step, tip x " << tip[k].back());
    }
    double amp = 0.0, diff = 0.0;
    for (size_t s = 0; s < tip[0].size(); ++s) {
      amp = std::max(amp, std::abs(tip[0][s]));
      diff = std::max({diff, std::abs(tip[1][s] - tip[0][s]), std::abs(tip[2][s] - tip[0][s])});
    }
    MESSAGE("tip amplitude " << amp << " m, largest difference between methods " << diff << " m");
    CHECK(amp > 0.05);
    CHECK(diff < 1e-5 * amp);
    CHECK(avg[0] <= avg[2]);
    CHECK(avg[2] <= avg[1]);
  }

  TEST_CASE("nonlinear trapezoid: non-convergence is a SolverError naming body and method") {
    SolidWorld w;
    w.gravity = Vec3::Zero();
    w.bodies.push_back(column());
    pluck(w.bodies[0], 1.5);
    w.integrator = Integrator::ModifiedNewton;
    w.equilibrium.max_iterations = 2;
    w.equilibrium.rtol = 1e-12;
    const MatX3 d0 = w.bodies[0].displacement;
    PhaseTimes times;
    try {
      w.step(0.02, times);
      FAIL("expected a SolverError");
    } catch (const SolverError& e) {
      const std::string msg = e.what();
      CHECK(msg.find("column") != std::string::npos);
      CHECK(msg.find("modified_newton") != std::string::npos);
      CHECK(msg.find("did not converge in 2 iterations") != std::string::npos);
    }
    CHECK(w.bodies[0].displacement == d0);  // left at tⁿ
    CHECK(w.time == 0.0);
    CHECK_THROWS_AS(parse_integrator("explicit"), InputError);
    CHECK(parse_integrator("bfgs") == Integrator::Bfgs);
  }

  TEST_CASE("Turek-Hron CSM1 by BFGS, modified Newton and Newton: the same answer") {
    const double x0 = 0.2 + std::sqrt(0.05 * 0.05 - 0.01 * 0.01);
    auto make = [&] {
      SolidBody body = make_box_body("csm1", Vec3(x0, 0.19, 0.0), Vec3(0.6, 0.21, 0.01),
                                     Vec3i(40, 4, 1), make_material(1000.0, 1.4e6, 0.4));
      for (Index i : nodes_at(body, 0, x0, 1.0)) body.pin_node(i);
      for (Index i = 0; i < body.num_nodes(); ++i) body.fix_dof(i, 2);
      return body;
    };
    SolidBody ref = make();
    StaticSolveOptions so;
    so.rel_tol = 1e-11;
    solve_static(ref, ref.external_forces(Vec3(0, -2.0, 0)), so);
    const Index a = closest_node(ref, Vec3(0.6, 0.2, 0.0));
    const double uy = ref.displacement(a, 1);
    MESSAGE("CSM1 40x4 (reference Newton): u_y(A) = " << uy);
    for (IterationMethod m : kMethods) {
      SolidBody b = make();
      EquilibriumOptions opt;
      opt.method = m;
      opt.rtol = 1e-7;  // the round-off floor of the force is ~2e-9 of the load here
      opt.etol = 1e-16;
      opt.max_iterations = 300;
      opt.line_search_newton = true;
      // an incremental analysis (10 load steps, the matrix formed at the start of each):
      // from d = 0 in one step modified Newton diverges (the initial stiffness has no
      // geometric stiffness and the linear solution stretches the flag)
      const EquilibriumReport rep =
          solve_static_iterated(b, b.external_forces(Vec3(0, -2.0, 0)), opt, 10);
      INFO(std::string(to_string(m)), ": ", rep.failure);
      REQUIRE(rep.converged);
      MESSAGE(std::string(to_string(m))
              << ": " << rep.iterations << " iterations, " << rep.factorizations
              << " factorizations, u_y(A) = " << b.displacement(a, 1));
      CHECK(b.displacement(a, 1) == doctest::Approx(uy).epsilon(1e-5));
      CHECK(b.displacement(a, 0) == doctest::Approx(ref.displacement(a, 0)).epsilon(1e-4));
    }
    // the flag bends 47 mm (66 mm on fine meshes: one cell layer of linear tets is stiff):
    // a rotation of ~0.2 rad at the tip, far from linear
    CHECK(uy < -0.04);
  }
}
