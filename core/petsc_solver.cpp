#include "core/petsc_solver.hpp"

#include <cmath>
#include <cstdlib>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#include <petscksp.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/ranks.hpp"
#include "core/timer.hpp"

static_assert(std::is_same_v<PetscInt, tetfsi::Index>,
              "PETSc must use 32-bit indices so Eigen's CSR arrays can be shared");
static_assert(std::is_same_v<PetscScalar, double>, "PETSc must be built with real doubles");

namespace tetfsi::detail {

namespace {

/// Throw SolverError for a nonzero PETSc error code, with PETSc's own message.
void petsc_check(PetscErrorCode ierr, const char* call) {
  if (ierr == 0) [[likely]]
    return;
  const char* text = nullptr;
  char* specific = nullptr;
  PetscErrorMessage(ierr, &text, &specific);
  std::string msg = fmt::format("PETSc error {} in {}", static_cast<int>(ierr), call);
  if (text && *text) msg += fmt::format(": {}", text);
  if (specific && *specific) msg += fmt::format(": {}", specific);
  throw SolverError(msg);
}
#define TETFSI_PETSC(call) petsc_check((call), #call)

bool petsc_finalized() {
  PetscBool done = PETSC_FALSE;
  PetscFinalized(&done);
  return done == PETSC_TRUE;
}

// ---- one-time initialisation ----------------------------------------------------------------

bool g_petsc_ours = false;  ///< we called PetscInitialize, so we finalise
std::string g_petsc_init_error;

void finalize_petsc() {
  if (g_petsc_ours && !petsc_finalized()) PetscFinalize();
}

/// Set an option in PETSc's global database unless the user already gave it
/// (through PETSC_OPTIONS), so run-time tuning always wins.
void default_option(const char* name, const char* value) {
  PetscBool given = PETSC_FALSE;
  TETFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name, &given));
  if (!given) TETFSI_PETSC(PetscOptionsSetValue(nullptr, name, value));
}

void init_petsc_once() {
  PetscBool up = PETSC_FALSE;
  PetscInitialized(&up);
  if (!up) {
    // PETSc keeps pointers to argc/argv: static storage.
    static char a0[] = "tetfsi", a1[] = "-no_signal_handler", a2[] = "-skip_petscrc",
                a3[] = "-options_left", a4[] = "no";
    static char* args[] = {a0, a1, a2, a3, a4, nullptr};
    static int argc = 5;
    static char** argv = args;
    // A serial Open MPI start (not under mpirun) spends ~0.3 s probing UCX, whose
    // transports a single process never uses: ask for the ob1 layer unless the user chose.
    if (std::getenv("OMPI_COMM_WORLD_SIZE") == nullptr) setenv("OMPI_MCA_pml", "ob1", 0);
    const PetscErrorCode ierr = PetscInitialize(&argc, &argv, nullptr, nullptr);
    if (ierr != 0) {
      g_petsc_init_error = fmt::format("PetscInitialize failed with error {}", (int)ierr);
      return;
    }
    g_petsc_ours = true;
    std::atexit(finalize_petsc);
  }
  // Errors come back as codes (turned into SolverError), without PETSc printing tracebacks.
  PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);

  // BoomerAMG tuned for 3D Poisson-like operators: HMIS coarsening with ext+i
  // interpolation truncated to 4 entries per row, strength threshold 0.5 (hypre's advice
  // in 3D), aggressive coarsening on the first level with 2 paths. Measured on the 250k
  // 3D Poisson (63³) to 1e-8: 7 CG iterations, about 0.4 s CPU for setup + solve; with 1
  // path 12 iterations and 1.3–1.9× the time, without aggressive coarsening 9 iterations
  // and ~2× the time, 2 levels of it 17 iterations; thresholds 0.25–0.7 and P_max 3–5
  // were within the noise.
  default_option("-tetfsi_amg_pc_hypre_boomeramg_strong_threshold", "0.5");
  default_option("-tetfsi_amg_pc_hypre_boomeramg_coarsen_type", "HMIS");
  default_option("-tetfsi_amg_pc_hypre_boomeramg_interp_type", "ext+i");
  default_option("-tetfsi_amg_pc_hypre_boomeramg_P_max", "4");
  default_option("-tetfsi_amg_pc_hypre_boomeramg_agg_nl", "1");
  default_option("-tetfsi_amg_pc_hypre_boomeramg_agg_num_paths", "2");
  // GAMG: aggressive (squared-graph) coarsening on the first two levels; on the 250k 3D
  // Poisson this cut the setup from 0.9 s to 0.55 s CPU (11 instead of 10 iterations).
  // (PETSc 3.18's PCGAMGSetAggressiveLevels is overridden by the options pass: set it here.)
  default_option("-tetfsi_gamg_pc_gamg_aggressive_coarsening", "2");
  default_option("-tetfsi_gamg_nonsym_pc_gamg_aggressive_coarsening", "2");
  // GAMG's default Chebyshev/Jacobi smoother needs a (nearly) symmetric operator; for
  // nonsymmetric ones (prefix tetfsi_gamg_nonsym_) use one SOR sweep instead.
  default_option("-tetfsi_gamg_nonsym_mg_levels_ksp_type", "richardson");
  default_option("-tetfsi_gamg_nonsym_mg_levels_pc_type", "sor");
  logger().debug("PETSc initialised ({} it)", g_petsc_ours ? "we initialised" : "already up");
}

