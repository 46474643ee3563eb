#include "core/linear_solver.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/CholmodSupport>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/UmfPackSupport>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/petsc_solver.hpp"
#include "core/ranks.hpp"
#include "core/solve_ranks.hpp"
#include "core/struct_solver.hpp"
#include "core/timer.hpp"

namespace tetfsi {

namespace {

/// Restarted solves after the Krylov loop stopped with a true residual still above tol
/// (the recursively updated residual drifts from b − A x); at most this many.
constexpr int k_max_restarts = 5;

/// The direct solvers factor a 64-bit-index copy of A: SuiteSparse's int versions run out
/// of integer-addressable workspace on 3D problems of a few 100k unknowns (UMFPACK failed
/// at 250k), and the copy costs little next to the factorization.
using LongIndex = SuiteSparse_long;
using LongSparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, LongIndex>;

/// Eigen's UmfPackLU, exposing UMFPACK's last status code (also after a failed symbolic
/// analysis, where `umfpackFactorizeReturncode()` would assert).
class UmfPackLUWithStatus : public Eigen::UmfPackLU<LongSparseMatrix> {
 public:
  int status() const { return static_cast<int>(m_fact_errorCode); }
};

/// What UMFPACK's status code means, for error messages.
std::string umfpack_status_text(int status) {
  switch (status) {
    case UMFPACK_WARNING_singular_matrix:
      return "the matrix is singular";
    case UMFPACK_ERROR_out_of_memory:
      return "out of memory";
    case UMFPACK_ERROR_invalid_matrix:
      return "invalid matrix";
    default:
      return fmt::format("UMFPACK status {}", status);
  }
}

void check_square(const SparseMatrix& A, const std::string& backend) {
  TETFSI_REQUIRE(SolverError, A.rows() == A.cols() && A.rows() > 0,
                 "{}: need a nonempty square matrix, got {} x {}", backend, A.rows(), A.cols());
}

void check_rhs(const SparseMatrix* A, const VecX& b, const std::string& backend) {
  TETFSI_CHECK(A != nullptr, "{}: solve() called before setup()", backend);
  TETFSI_CHECK(b.size() == A->rows(), "{}: right-hand side has length {}, matrix is {} x {}",
               backend, b.size(), A->rows(), A->cols());
}

// ---- direct backends ----------------------------------------------------------------------

/// CHOLMOD supernodal LLᵀ (reads the lower triangle only, so symmetry is checked first).
class CholmodSolver final : public LinearSolver {
 public:
  std::string name() const override { return "cholmod"; }

  void setup(const SparseMatrix& A) override {
    const double t0 = now_seconds();
    m_A = nullptr;
    check_square(A, name());
    TETFSI_REQUIRE(SolverError, is_symmetric(A),
                   "cholmod: the {} x {} matrix is not symmetric; use the umfpack backend "
                   "for nonsymmetric matrices",
                   A.rows(), A.cols());
    m_llt.cholmod().print = 0;  // failures are reported by the exception below
    m_llt.compute(LongSparseMatrix(A));
    TETFSI_REQUIRE(SolverError, m_llt.info() == Eigen::Success,
                   "cholmod: Cholesky factorization of the {} x {} matrix failed (not "
                   "positive definite); use the umfpack backend for symmetric indefinite "
                   "matrices",
                   A.rows(), A.cols());
    m_A = &A;
    m_setup_s = now_seconds() - t0;
  }

  SolveReport solve(const VecX& b, VecX& x) override {
    check_rhs(m_A, b, name());
    const double t0 = now_seconds();
    x = m_llt.solve(b);
    SolveReport rep{
        name(), m_llt.info() == Eigen::Success, 1, relative_residual(*m_A, b, x), m_setup_s, 0.0};
    rep.solve_s = now_seconds() - t0;
    return rep;
  }

 private:
  Eigen::CholmodSupernodalLLT<LongSparseMatrix, Eigen::Lower> m_llt;
  const SparseMatrix* m_A = nullptr;
  double m_setup_s = 0.0;
};

/// UMFPACK LU with partial pivoting: any nonsingular matrix.
class UmfpackSolver final : public LinearSolver {
 public:
  std::string name() const override { return "umfpack"; }

  void setup(const SparseMatrix& A) override {
    const double t0 = now_seconds();
    m_A = nullptr;
    check_square(A, name());
    m_copy = A;
    m_copy.makeCompressed();
    m_lu.compute(m_copy);  // Eigen refers to the matrix it factors: keep the copy
    TETFSI_REQUIRE(SolverError, m_lu.info() == Eigen::Success,
                   "umfpack: LU factorization of the {} x {} matrix failed: {}", A.rows(), A.cols(),
                   umfpack_status_text(m_lu.status()));
    m_A = &A;
    m_setup_s = now_seconds() - t0;
  }

