/// Tests of solid/static_solve.cpp: patch test, cantilever under gravity against
/// Euler–Bernoulli, Turek & Hron CSM1.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "core/error.hpp"
#include "solid/static_solve.hpp"
#include "solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

namespace {

/// Pin every node with rest coordinate `axis` == value.
void clamp_face(SolidBody& body, int axis, double value, double scale) {
  for (Index i : nodes_at(body, axis, value, scale)) body.pin_node(i);
}

/// Result of one CSM1 run.
struct Csm1Result {
  double ux, uy;  ///< displacement of point A (m)
  int iterations;
  Index dofs;
};

/// Turek & Hron (2006) CSM1, plane strain. The flag 0.35 × 0.02 is "clamped to the
/// cylinder"; as is standard we clamp its left end at x0 = 0.2 + sqrt(0.05² − 0.01²)
/// (where the flag's top and bottom edges meet the cylinder) and ignore the cylinder's
/// curvature there. It is extruded one cell in z with every z-DOF fixed (plane strain).
Csm1Result run_csm1(int nx, int ny) {
  const double x0 = 0.2 + std::sqrt(0.05 * 0.05 - 0.01 * 0.01);
  const double dz = 0.01;
  // ρ_s = 1000, ν_s = 0.4, E = 1.4e6 (μ_s = 0.5e6), gravity (0, −2) [Turek & Hron 2006, CSM1].
  const Material mat = make_material(1000.0, 1.4e6, 0.4);
  SolidBody body =
      make_box_body("csm1", Vec3(x0, 0.19, 0.0), Vec3(0.6, 0.21, dz), Vec3i(nx, ny, 1), mat);
  clamp_face(body, 0, x0, 1.0);
  for (Index i = 0; i < body.num_nodes(); ++i) body.fix_dof(i, 2);  // plane strain
  StaticSolveOptions opts;
  opts.rel_tol = 1e-9;
  opts.load_steps = 1;  // Newton with line search converges from d = 0 (≈ 13 iterations)
  const StaticSolveReport rep = solve_static(body, body.external_forces(Vec3(0, -2.0, 0)), opts);
  CHECK(rep.converged);
  const Index a = closest_node(body, Vec3(0.6, 0.2, 0.0));
  REQUIRE((body.rest_positions().row(a).transpose() - Vec3(0.6, 0.2, 0.0)).norm() < 1e-12);
  return {body.displacement(a, 0), body.displacement(a, 1), rep.iterations, body.num_dofs()};
}

// Turek & Hron 2006, Table "CSM1": u_x(A) = −7.187e-3 m, u_y(A) = −66.10e-3 m.
constexpr double kCsm1Ux = -7.187e-3;
constexpr double kCsm1Uy = -66.10e-3;

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("patch test: an affine boundary displacement is reproduced inside") {
    const Material mat = make_material(1000.0, 1e6, 0.3);
    SolidBody body = make_box_body("patch", Vec3::Zero(), Vec3::Ones(), Vec3i(3, 3, 3), mat);
    // Jitter the interior nodes so the patch is irregular.
    // (make_box nodes are regular; the affine field must be reproduced on any mesh.)
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    Mat3 F;
    F << 1.10, 0.05, -0.03, 0.02, 0.95, 0.08, -0.04, 0.06, 1.05;  // moderate stretch + shear
    const Vec3 c(0.1, -0.2, 0.05);
    std::vector<Index> interior;
    for (Index i = 0; i < body.num_nodes(); ++i) {
      const Vec3 X = body.rest_positions().row(i);
      const bool on_boundary = (X.array() < 1e-12).any() || (X.array() > 1.0 - 1e-12).any();
      if (on_boundary) {
        body.pin_node(i);
        body.displacement.row(i) = ((F - Mat3::Identity()) * X + c).transpose();
      } else {
        interior.push_back(i);
      }
    }
    REQUIRE(interior.size() == 8);
    const VecX f_e = VecX::Zero(body.num_dofs());
    const StaticSolveReport rep = solve_static(body, f_e, {.rel_tol = 1e-12});
    CHECK(rep.converged);
    double max_err = 0.0;
    for (Index i : interior) {
      const Vec3 X = body.rest_positions().row(i);
      const Vec3 x_exact = F * X + c;
      const Vec3 x = X + body.displacement.row(i).transpose();
      max_err = std::max(max_err, (x - x_exact).norm() / x_exact.norm());
    }
    MESSAGE("patch test: max relative position error " << max_err << " after " << rep.iterations
                                                       << " Newton iterations");
    CHECK(max_err <=
          1e-8);  // docs/dev/validation_plan.md "Consistency": exact up to solver tolerance
    // Interior nodal forces vanish (relative to E · L², L = 1 m).
    const VecX K = body.elasticity().forces(body.positions());
    for (Index i : interior) CHECK(K.segment<3>(3 * i).norm() <= 1e-8 * mat.youngs_modulus);
    // Every tet carries the same strain E = ½(FᵀF − I).
    const double e_norm = (0.5 * (F.transpose() * F - Mat3::Identity())).norm();
    const TetFields fl = body.elasticity().tet_fields(body.positions());
    CHECK((fl.green_strain_norm.array() - e_norm).abs().maxCoeff() <= 1e-8 * e_norm);
  }