void ensure_petsc() {
  static std::once_flag once;
  std::call_once(once, [] {
    try {
      init_petsc_once();
    } catch (const SolverError& e) {
      g_petsc_init_error = e.what();
    }
  });
  TETFSI_REQUIRE(SolverError, g_petsc_init_error.empty(),
                 "amg: cannot initialise PETSc: {}; use cholmod or cg_ic instead",
                 g_petsc_init_error);
}

/// The communicator of the solves: every rank's under mpirun (core/ranks.hpp), else this one.
MPI_Comm solve_comm() {
  return rank_count() > 1 ? PETSC_COMM_WORLD : PETSC_COMM_SELF;
}

/// The rows of an n-row system this rank owns (all of them with one rank).
RowRange my_rows(Index n) {
  return rank_rows(n, rank_index(), rank_count());
}

/// A PETSc Vec that wraps caller memory (no copy) and is destroyed with the scope. With
/// several ranks it is the distributed vector whose local part is this rank's rows of `data`
/// (the full vector of length n, the same on every rank).
struct WrappedVec {
  Vec v = nullptr;
  WrappedVec(Index n, const double* data) {
    if (rank_count() > 1) {
      const RowRange rows = my_rows(n);
      TETFSI_PETSC(
          VecCreateMPIWithArray(PETSC_COMM_WORLD, 1, rows.size(), n, data + rows.begin, &v));
    } else {
      TETFSI_PETSC(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, data, &v));
    }
  }
  WrappedVec(const WrappedVec&) = delete;
  WrappedVec& operator=(const WrappedVec&) = delete;
  ~WrappedVec() {
    if (v && !petsc_finalized()) VecDestroy(&v);
  }
};

/// KSPSolve with restarts from x; fills rep.iterations and rep.residual (true_residual()
/// evaluates ||b − A x|| / ||b|| for the current x).
template <class Residual>
void krylov_with_restarts(KSP ksp, const VecX& b, VecX& x, const SolverOptions& opts,
                          const std::string& name, SolveReport& rep, Residual&& true_residual) {
  const Index n = static_cast<Index>(b.size());
  WrappedVec vb(n, b.data());
  WrappedVec vx(n, x.data());
  rep.residual = true_residual();
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
  // Restart when PETSc's recursively updated residual met the tolerance but the true one
  // did not (rare; a few restarts at most).
  for (int round = 0; round <= 5; ++round) {
    const int left = opts.max_iterations - rep.iterations;
    if (rep.residual <= opts.rel_tol || left <= 0) break;
    TETFSI_PETSC(KSPSetTolerances(ksp, opts.rel_tol, 0.0, PETSC_DEFAULT, left));
    const VecX x_before = x;
    TETFSI_PETSC(KSPSolve(ksp, vb.v, vx.v));
    allgather_rows(x.data(), n);  // every rank's rows to every rank (a no-op with one rank)
    PetscInt its = 0;
    TETFSI_PETSC(KSPGetIterationNumber(ksp, &its));
    TETFSI_PETSC(KSPGetConvergedReason(ksp, &reason));
    rep.iterations += static_cast<int>(its);
    rep.residual = true_residual();
    if (!std::isfinite(rep.residual)) {  // breakdown (NaN/Inf): keep the last finite x
      x = x_before;                      // same size, so vx still wraps x's buffer
      rep.residual = true_residual();
      break;
    }
    if (reason < 0 || its == 0) break;
  }
  if (rep.residual > opts.rel_tol)
    logger().debug("{}: not converged after {} iterations (PETSc reason {}), residual {:.3g}", name,
                   rep.iterations, KSPConvergedReasons[reason], rep.residual);
}