  SolveReport solve(const VecX& b, VecX& x) override {
    check_rhs(m_A, b, name());
    const double t0 = now_seconds();
    x = m_lu.solve(b);
    SolveReport rep{
        name(), m_lu.info() == Eigen::Success, 1, relative_residual(*m_A, b, x), m_setup_s, 0.0};
    rep.solve_s = now_seconds() - t0;
    return rep;
  }

 private:
  LongSparseMatrix m_copy;
  UmfPackLUWithStatus m_lu;
  const SparseMatrix* m_A = nullptr;
  double m_setup_s = 0.0;
};

// ---- Eigen iterative backends -------------------------------------------------------------

/// Eigen Krylov solver `Krylov` (BiCGSTAB or CG with its preconditioner) with restarts until
/// the *true* relative residual reaches rel_tol or max_iterations are spent.
template <class Krylov>
class EigenIterativeSolver final : public LinearSolver {
 public:
  EigenIterativeSolver(std::string name, const SolverOptions& opts, bool needs_symmetric)
      : m_name(std::move(name)), m_opts(opts), m_needs_symmetric(needs_symmetric) {
    if constexpr (requires(Krylov k) { k.preconditioner().setDroptol(1.0); }) {
      m_krylov.preconditioner().setDroptol(opts.ilut_drop_tol);
      m_krylov.preconditioner().setFillfactor(opts.ilut_fill);
    }
  }

  std::string name() const override { return m_name; }

  void setup(const SparseMatrix& A) override {
    const double t0 = now_seconds();
    m_A = nullptr;
    check_square(A, m_name);
    TETFSI_REQUIRE(SolverError, !m_needs_symmetric || is_symmetric(A),
                   "{}: the {} x {} matrix is not symmetric; use bicgstab_ilut or umfpack", m_name,
                   A.rows(), A.cols());
    m_krylov.compute(A);
    TETFSI_REQUIRE(SolverError, m_krylov.info() == Eigen::Success,
                   "{}: building the incomplete factorization of the {} x {} matrix failed; "
                   "try umfpack",
                   m_name, A.rows(), A.cols());
    m_A = &A;
    m_setup_s = now_seconds() - t0;
  }

  SolveReport solve(const VecX& b, VecX& x) override {
    check_rhs(m_A, b, m_name);
    const double t0 = now_seconds();
    SolveReport rep{m_name, true, 0, 0.0, m_setup_s, 0.0};
    if (x.size() != b.size() || !x.allFinite()) x = VecX::Zero(b.size());
    if (b.squaredNorm() == 0.0) {
      x.setZero();
      rep.solve_s = now_seconds() - t0;
      return rep;
    }
    m_krylov.setTolerance(m_opts.rel_tol);
    rep.residual = relative_residual(*m_A, b, x);
    for (int round = 0; round <= k_max_restarts; ++round) {
      const int left = m_opts.max_iterations - rep.iterations;
      if (rep.residual <= m_opts.rel_tol || left <= 0) break;
      m_krylov.setMaxIterations(left);
      VecX x_new = m_krylov.solveWithGuess(b, x);
      const int its = static_cast<int>(m_krylov.iterations());
      rep.iterations += its;
      const double res_new = relative_residual(*m_A, b, x_new);
      if (!std::isfinite(res_new)) {  // breakdown: keep the last finite iterate
        rep.iterations = std::max(rep.iterations, 1);
        break;
      }
      x = std::move(x_new);
      rep.residual = res_new;
      if (its == 0) break;  // no progress possible
    }
    rep.converged = rep.residual <= m_opts.rel_tol;
    rep.solve_s = now_seconds() - t0;
    return rep;
  }

