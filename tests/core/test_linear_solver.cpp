// Tests of core/linear_solver.cpp and core/petsc_solver.cpp, on the matrices of
// core/test_problems.cpp.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/test_problems.hpp"

using namespace tetfsi;

namespace {

/// A smooth-ish deterministic right-hand side of length n.
VecX test_rhs(Index n) {
  VecX b(n);
  for (Index i = 0; i < n; ++i) b[i] = 1.0 + std::sin(0.37 * i) + 0.5 * std::cos(0.011 * i * i);
  return b;
}

/// Reference solution by UMFPACK.
VecX direct_solution(const SparseMatrix& A, const VecX& b) {
  auto lu = make_linear_solver(SolverKind::Umfpack);
  lu->setup(A);
  VecX x;
  const SolveReport rep = lu->solve(b, x);
  REQUIRE(rep.converged);
  REQUIRE(rep.residual <= 1e-12);
  return x;
}

double rel_diff(const VecX& x, const VecX& ref) {
  return (x - ref).norm() / ref.norm();
}

/// Every cell of an nx × ny × nz grid an unknown, in cell order (poisson3d's numbering).
GridLayout full_grid(Index nx, Index ny, Index nz) {
  GridLayout g{{nx, ny, nz}, {}};
  for (Index c = 0; c < nx * ny * nz; ++c) g.cells.push_back(c);
  return g;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("solver names round-trip and unknown names are rejected") {
    const auto& names = solver_names();
    REQUIRE(names.size() == 9);
    CHECK(names.front() == "cholmod");
    for (const auto& n : names) CHECK(to_string(parse_solver_kind(n)) == n);
    CHECK_THROWS_AS(parse_solver_kind("superlu"), InputError);
    CHECK_THROWS_AS(parse_solver_kind(""), InputError);
    CHECK_THROWS_AS(parse_solver_kind("AMG"), InputError);  // names are case-sensitive
    try {
      parse_solver_kind("superlu");
    } catch (const InputError& e) {
      const std::string msg = e.what();
      CHECK(msg.find("'superlu'") != std::string::npos);
      for (const auto& n : names) CHECK(msg.find(n) != std::string::npos);
    }
  }

  TEST_CASE(
      "test problems - Poisson is a symmetric M-matrix and convection-diffusion is nonsymmetric") {
    const SparseMatrix P = poisson3d(4, 3, 5);
    CHECK(P.rows() == 60);
    CHECK(is_symmetric(P));
    // 7-point stencil: 60 diagonal entries plus two per interior grid edge.
    const int edges = 3 * 3 * 5 + 4 * 2 * 5 + 4 * 3 * 4;
    CHECK(P.nonZeros() == 60 + 2 * edges);
    CHECK(P.diagonal().minCoeff() == doctest::Approx(6.0).epsilon(1e-15));
    // Row sums: 6 minus the number of interior neighbours, so ≥ 0, and > 0 on the boundary.
    const VecX rowsum = P * VecX::Ones(60);
    CHECK(rowsum.minCoeff() >= 0.0);
    CHECK(rowsum[0] == doctest::Approx(3.0).epsilon(1e-15));  // corner: 3 neighbours missing

    const SparseMatrix C = convection_diffusion3d(4, 3, 5, 2.0);
    CHECK(C.rows() == 60);
    CHECK_FALSE(is_symmetric(C));
    CHECK((C * VecX::Ones(60)).minCoeff() >= 0.0);  // M-matrix row sums
    CHECK(is_symmetric(convection_diffusion3d(3, 3, 3, 0.0)));
    CHECK_THROWS_AS(poisson3d(0, 3, 3), InputError);
    CHECK_THROWS_AS(convection_diffusion3d(3, 3, 3, -1.0), InputError);
  }

  TEST_CASE("every backend solves a 20x20x20 Poisson problem like the direct solver") {
    const SparseMatrix A = poisson3d(20, 20, 20);
    const VecX b = test_rhs(A.rows());
    const VecX ref = direct_solution(A, b);
    SolverOptions opts;
    opts.rel_tol = 1e-10;
    for (const auto& name : solver_names()) {
      CAPTURE(name);
      const SolverKind kind = parse_solver_kind(name);
      auto solver = make_linear_solver(kind, opts);
      CHECK(solver->name() == name);
      solver->set_grid(full_grid(20, 20, 20));  // pfmg needs it, the others ignore it
      solver->setup(A);
      VecX x = VecX::Zero(A.rows());
      const SolveReport rep = solver->solve(b, x);
      CHECK(rep.backend == name);
      CHECK(rep.converged);
      CHECK(rep.setup_s >= 0.0);
      CHECK(rep.solve_s >= 0.0);
      CHECK(rep.residual == doctest::Approx(relative_residual(A, b, x)).epsilon(1e-6));
      if (is_direct_solver(kind)) {
        CHECK(rep.iterations == 1);
        CHECK(rep.residual <= 1e-12);
      } else {
        CHECK(rep.iterations >= 1);
        CHECK(rep.residual <= 1e-10);  // ≤ opts.rel_tol, measured on b − A x itself
      }
      // cond(A) ≈ 180 here, so a 1e-10 residual bounds the error by ~2e-8.
      CHECK(rel_diff(x, ref) <= 1e-6);
    }
  }

  TEST_CASE("nonsymmetric backends solve a convection-diffusion problem like UMFPACK") {
    const SparseMatrix A = convection_diffusion3d(16, 16, 16, 3.0);
    const VecX b = test_rhs(A.rows());
    const VecX ref = direct_solution(A, b);
    SolverOptions opts;
    opts.rel_tol = 1e-10;
    opts.symmetric = false;
    for (const SolverKind kind :
         {SolverKind::Umfpack, SolverKind::BiCgStabIlut, SolverKind::Amg, SolverKind::AmgGamg,
          SolverKind::Mumps, SolverKind::SuperluDist}) {
      CAPTURE(to_string(kind));
      auto solver = make_linear_solver(kind, opts);
      solver->setup(A);
      VecX x = VecX::Zero(A.rows());
      const SolveReport rep = solver->solve(b, x);
      CHECK(rep.converged);
      CHECK(rep.residual <= (is_direct_solver(kind) ? 1e-12 : 1e-10));
      CHECK(rel_diff(x, ref) <= 1e-6);
    }
  }

  TEST_CASE("CHOLMOD rejects nonsymmetric and indefinite matrices and UMFPACK takes them") {
    auto chol = make_linear_solver(SolverKind::Cholmod);
    const SparseMatrix C = convection_diffusion3d(6, 6, 6, 2.0);
    CHECK_THROWS_AS(chol->setup(C), SolverError);

    // Symmetric indefinite, as StVK stiffness under compression: the 3D Poisson shifted
    // into the middle of its spectrum (eigenvalues 6 − 2 Σ cos(π m/7) ∈ (0.25, 11.75)).
    SparseMatrix S = poisson3d(6, 6, 6);
    SparseMatrix shift(S.rows(), S.cols());
    shift.setIdentity();
    S = S - 5.1 * shift;
    REQUIRE(is_symmetric(S));
    try {
      chol->setup(S);
      FAIL("cholmod accepted an indefinite matrix");
    } catch (const SolverError& e) {
      const std::string msg = e.what();
      CHECK(msg.find("cholmod") != std::string::npos);
      CHECK(msg.find("umfpack") != std::string::npos);  // says what to use instead
    }

    // The caller's fallback: UMFPACK solves the same symmetric indefinite system.
    auto lu = make_linear_solver(SolverKind::Umfpack);
    lu->setup(S);
    const VecX b = test_rhs(S.rows());
    VecX x;
    const SolveReport rep = lu->solve(b, x);
    CHECK(rep.converged);
    CHECK(rep.residual <= 1e-12);

    // cg_ic refuses a nonsymmetric matrix instead of silently diverging.
    CHECK_THROWS_AS(make_linear_solver(SolverKind::CgIc)->setup(C), SolverError);
  }

  TEST_CASE("an iterative solver out of iterations reports not converged without throwing") {
    const SparseMatrix A = poisson3d(12, 12, 12);
    const VecX b = test_rhs(A.rows());
    SolverOptions opts;
    opts.max_iterations = 2;
    opts.rel_tol = 1e-12;
    for (const SolverKind kind :
         {SolverKind::BiCgStabIlut, SolverKind::CgIc, SolverKind::Amg, SolverKind::AmgGamg}) {
      CAPTURE(to_string(kind));
      auto solver = make_linear_solver(kind, opts);
      solver->setup(A);
      VecX x = VecX::Zero(A.rows());
      SolveReport rep;
      CHECK_NOTHROW(rep = solver->solve(b, x));
      CHECK_FALSE(rep.converged);
      CHECK(rep.iterations <= 2);
      CHECK(rep.iterations >= 1);
      CHECK(rep.residual > 1e-12);
      CHECK(rep.residual < 1.0);  // but it did make progress from x = 0
    }
  }

  TEST_CASE("one setup serves repeated solves and a zero right-hand side gives x zero") {
    const SparseMatrix A = poisson3d(10, 11, 12);
    const VecX b1 = test_rhs(A.rows());
    const VecX b2 = VecX::LinSpaced(A.rows(), -1.0, 2.0);
    const VecX ref1 = direct_solution(A, b1);
    const VecX ref2 = direct_solution(A, b2);
    for (const auto& name : solver_names()) {
      CAPTURE(name);
      auto solver = make_linear_solver(parse_solver_kind(name));
      solver->set_grid(full_grid(10, 11, 12));
      solver->setup(A);
      VecX x = VecX::Zero(A.rows());
      CHECK(solver->solve(b1, x).converged);
      CHECK(rel_diff(x, ref1) <= 1e-6);
      // Second solve starts from the previous solution (iterative) or overwrites it.
      const SolveReport rep2 = solver->solve(b2, x);
      CHECK(rep2.converged);
      CHECK(rep2.residual <= 1e-8);
      CHECK(rel_diff(x, ref2) <= 1e-6);
      // Solving again from the exact answer needs no iterations.
      if (!is_direct_solver(parse_solver_kind(name))) {
        VecX x_again = ref2;
        const SolveReport rep3 = solver->solve(b2, x_again);
        CHECK(rep3.converged);
        CHECK(rep3.iterations == 0);
      }
      // Zero right-hand side, from a nonzero (or wrongly sized) start.
      VecX x0 = VecX::Ones(A.rows());
      const SolveReport rep0 = solver->solve(VecX::Zero(A.rows()), x0);
      CHECK(rep0.converged);
      CHECK(rep0.residual == 0.0);
      CHECK(x0.lpNorm<Eigen::Infinity>() == 0.0);
      VecX x_empty;
      solver->solve(b1, x_empty);
      CHECK(x_empty.size() == A.rows());
      CHECK(rel_diff(x_empty, ref1) <= 1e-6);
    }
  }

  TEST_CASE("a 3n x 3n symmetric solid-like system in SPD and indefinite variants") {
    // Stiffness-like matrix: (Poisson ⊗ I₃ + coupling between the 3 components) — symmetric,
    // SPD for small coupling; a negative shift makes it indefinite like StVK under compression.
    const SparseMatrix P = poisson3d(7, 7, 7);
    const Index n = static_cast<Index>(P.rows());
    Triplets t;
    for (Index k = 0; k < P.outerSize(); ++k)
      for (SparseMatrix::InnerIterator it(P, k); it; ++it)
        for (int d = 0; d < 3; ++d) t.emplace_back(3 * it.row() + d, 3 * it.col() + d, it.value());
    for (Index i = 0; i < n; ++i) {
      t.emplace_back(3 * i, 3 * i + 1, 0.3);
      t.emplace_back(3 * i + 1, 3 * i, 0.3);
      t.emplace_back(3 * i + 1, 3 * i + 2, -0.2);
      t.emplace_back(3 * i + 2, 3 * i + 1, -0.2);
    }
    SparseMatrix K(3 * n, 3 * n);
    K.setFromTriplets(t.begin(), t.end());
    REQUIRE(is_symmetric(K));
    const VecX b = test_rhs(3 * n);
    const VecX ref = direct_solution(K, b);
    for (const SolverKind kind : {SolverKind::Cholmod, SolverKind::CgIc, SolverKind::Amg}) {
      CAPTURE(to_string(kind));
      auto solver = make_linear_solver(kind);
      solver->setup(K);
      VecX x = VecX::Zero(3 * n);
      const SolveReport rep = solver->solve(b, x);
      CHECK(rep.converged);
      CHECK(rep.residual <= 1e-8);
      CHECK(rel_diff(x, ref) <= 1e-6);
    }
    SparseMatrix I(3 * n, 3 * n);
    I.setIdentity();
    const SparseMatrix K_indef = K - 4.0 * I;
    CHECK_THROWS_AS(make_linear_solver(SolverKind::Cholmod)->setup(K_indef), SolverError);
    // mumps's LDLᵀ takes the indefinite matrix (UMFPACK's LU the reference)
    auto mumps = make_linear_solver(SolverKind::Mumps);
    mumps->setup(K_indef);
    VecX x;
    const SolveReport rep = mumps->solve(b, x);
    CHECK(rep.converged);
    CHECK(rep.residual <= 1e-12);
    CHECK(rel_diff(x, direct_solution(K_indef, b)) <= 1e-10);
    // a nonsymmetric matrix given as symmetric is refused, naming what to use
    try {
      make_linear_solver(SolverKind::Mumps)->setup(convection_diffusion3d(5, 5, 5, 2.0));
      FAIL("mumps took a nonsymmetric matrix as symmetric");
    } catch (const SolverError& e) {
      CHECK(std::string(e.what()).find("not symmetric") != std::string::npos);
    }
  }

  TEST_CASE("setup rejects non-square matrices and solve before setup is a bug") {
    SparseMatrix R(3, 4);
    for (const auto& name : solver_names()) {
      CAPTURE(name);
      auto solver = make_linear_solver(parse_solver_kind(name));
      CHECK_THROWS_AS(solver->setup(R), SolverError);
      VecX x;
      CHECK_THROWS_AS(solver->solve(VecX::Ones(3), x), InternalError);
    }
    SolverOptions bad;
    bad.rel_tol = 0.0;
    CHECK_THROWS_AS(make_linear_solver(SolverKind::CgIc, bad), InputError);
  }

  TEST_CASE("pfmg: a Poisson problem on the cells outside a sphere, pinned, like UMFPACK") {
    // The grid fluid's shape of system: unknowns on a subset of a 24 x 20 x 16 grid (a ball
    // of cells left out, their neighbours' diagonals keeping the faces to it: Neumann-like
    // rows with row sum 0), one diagonal doubled (the pin), coefficients differing by axis.
    const Index nx = 24, ny = 20, nz = 16;
    GridLayout layout{{nx, ny, nz}, {}};
    std::vector<Index> unknown(nx * ny * nz, -1);
    for (Index k = 0; k < nz; ++k)
      for (Index j = 0; j < ny; ++j)
        for (Index i = 0; i < nx; ++i) {
          const double r2 = (i - 10.5) * (i - 10.5) + (j - 9.5) * (j - 9.5) + (k - 7.5) * (k - 7.5);
          if (r2 < 25.0) continue;
          const Index c = i + nx * (j + ny * k);
          unknown[c] = static_cast<Index>(layout.cells.size());
          layout.cells.push_back(c);
        }
    const Index n = static_cast<Index>(layout.cells.size());
    const double w[3] = {1.0, 2.5, 0.4};
    Triplets t;
    for (Index u = 0; u < n; ++u) {
      const Index c = layout.cells[u];
      const Index ijk[3] = {c % nx, (c / nx) % ny, c / (nx * ny)};
      const Index stride[3] = {1, nx, nx * ny}, dims[3] = {nx, ny, nz};
      for (int a = 0; a < 3; ++a)
        if (ijk[a] + 1 < dims[a] && unknown[c + stride[a]] >= 0) {
          const Index v = unknown[c + stride[a]];
          t.emplace_back(u, u, w[a]);
          t.emplace_back(v, v, w[a]);
          t.emplace_back(u, v, -w[a]);
          t.emplace_back(v, u, -w[a]);
        }
    }
    t.emplace_back(0, 0, 6.0);  // the pin
    SparseMatrix A(n, n);
    A.setFromTriplets(t.begin(), t.end());
    VecX b = test_rhs(n);
    b.array() -= b.mean();  // compatible, as the projection makes it
    const VecX ref = direct_solution(A, b);
    auto pfmg = make_linear_solver(SolverKind::Pfmg, SolverOptions{.rel_tol = 1e-10});
    pfmg->set_grid(layout);
    pfmg->setup(A);
    VecX x;
    const SolveReport rep = pfmg->solve(b, x);
    CHECK(rep.converged);
    CHECK(rep.residual <= 1e-10);
    CHECK(rep.residual == doctest::Approx(relative_residual(A, b, x)).epsilon(1e-6));
    CHECK(rep.iterations <= 40);
    CHECK(rel_diff(x, ref) <= 1e-6);
    // Again from that answer: converged at once.
    const SolveReport again = pfmg->solve(b, x);
    CHECK(again.iterations == 0);
  }

  TEST_CASE("pfmg: without the grid, or with a matrix the grid cannot hold, a SolverError") {
    const SparseMatrix A = poisson3d(4, 4, 4);
    auto pfmg = make_linear_solver(SolverKind::Pfmg);
    CHECK_THROWS_WITH_AS(pfmg->setup(A), doctest::Contains("fluid.discretization"), SolverError);
    // The 4 x 4 x 4 matrix on an 8 x 8 x 1 grid's cells: row 0's neighbours 4 and 16 are
    // cells (4, 0) and (0, 2) there, no face neighbours of cell (0, 0).
    GridLayout wrong = full_grid(8, 8, 1);
    pfmg->set_grid(wrong);
    CHECK_THROWS_WITH_AS(pfmg->setup(A), doctest::Contains("not face neighbours"), SolverError);
    SolverOptions nonsym;
    nonsym.symmetric = false;
    CHECK_THROWS_AS(make_linear_solver(SolverKind::Pfmg, nonsym), InputError);
  }

  TEST_CASE("multigrid backends need few iterations on a 125k-unknown Poisson problem") {
    // The property that makes amg worth its dependency: iterations nearly independent of n
    // (bench_solvers measured 7 for amg and 11 for amg_gamg at 250k and at 1M unknowns).
    const SparseMatrix A = poisson3d(50, 50, 50);
    const VecX b = test_rhs(A.rows());
    for (const SolverKind kind : {SolverKind::Amg, SolverKind::AmgGamg, SolverKind::Pfmg}) {
      CAPTURE(to_string(kind));
      auto solver = make_linear_solver(kind);
      solver->set_grid(full_grid(50, 50, 50));
      solver->setup(A);
      VecX x = VecX::Zero(A.rows());
      const SolveReport rep = solver->solve(b, x);
      CHECK(rep.converged);
      CHECK(rep.residual <= 1e-8);
      CHECK(rep.iterations < 20);
      CHECK(relative_residual(A, b, x) <= 1e-8);
    }
  }

  TEST_CASE("relative_residual and is_symmetric helpers") {
    const SparseMatrix A = poisson3d(3, 3, 3);
    const VecX x = VecX::Ones(27);
    const VecX b = A * x;
    CHECK(relative_residual(A, b, x) <= 1e-15);
    CHECK(relative_residual(A, b, VecX::Zero(27)) == doctest::Approx(1.0).epsilon(1e-14));
    CHECK(relative_residual(A, VecX::Zero(27), VecX::Zero(27)) == 0.0);
    SparseMatrix B = A;
    B.coeffRef(0, 1) += 1e-6;
    CHECK_FALSE(is_symmetric(B));
    CHECK(is_symmetric(B, 1e-6));
  }

}  // TEST_SUITE