/// Log (debug) how much of the matrix couples two ranks' row blocks: the share of the
/// off-diagonal non-zeros whose column another rank owns (what each solve communicates).
void log_coupling(const Eigen::SparseMatrix<double, Eigen::RowMajor, Index>& csr) {
  const Index n = static_cast<Index>(csr.rows());
  long long off_diagonal = 0, across = 0;
  for (int r = 0; r < rank_count(); ++r) {
    const RowRange rows = rank_rows(n, r, rank_count());
    for (Index i = rows.begin; i < rows.end; ++i)
      for (Index q = csr.outerIndexPtr()[i]; q < csr.outerIndexPtr()[i + 1]; ++q) {
        const Index j = csr.innerIndexPtr()[q];
        off_diagonal += j != i;
        across += j < rows.begin || j >= rows.end;
      }
  }
  logger().debug(
      "{} ranks, contiguous row blocks of {} rows: {:.2f} % of the off-diagonal "
      "non-zeros couple two ranks",
      rank_count(), n, off_diagonal > 0 ? 100.0 * across / off_diagonal : 0.0);
}

/// A PETSc AIJ matrix on `csr` (compressed, row-major): sequential and sharing csr's arrays
/// with one rank; with several, the MPIAIJ matrix whose local rows are this rank's (copied).
Mat make_aij(const Eigen::SparseMatrix<double, Eigen::RowMajor, Index>& csr) {
  const Index n = static_cast<Index>(csr.rows());
  Mat m = nullptr;
  if (rank_count() == 1) {
    TETFSI_PETSC(MatCreateSeqAIJWithArrays(
        PETSC_COMM_SELF, n, n, const_cast<Index*>(csr.outerIndexPtr()),
        const_cast<Index*>(csr.innerIndexPtr()), const_cast<double*>(csr.valuePtr()), &m));
    return m;
  }
  if (rank_index() == 0 && logger().should_log(spdlog::level::debug)) log_coupling(csr);
  const RowRange rows = my_rows(n);
  const Index* outer = csr.outerIndexPtr();
  const Index first = outer[rows.begin];
  std::vector<PetscInt> starts(static_cast<size_t>(rows.size()) + 1);
  for (Index i = 0; i <= rows.size(); ++i) starts[i] = outer[rows.begin + i] - first;
  TETFSI_PETSC(MatCreateMPIAIJWithArrays(PETSC_COMM_WORLD, rows.size(), rows.size(), n, n,
                                         starts.data(), csr.innerIndexPtr() + first,
                                         csr.valuePtr() + first, &m));
  return m;
}

// ---- the solver ------------------------------------------------------------------------------

class PetscAmgSolver final : public LinearSolver {
 public:
  PetscAmgSolver(SolverKind kind, const SolverOptions& opts) : m_kind(kind), m_opts(opts) {
    ensure_petsc();
  }
  PetscAmgSolver(const PetscAmgSolver&) = delete;
  PetscAmgSolver& operator=(const PetscAmgSolver&) = delete;
  ~PetscAmgSolver() override { release(); }

  std::string name() const override { return to_string(m_kind); }

  void setup(const SparseMatrix& A) override {
    m_setup_s = detail::setup_or_release(
        name(), [&] { build(A); }, [&] { release(); });
  }