 private:
  std::string m_name;
  SolverOptions m_opts;
  bool m_needs_symmetric;
  Krylov m_krylov;
  const SparseMatrix* m_A = nullptr;
  double m_setup_s = 0.0;
};

using BiCgStabIlut = Eigen::BiCGSTAB<SparseMatrix, Eigen::IncompleteLUT<double, Index>>;
using CgIc = Eigen::ConjugateGradient<
    SparseMatrix, Eigen::Lower | Eigen::Upper,
    Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<Index>>>;

}  // namespace

const std::vector<std::string>& solver_names() {
  static const std::vector<std::string> names = k_solver_kind_names.names();
  return names;
}

SolverKind parse_solver_kind(const std::string& name) {
  return k_solver_kind_names.parse(name);
}

std::string to_string(SolverKind kind) {
  return k_solver_kind_names.name(kind);
}

bool is_direct_solver(SolverKind kind) {
  return kind == SolverKind::Cholmod || kind == SolverKind::Umfpack || kind == SolverKind::Mumps ||
         kind == SolverKind::SuperluDist;
}

std::unique_ptr<LinearSolver> make_linear_solver(SolverKind kind, const SolverOptions& opts) {
  TETFSI_REQUIRE(InputError, opts.rel_tol > 0.0 && opts.rel_tol < 1.0,
                 "linear solver rel_tol must be in (0, 1), got {}", opts.rel_tol);
  TETFSI_REQUIRE(InputError, opts.max_iterations >= 1,
                 "linear solver max_iterations must be ≥ 1, got {}", opts.max_iterations);
  switch (kind) {
    case SolverKind::Cholmod:
      return std::make_unique<CholmodSolver>();
    case SolverKind::Umfpack:
      return std::make_unique<UmfpackSolver>();
    case SolverKind::BiCgStabIlut:
      TETFSI_REQUIRE(InputError, opts.ilut_drop_tol >= 0.0 && opts.ilut_fill >= 1,
                     "bicgstab_ilut: need ilut_drop_tol ≥ 0 and ilut_fill ≥ 1, got {} and {}",
                     opts.ilut_drop_tol, opts.ilut_fill);
      return std::make_unique<EigenIterativeSolver<BiCgStabIlut>>("bicgstab_ilut", opts, false);
    case SolverKind::CgIc:
      return std::make_unique<EigenIterativeSolver<CgIc>>("cg_ic", opts, true);
    case SolverKind::Amg:
    case SolverKind::AmgGamg:
    case SolverKind::Mumps:
    case SolverKind::SuperluDist:
      if (drives_solve_workers()) return detail::make_served_solver(kind, opts);
      return detail::make_petsc_solver(kind, opts);
    case SolverKind::Pfmg:
      if (drives_solve_workers()) return detail::make_served_solver(kind, opts);
      return detail::make_pfmg_solver(opts);
  }
  throw InternalError(
      fmt::format("make_linear_solver: invalid SolverKind {}", static_cast<int>(kind)));
}

double relative_residual(const SparseMatrix& A, const VecX& b, const VecX& x) {
  TETFSI_CHECK(A.rows() == b.size() && A.cols() == x.size(),
               "relative_residual: A is {} x {}, b has {} entries, x has {}", A.rows(), A.cols(),
               b.size(), x.size());
  const double bnorm = b.norm();
  const double rnorm = (b - A * x).norm();
  return bnorm > 0.0 ? rnorm / bnorm : rnorm;
}

bool is_symmetric(const SparseMatrix& A, double rel_tol) {
  if (A.rows() != A.cols()) return false;
  if (A.nonZeros() == 0) return true;
  const SparseMatrix At = A.transpose();
  const SparseMatrix D = A - At;
  double amax = 0.0, dmax = 0.0;
  for (Index k = 0; k < A.outerSize(); ++k) {
    for (SparseMatrix::InnerIterator it(A, k); it; ++it)
      amax = std::max(amax, std::abs(it.value()));
    for (SparseMatrix::InnerIterator it(D, k); it; ++it)
      dmax = std::max(dmax, std::abs(it.value()));
  }
  return dmax <= rel_tol * amax;
}

std::unique_ptr<AmgPreconditioner> make_pfmg_preconditioner(const GridLayout& layout) {
  if (drives_solve_workers()) return detail::make_served_preconditioner(&layout);
  return detail::make_pfmg_preconditioner(layout);
}

std::unique_ptr<AmgPreconditioner> make_amg_preconditioner() {
  if (drives_solve_workers()) return detail::make_served_preconditioner(nullptr);
  return detail::make_petsc_preconditioner();
}

void start_amg_backends() {
  (void)detail::start_petsc();
}

}  // namespace tetfsi

namespace tetfsi {

std::unique_ptr<LinearSolver> factor_symmetric(const SparseMatrix& A) {
  auto s = make_linear_solver(SolverKind::Cholmod);
  try {
    s->setup(A);
  } catch (const SolverError&) {
    logger().debug("a symmetric matrix is not positive definite; it is solved by LU");
    s = make_linear_solver(SolverKind::Umfpack);
    s->setup(A);
  }
  return s;
}

double detail::setup_or_release(const std::string& name, const std::function<void()>& build,
                                const std::function<void()>& release) {
  const double t0 = now_seconds();
  release();
  try {
    build();
  } catch (const SolverError& e) {
    release();
    throw SolverError(fmt::format("{}: {}", name, e.what()));
  } catch (...) {
    release();
    throw;
  }
  return now_seconds() - t0;
}

}  // namespace tetfsi
