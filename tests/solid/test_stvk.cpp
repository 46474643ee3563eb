/// Tests of solid/material.cpp, solid/stvk.cpp and solid/solid_body.cpp: material checks,
/// rigid-motion invariance, finite-difference derivatives, lumped mass, tet fields.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>

#include "core/error.hpp"
#include "mesh/volume_mesh.hpp"
#include "solid/stvk.hpp"
#include "solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

TEST_SUITE("unit") {
  TEST_CASE("material: Lame parameters and validation") {
    Material m = make_material(1000.0, 1.4e6, 0.4);
    const LameParameters l = lame_parameters(m);
    // μ_s = 0.5e6 Pa for E = 1.4e6, ν = 0.4 (Turek & Hron 2006, CSM1 parameters);
    // λ = Eν/((1+ν)(1−2ν)) = 2.0e6 Pa.
    CHECK(l.mu == doctest::Approx(0.5e6).epsilon(1e-14));
    CHECK(l.lambda == doctest::Approx(2.0e6).epsilon(1e-14));
    CHECK_NOTHROW(validate_material(m, "m"));

    m.poisson_ratio = 0.5;
    try {
      validate_material(m, "scene.json: bodies[0].material");
      FAIL("expected InputError");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()) ==
            "scene.json: bodies[0].material.poisson_ratio: 0.5 is out of range; need -1 < "
            "poisson_ratio < 0.5 (0.5 is incompressible and locks linear tets)");
    }
    m = make_material(1000.0, 1e5, 0.3);
    m.density = 0.0;
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
    m = make_material(1000.0, -1.0, 0.3);
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
    m = make_material(1000.0, 1e5, -1.0);
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
    m = make_material(1000.0, 1e5, 0.3, -0.1);
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
    m = make_material(1000.0, 1e5, 0.3, 0.0, NAN);
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
    m = make_material(INFINITY, 1e5, 0.3);
    CHECK_THROWS_AS(validate_material(m, "m"), InputError);
  }

  TEST_CASE("SolidBody rejects a bad material or mesh and names the body") {
    mesh::VolumeMesh box = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1));
    CHECK_THROWS_AS(SolidBody("b", box, make_material(1000.0, 1e5, 0.5)), InputError);
    mesh::VolumeMesh inverted = box;
    inverted.tets.col(2).swap(inverted.tets.col(3));
    inverted.tets.row(1) = box.tets.row(1);  // mixed orientation: not globally fixable
    CHECK_THROWS_AS(SolidBody("b", inverted, make_material(1000.0, 1e5, 0.3)), MeshError);
  }

  TEST_CASE("rigid motions give zero strain and zero energy and zero force") {
    const Material mat = make_material(1000.0, 1e6, 0.3);
    SolidBody body =
        make_box_body("patch", Vec3(0, 0, 0), Vec3(1.0, 0.6, 0.8), Vec3i(3, 2, 2), mat);
    const StvkElasticity& el = body.elasticity();
    const double volume = el.rest_volumes().sum();
    const double force_scale = mat.youngs_modulus * std::pow(volume, 2.0 / 3.0);  // E·V^(2/3) (N)
    const double energy_scale = mat.youngs_modulus * volume;                      // E·V (J)
    const Vec3 t(0.3, -2.0, 5.0);
    const std::vector<Mat3> rotations = {rotation(Vec3::UnitZ(), M_PI / 2),
                                         rotation(Vec3::UnitX(), M_PI),
                                         rotation(Vec3(1.0, -2.0, 0.7), 2.1)};
    for (const Mat3& R : rotations) {
      MatX3 x = (body.rest_positions() * R.transpose()).rowwise() + t.transpose();
      const VecX f = el.forces(x);
      const TetFields fields = el.tet_fields(x);
      // Round-off level only: 1e-10 relative to the E·V scales.
      CHECK(f.cwiseAbs().maxCoeff() <= 1e-10 * force_scale);
      CHECK(std::abs(el.energy(x)) <= 1e-10 * energy_scale);
      CHECK(fields.green_strain_norm.maxCoeff() <= 1e-12);
      CHECK(fields.von_mises_stress.maxCoeff() <= 1e-10 * mat.youngs_modulus);
      CHECK((fields.volume_ratio.array() - 1.0).abs().maxCoeff() <= 1e-12);
    }
  }

  TEST_CASE("forces are the gradient of the energy and K' the Jacobian of the forces (FD)") {
    const Material mat = make_material(1000.0, 1e6, 0.35);
    SolidBody body = make_box_body("fd", Vec3(0, 0, 0), Vec3(1.0, 0.5, 0.7), Vec3i(2, 2, 2), mat);
    const StvkElasticity& el = body.elasticity();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    for (int trial = 0; trial < 3; ++trial) {
      // Moderate random deformation: an affine stretch/shear plus ±5% nodal noise.
      Mat3 F = Mat3::Identity();
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) F(i, j) += 0.2 * uni(rng);
      MatX3 x = body.rest_positions() * F.transpose();
      for (Index i = 0; i < x.rows(); ++i)
        for (int k = 0; k < 3; ++k) x(i, k) += 0.05 * uni(rng);
      VecX f;
      SparseMatrix K;
      el.forces_and_jacobian(x, f, K);
      CHECK((f - el.forces(x)).norm() <= 1e-14 * f.norm());
      CHECK((MatX(K) - MatX(el.jacobian(x))).norm() == 0.0);

      const double eps = 1e-6;  // central differences; W is a quartic polynomial in x
      VecX grad_fd(f.size());
      MatX K_fd(f.size(), f.size());
      for (Index i = 0; i < f.size(); ++i) {
        MatX3 xp = x, xm = x;
        xp(i / 3, i % 3) += eps;
        xm(i / 3, i % 3) -= eps;
        grad_fd[i] = (el.energy(xp) - el.energy(xm)) / (2 * eps);
        K_fd.col(i) = (el.forces(xp) - el.forces(xm)) / (2 * eps);
      }
      const MatX Kd = MatX(K);
      const double grad_err = (grad_fd - f).norm() / f.norm();
      const double jac_err = (K_fd - Kd).norm() / Kd.norm();
      MESSAGE("trial " << trial << ": FD gradient rel. error " << grad_err
                       << ", FD Jacobian rel. error " << jac_err);
      CHECK(grad_err < 1e-6);  // docs/dev/validation_plan.md "Consistency": < 1e-6
      CHECK(jac_err < 1e-6);
      CHECK((Kd - Kd.transpose()).norm() == 0.0);  // K' = ∂²W/∂x² is symmetric
    }
  }

  TEST_CASE("the definite tangent is positive semi-definite where the exact one is not") {
    // One box of 2 x 2 x 2 cells crushed to 40 % of its height with 3 % nodal noise (the
    // state of the foam block under the ball of ball_block): the exact K' has negative
    // eigenvalues (the compressive initial stress), the definite one none below −1e-9 of its
    // largest; the forces are the same (only the matrix changes); away from compression
    // (a stretch) both are the same matrix.
    const Material mat = make_material(100.0, 2e4, 0.3);
    SolidBody body =
        make_box_body("crush", Vec3(0, 0, 0), Vec3(0.3, 0.3, 0.1), Vec3i(2, 2, 2), mat);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    MatX3 x = body.rest_positions();
    x.col(2) *= 0.4;
    for (Index i = 0; i < x.rows(); ++i)
      for (int k = 0; k < 3; ++k) x(i, k) += 0.003 * uni(rng);
    const auto spectrum = [&](Tangent t, const MatX3& at, VecX& f) {
      body.set_tangent(t);
      SparseMatrix K;
      body.elasticity().forces_and_jacobian(at, f, K);
      return Eigen::SelfAdjointEigenSolver<MatX>(MatX(K)).eigenvalues();
    };
    VecX f_exact, f_def;
    const VecX ev_exact = spectrum(Tangent::Exact, x, f_exact);
    const VecX ev_def = spectrum(Tangent::Definite, x, f_def);
    MESSAGE("crushed: exact K' eigenvalues " << ev_exact.minCoeff() << " .. " << ev_exact.maxCoeff()
                                             << ", definite " << ev_def.minCoeff() << " .. "
                                             << ev_def.maxCoeff());
    CHECK(ev_exact.minCoeff() < -1e-3 * ev_exact.maxCoeff());
    CHECK(ev_def.minCoeff() >= -1e-9 * ev_def.maxCoeff());
    CHECK((f_def - f_exact).norm() == 0.0);

    MatX3 y = body.rest_positions();
    y.col(0) *= 1.2;  // uniaxial stretch: S ⪰ 0 (ν > 0 gives no lateral stress under F)
    body.set_tangent(Tangent::Exact);
    const MatX K_exact = MatX(body.elasticity().jacobian(y));
    body.set_tangent(Tangent::Definite);
    const MatX K_def = MatX(body.elasticity().jacobian(y));
    CHECK((K_def - K_exact).norm() <= 1e-12 * K_exact.norm());
  }

  TEST_CASE("lumped masses sum to density times volume") {
    const Material mat = make_material(1234.0, 1e6, 0.3);
    mesh::VolumeMesh m = mesh::make_box(Vec3(-0.2, 0.1, 0.0), Vec3(0.5, 0.4, 0.3), Vec3i(4, 3, 2));
    // Jitter interior nodes so the tets differ in volume.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> uni(-0.02, 0.02);
    for (Index i = 0; i < m.num_vertices(); ++i) {
      const Vec3 p = m.vertices.row(i);
      const bool interior = p.x() > -0.2 + 1e-9 && p.x() < 0.5 - 1e-9 && p.y() > 0.1 + 1e-9 &&
                            p.y() < 0.4 - 1e-9 && p.z() > 1e-9 && p.z() < 0.3 - 1e-9;
      if (interior)
        for (int k = 0; k < 3; ++k) m.vertices(i, k) += uni(rng);
    }
    const double volume = 0.7 * 0.3 * 0.3;
    SolidBody body("mass", m, mat);
    CHECK(mesh::total_volume(body.rest_mesh()) == doctest::Approx(volume).epsilon(1e-12));
    CHECK(body.total_mass() == doctest::Approx(mat.density * volume).epsilon(1e-12));
    CHECK(body.elasticity().rest_volumes().sum() == doctest::Approx(volume).epsilon(1e-12));
    CHECK(body.boundary_triangles().rows() == 2 * 2 * (4 * 3 + 3 * 2 + 4 * 2));
    // Gravity load = m g per node; its sum is the weight.
    const Vec3 g(0, 0, -9.81);
    const VecX fe = body.external_forces(g);
    CHECK(as_nodes(fe).colwise().sum().z() ==
          doctest::Approx(-9.81 * body.total_mass()).epsilon(1e-12));
  }

  TEST_CASE("tet fields of a uniaxial stretch") {
    const Material mat = make_material(1000.0, 2e5, 0.25);
    const LameParameters l = lame_parameters(mat);
    SolidBody body = make_box_body("stretch", Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1), mat);
    const double s = 1.1;
    MatX3 x = body.rest_positions();
    x.col(0) *= s;
    const TetFields fl = body.elasticity().tet_fields(x);
    // Closed form: E11 = (s² − 1)/2, S = λ E11 I + 2μ E11 e1e1ᵀ, σ = F S Fᵀ / s.
    const double e11 = 0.5 * (s * s - 1.0);
    const double s11 = (l.lambda + 2 * l.mu) * e11, s22 = l.lambda * e11;
    const double sig11 = s * s * s11 / s, sig22 = s22 / s;
    const double vm = std::abs(sig11 - sig22);  // von Mises of diag(a, b, b) is |a − b|
    for (Index t = 0; t < body.num_tets(); ++t) {
      CHECK(fl.green_strain_norm[t] == doctest::Approx(e11).epsilon(1e-12));
      CHECK(fl.volume_ratio[t] == doctest::Approx(s).epsilon(1e-12));
      CHECK(fl.von_mises_stress[t] == doctest::Approx(vm).epsilon(1e-12));
    }
  }

}  // TEST_SUITE