 private:
  void build(const SparseMatrix& A) {
    TETFSI_REQUIRE(SolverError, A.rows() == A.cols() && A.rows() > 0,
                   "{}: need a nonempty square matrix, got {} x {}", name(), A.rows(), A.cols());
    // PETSc AIJ is CSR: convert once and share the arrays (PETSc does not copy them).
    m_csr = A;
    m_csr.makeCompressed();
    m_mat = make_aij(m_csr);
    if (m_opts.symmetric) {
      // MUMPS reads one triangle: check, as cholmod does; and no SPD flag, which would make
      // it an LLᵀ that an indefinite matrix breaks (LDLᵀ takes both)
      TETFSI_REQUIRE(SolverError, m_kind != SolverKind::Mumps || is_symmetric(A),
                     "the {} x {} matrix is not symmetric; set symmetric false (LU) or use "
                     "umfpack",
                     A.rows(), A.cols());
      TETFSI_PETSC(MatSetOption(m_mat, MAT_SYMMETRIC, PETSC_TRUE));
      if (m_kind != SolverKind::Mumps)
        TETFSI_PETSC(MatSetOption(m_mat, MAT_SPD, PETSC_TRUE));  // CG presumes it anyway
    }

    new_ksp();
    if (is_direct_solver(m_kind)) return build_direct();
    if (m_opts.symmetric) {
      TETFSI_PETSC(KSPSetType(m_ksp, KSPCG));
    } else {
      TETFSI_PETSC(KSPSetType(m_ksp, KSPGMRES));
      TETFSI_PETSC(KSPGMRESSetRestart(m_ksp, 50));
      TETFSI_PETSC(KSPSetPCSide(m_ksp, PC_RIGHT));  // residual norm = ||b − A x||
    }
    // Stop on ||b − A x|| ≤ rel_tol ||b|| (PETSc uses ||b|| for a nonzero initial guess).
    TETFSI_PETSC(KSPSetNormType(m_ksp, KSP_NORM_UNPRECONDITIONED));
    TETFSI_PETSC(
        KSPSetTolerances(m_ksp, m_opts.rel_tol, 0.0, PETSC_DEFAULT, m_opts.max_iterations));
    TETFSI_PETSC(KSPSetInitialGuessNonzero(m_ksp, PETSC_TRUE));

    PC pc = nullptr;
    TETFSI_PETSC(KSPGetPC(m_ksp, &pc));
    if (m_kind == SolverKind::Amg) {
      TETFSI_PETSC(PCSetType(pc, PCHYPRE));
      TETFSI_PETSC(PCHYPRESetType(pc, "boomeramg"));
    } else {
      TETFSI_PETSC(PCSetType(pc, PCGAMG));
      TETFSI_PETSC(PCGAMGSetType(pc, PCGAMGAGG));
      // Smoothed aggregation for SPD; plain aggregation for nonsymmetric operators, whose
      // prolongator smoothing can make the coarse operator worse.
      TETFSI_PETSC(PCGAMGSetNSmooths(pc, m_opts.symmetric ? 1 : 0));
    }
    TETFSI_PETSC(KSPSetFromOptions(m_ksp));
    TETFSI_PETSC(KSPSetUp(m_ksp));
    TETFSI_PETSC(PCSetUp(pc));
  }

  /// m_ksp, a new KSP with this solver's options prefix on m_mat (any earlier one destroyed).
  void new_ksp() {
    if (m_ksp) KSPDestroy(&m_ksp);
    TETFSI_PETSC(KSPCreate(solve_comm(), &m_ksp));
    TETFSI_PETSC(KSPSetOptionsPrefix(m_ksp, options_prefix()));
    TETFSI_PETSC(KSPSetOperators(m_ksp, m_mat, m_mat));
  }

  /// The factorisation as the whole solve (KSPPREONLY), distributed over the ranks' rows:
  /// MUMPS's Cholesky — its LDLᵀ, which takes a symmetric indefinite matrix too — or LU;
  /// SuperLU_DIST's LU.
  ///
  /// MUMPS's parallel factorisation can outgrow the workspace its analysis estimated (its
  /// dynamic scheduling varies from run to run: INFOG(1) = −9, seen once in a few runs of a
  /// 28k-unknown Poisson on 2 ranks): then the estimate's slack, ICNTL(14), is doubled (in
  /// PETSc's options, so later set-ups keep it) and the factorisation redone, up to 3 times.
  void build_direct() {
    const bool mumps = m_kind == SolverKind::Mumps;
    for (int attempt = 0;; ++attempt) {
      if (attempt > 0) new_ksp();  // a fresh KSP on the same matrix
      TETFSI_PETSC(KSPSetType(m_ksp, KSPPREONLY));
      PC pc = nullptr;
      TETFSI_PETSC(KSPGetPC(m_ksp, &pc));
      TETFSI_PETSC(PCSetType(pc, mumps && m_opts.symmetric ? PCCHOLESKY : PCLU));
      TETFSI_PETSC(PCFactorSetMatSolverType(pc, mumps ? MATSOLVERMUMPS : MATSOLVERSUPERLU_DIST));
      TETFSI_PETSC(KSPSetFromOptions(m_ksp));
      TETFSI_PETSC(KSPSetUp(m_ksp));
      TETFSI_PETSC(PCSetUp(pc));
      PCFailedReason failed = PC_NOERROR;
      TETFSI_PETSC(PCGetFailedReason(pc, &failed));
      if (failed == PC_NOERROR) return;
      if (failed == PC_FACTOR_OUTMEMORY && mumps && attempt < 3) {
        raise_mumps_workspace();
        continue;
      }
      const bool pivot =
          failed == PC_FACTOR_STRUCT_ZEROPIVOT || failed == PC_FACTOR_NUMERIC_ZEROPIVOT;
      throw SolverError(fmt::format(
          "the factorisation failed ({}): {}", PCFailedReasons[failed],
          pivot ? "the matrix is singular"
          : failed == PC_FACTOR_OUTMEMORY
              ? fmt::format("out of workspace; raise it with PETSC_OPTIONS='{} <percent>'",
                            mumps_workspace_option())
              : fmt::format("the library's own error; PETSC_OPTIONS='-{0}ksp_view'{1} prints its "
                            "diagnostics",
                            options_prefix(),
                            mumps ? fmt::format(" (or '-{}mat_mumps_icntl_4 2')", options_prefix())
                                  : std::string())));
    }
  }