  TEST_CASE("static solve: fixed DOFs keep their value and a zero load is an equilibrium") {
    SolidBody body = make_box_body("b", Vec3::Zero(), Vec3(1, 0.2, 0.2), Vec3i(5, 1, 1),
                                   make_material(1000, 1e6, 0.3));
    clamp_face(body, 0, 0.0, 1.0);
    const StaticSolveReport rep = solve_static(body, VecX::Zero(body.num_dofs()));
    CHECK(rep.converged);
    CHECK(rep.iterations == 0);
    CHECK(body.displacement.norm() == 0.0);
  }

  TEST_CASE("static solve reports non-convergence as a SolverError naming the body") {
    SolidBody body = make_box_body("flag", Vec3::Zero(), Vec3(1, 0.1, 0.1), Vec3i(10, 1, 1),
                                   make_material(1000, 1e5, 0.3));
    clamp_face(body, 0, 0.0, 1.0);
    StaticSolveOptions opts;
    opts.max_iterations = 1;
    try {
      solve_static(body, body.external_forces(Vec3(0, -50.0, 0)), opts);
      FAIL("expected SolverError");
    } catch (const SolverError& e) {
      const std::string msg = e.what();
      CHECK(msg.find("body 'flag'") != std::string::npos);
      CHECK(msg.find("relative residual") != std::string::npos);
    }
  }

  TEST_CASE("cantilever under gravity converges to Euler-Bernoulli qL^4/(8EI)") {
    // Beam L × H × B with L/H = 20, ν = 0 (so plane stress, plane strain and the 3D beam
    // agree, and E/(1−ν²) = E), small load (w/L ≈ 6e-4, geometrically linear regime).
    // Euler–Bernoulli: w = q L⁴ / (8 E I), q = ρ g B H, I = B H³ / 12 (e.g. Gere & Timoshenko,
    // Mechanics of Materials, cantilever with uniform load). Timoshenko shear adds
    // (E/G)(H/L)²/(3κ) = 0.2% here, so the FE answer converges to ≈ 1.002 × w_EB.
    const double L = 1.0, H = 0.05, B = 0.05, rho = 1000.0, g = 9.81, E = 1e10;
    const double q = rho * g * B * H;
    const double I = B * H * H * H / 12.0;
    const double w_eb = q * std::pow(L, 4) / (8.0 * E * I);
    const Material mat = make_material(rho, E, 0.0);
    std::vector<double> errors;
    for (int ny : {1, 2, 4, 8}) {
      SolidBody body = make_box_body("cantilever", Vec3::Zero(), Vec3(L, H, B),
                                     Vec3i(20 * ny, ny, ny > 2 ? 2 : 1), mat);
      clamp_face(body, 0, 0.0, L);
      solve_static(body, body.external_forces(Vec3(0, -g, 0)));
      double w = 0.0;
      const auto tip = nodes_at(body, 0, L, L);
      for (Index i : tip) w += -body.displacement(i, 1) / static_cast<double>(tip.size());
      const double err = std::abs(w - w_eb) / w_eb;
      MESSAGE("cantilever: " << ny << " cells through the thickness (" << body.num_tets()
                             << " tets): tip w = " << w << " m, Euler-Bernoulli " << w_eb
                             << " m, rel. error " << err);
      errors.push_back(err);
    }
    for (std::size_t k = 1; k < errors.size(); ++k) CHECK(errors[k] < 0.7 * errors[k - 1]);
    // Linear tets lock in bending; 8 cells through the thickness (aspect 1) reach a few %.
    CHECK(errors.back() < 0.05);
  }