  /// PETSc's option that sets MUMPS's workspace slack ICNTL(14) for this solver.
  std::string mumps_workspace_option() const {
    return fmt::format("-{}mat_mumps_icntl_14", options_prefix());
  }

  /// Double MUMPS's workspace slack ICNTL(14) (percent over its analysis' estimate; at least +20).
  void raise_mumps_workspace() const {
    const std::string key = mumps_workspace_option();
    PetscInt now = 20;  // MUMPS's default
    PetscBool set = PETSC_FALSE;
    TETFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, key.c_str(), &now, &set));
    const std::string next = std::to_string(std::max<PetscInt>(2 * now, now + 20));
    logger().debug("mumps: out of workspace; ICNTL(14) {} -> {}", now, next);
    TETFSI_PETSC(PetscOptionsSetValue(nullptr, key.c_str(), next.c_str()));
  }

 public:
  SolveReport solve(const VecX& b, VecX& x) override {
    TETFSI_CHECK(m_ksp != nullptr, "{}: solve() called before setup()", name());
    TETFSI_CHECK(b.size() == m_csr.rows(), "{}: right-hand side has length {}, matrix is {} x {}",
                 name(), b.size(), m_csr.rows(), m_csr.cols());
    const double t0 = now_seconds();
    SolveReport rep{name(), true, 0, 0.0, m_setup_s, 0.0};
    const Index n = static_cast<Index>(b.size());
    if (x.size() != n || !x.allFinite()) x = VecX::Zero(n);
    const double bnorm = b.norm();
    if (bnorm == 0.0) {
      x.setZero();
      rep.solve_s = now_seconds() - t0;
      return rep;
    }
    try {
      if (is_direct_solver(m_kind))
        direct(b, x, rep);
      else
        krylov(b, x, rep);
    } catch (const SolverError& e) {
      throw SolverError(fmt::format("{}: {}", name(), e.what()));
    }
    rep.converged = rep.residual <= m_opts.rel_tol;
    rep.solve_s = now_seconds() - t0;
    return rep;
  }

 private:
  void krylov(const VecX& b, VecX& x, SolveReport& rep) {
    krylov_with_restarts(m_ksp, b, x, m_opts, name(), rep, [&] { return residual(b, x); });
  }

  /// One solve with the factors (iterations = 1), x every rank's whole solution.
  void direct(const VecX& b, VecX& x, SolveReport& rep) {
    const Index n = static_cast<Index>(b.size());
    WrappedVec vb(n, b.data());
    WrappedVec vx(n, x.data());
    TETFSI_PETSC(KSPSolve(m_ksp, vb.v, vx.v));
    allgather_rows(x.data(), n);
    rep.iterations = 1;
    rep.residual = residual(b, x);
  }

  /// ||b − A x|| / ||b||.
  double residual(const VecX& b, const VecX& x) const { return (b - m_csr * x).norm() / b.norm(); }

  /// Prefix of this solver's options in PETSc's database (see init_petsc_once).
  const char* options_prefix() const {
    if (m_kind == SolverKind::Mumps) return "tetfsi_mumps_";
    if (m_kind == SolverKind::SuperluDist) return "tetfsi_superlu_dist_";
    if (m_kind == SolverKind::Amg) return "tetfsi_amg_";
    return m_opts.symmetric ? "tetfsi_gamg_" : "tetfsi_gamg_nonsym_";
  }

  void release() {
    if (!petsc_finalized()) {
      if (m_ksp) KSPDestroy(&m_ksp);
      if (m_mat) MatDestroy(&m_mat);
    }
    m_ksp = nullptr;
    m_mat = nullptr;
  }

  SolverKind m_kind;
  SolverOptions m_opts;
  Eigen::SparseMatrix<double, Eigen::RowMajor, Index> m_csr;  ///< arrays shared with m_mat
  Mat m_mat = nullptr;
  KSP m_ksp = nullptr;
  double m_setup_s = 0.0;
};

// ---- BoomerAMG alone, as a preconditioner ---------------------------------------------------

class PetscAmgPreconditioner final : public AmgPreconditioner {
 public:
  PetscAmgPreconditioner() { ensure_petsc(); }
  PetscAmgPreconditioner(const PetscAmgPreconditioner&) = delete;
  PetscAmgPreconditioner& operator=(const PetscAmgPreconditioner&) = delete;
  ~PetscAmgPreconditioner() override { release(); }

  void setup(const SparseMatrix& P) override {
    const double t0 = now_seconds();
    release();
    try {
      const Index n = static_cast<Index>(P.rows());
      TETFSI_REQUIRE(SolverError, n > 0 && P.cols() == n,
                     "need a nonempty square matrix, got {} x {}", P.rows(), P.cols());
      m_n = n;
      m_csr = P;
      m_csr.makeCompressed();
      m_mat = make_aij(m_csr);
      TETFSI_PETSC(MatSetOption(m_mat, MAT_SYMMETRIC, PETSC_TRUE));
      TETFSI_PETSC(PCCreate(solve_comm(), &m_pc));
      TETFSI_PETSC(PCSetOptionsPrefix(m_pc, "tetfsi_amg_"));
      TETFSI_PETSC(PCSetOperators(m_pc, m_mat, m_mat));
      TETFSI_PETSC(PCSetType(m_pc, PCHYPRE));
      TETFSI_PETSC(PCHYPRESetType(m_pc, "boomeramg"));
      TETFSI_PETSC(PCSetFromOptions(m_pc));
      TETFSI_PETSC(PCSetUp(m_pc));
    } catch (const SolverError& e) {
      release();
      throw SolverError(fmt::format("amg preconditioner: {}", e.what()));
    }
    m_setup_s = now_seconds() - t0;
  }

  void apply(const VecX& r, VecX& z) override {
    TETFSI_CHECK(m_pc != nullptr && r.size() == m_n,
                 "amg preconditioner: apply before setup or wrong size ({} for {})", r.size(), m_n);
    z.resize(m_n);
    WrappedVec vr(m_n, r.data());
    WrappedVec vz(m_n, z.data());
    TETFSI_PETSC(PCApply(m_pc, vr.v, vz.v));
    allgather_rows(z.data(), m_n);
  }

  double setup_seconds() const override { return m_setup_s; }

 private:
  void release() {
    if (!petsc_finalized()) {
      if (m_pc) PCDestroy(&m_pc);
      if (m_mat) MatDestroy(&m_mat);
    }
    m_pc = nullptr;
    m_mat = nullptr;
  }
  Index m_n = 0;
  Eigen::SparseMatrix<double, Eigen::RowMajor, Index> m_csr;
  Mat m_mat = nullptr;
  PC m_pc = nullptr;
  double m_setup_s = 0.0;
};

}  // namespace

std::string start_petsc() {
  try {
    ensure_petsc();
  } catch (const SolverError&) {
    return g_petsc_init_error;
  }
  return {};
}

std::unique_ptr<LinearSolver> make_petsc_solver(SolverKind kind, const SolverOptions& opts) {
  TETFSI_CHECK(kind == SolverKind::Amg || kind == SolverKind::AmgGamg ||
                   kind == SolverKind::Mumps || kind == SolverKind::SuperluDist,
               "make_petsc_solver: {} is not a PETSc backend", to_string(kind));
  return std::make_unique<PetscAmgSolver>(kind, opts);
}

std::unique_ptr<AmgPreconditioner> make_petsc_preconditioner() {
  return std::make_unique<PetscAmgPreconditioner>();
}

}  // namespace tetfsi::detail