  TEST_CASE("Turek-Hron CSM1 on coarse meshes: converging towards the reference") {
    // Cells of aspect 2:1 (dx = 2 dy), 4 → 16 cells through the thickness. Linear tets lock in
    // bending (plane strain, ν = 0.4), so the coarse errors are large; they fall by about 3×
    // per refinement. Measured here: 54%/32%, 20%/11%, 5.6%/2.9% (u_x/u_y). The finest case
    // is asserted at 6.5%/3.5%: an honest bound for this mesh, not the benchmark's 3%
    // (that is the next case).
    std::vector<double> ex, ey;
    for (auto [nx, ny] : {std::pair{35, 4}, std::pair{70, 8}, std::pair{140, 16}}) {
      const Csm1Result r = run_csm1(nx, ny);
      ex.push_back(std::abs(r.ux - kCsm1Ux) / std::abs(kCsm1Ux));
      ey.push_back(std::abs(r.uy - kCsm1Uy) / std::abs(kCsm1Uy));
      MESSAGE("CSM1 " << nx << "x" << ny << " cells (" << r.dofs << " DOFs, " << r.iterations
                      << " Newton its): u_x = " << r.ux << " (err " << ex.back()
                      << "), u_y = " << r.uy << " (err " << ey.back() << ")");
    }
    for (std::size_t k = 1; k < ex.size(); ++k) {
      CHECK(ex[k] < 0.5 * ex[k - 1]);
      CHECK(ey[k] < 0.5 * ey[k - 1]);
    }
    CHECK(ex.back() < 0.065);
    CHECK(ey.back() < 0.035);
  }

  TEST_CASE("Turek-Hron CSM1 on fine meshes: within 3% of the reference") {
    // docs/dev/validation_plan.md "Solid": within 3% on the finest mesh that runs in under a
    // minute, with two coarser meshes showing convergence. Square cells, 8 → 32 cells through the
    // thickness; the finest (111k DOFs, CHOLMOD) takes ≈ 15 s here. Measured: 13.6%/7.0%,
    // 3.4%/1.7%, 0.52%/0.24% (u_x/u_y).
    std::vector<double> ex, ey;
    for (auto [nx, ny] : {std::pair{140, 8}, std::pair{280, 16}, std::pair{560, 32}}) {
      const Csm1Result r = run_csm1(nx, ny);
      ex.push_back(std::abs(r.ux - kCsm1Ux) / std::abs(kCsm1Ux));
      ey.push_back(std::abs(r.uy - kCsm1Uy) / std::abs(kCsm1Uy));
      MESSAGE("CSM1 " << nx << "x" << ny << " cells (" << r.dofs << " DOFs, " << r.iterations
                      << " Newton its): u_x = " << r.ux << " (err " << ex.back()
                      << "), u_y = " << r.uy << " (err " << ey.back() << ")");
    }
    for (std::size_t k = 1; k < ex.size(); ++k) {
      CHECK(ex[k] < 0.5 * ex[k - 1]);
      CHECK(ey[k] < 0.5 * ey[k - 1]);
    }
    CHECK(ex.back() < 0.03);
    CHECK(ey.back() < 0.03);
  }

}  // TEST_SUITE

TEST_SUITE("long") {
  TEST_CASE("Turek-Hron CSM1 at 1120x64 cells: closer than at 560x32 and within 0.3%") {
    // 437k DOFs, ≈ 75 s here. Measured: 0.52%/0.24% at 560x32 → 0.25%/0.15% at 1120x64. The
    // error no longer falls by the O(h²) factor 4: what is left is of the order of the
    // reference's own precision (4 digits) and of our straight clamp where the flag meets
    // the cylinder.
    std::vector<double> ex, ey;
    for (auto [nx, ny] : {std::pair{560, 32}, std::pair{1120, 64}}) {
      const Csm1Result r = run_csm1(nx, ny);
      ex.push_back(std::abs(r.ux - kCsm1Ux) / std::abs(kCsm1Ux));
      ey.push_back(std::abs(r.uy - kCsm1Uy) / std::abs(kCsm1Uy));
      MESSAGE("CSM1 " << nx << "x" << ny << " cells (" << r.dofs << " DOFs, " << r.iterations
                      << " Newton its): u_x = " << r.ux << " (err " << ex.back()
                      << "), u_y = " << r.uy << " (err " << ey.back() << ")");
    }
    CHECK(ex[1] < ex[0]);
    CHECK(ey[1] < ey[0]);
    CHECK(ex[1] < 0.003);
    CHECK(ey[1] < 0.003);
  }

}  // TEST_SUITE
