#pragma once
/// @file linear_solver.hpp
/// Sparse linear solvers behind one interface. Every solve returns a `SolveReport` so the
/// caller (the step driver) can react to a failed or slow solve instead of crashing.
///
/// Backends:
///  - `cholmod`        CHOLMOD supernodal Cholesky (SPD only)            [direct]
///  - `umfpack`        UMFPACK LU (any nonsingular matrix)               [direct]
///  - `bicgstab_ilut`  Eigen BiCGSTAB + IncompleteLUT (the paper's choice) [iterative]
///  - `cg_ic`          Eigen CG + IncompleteCholesky (SPD)               [iterative]
///  - `amg`            PETSc CG (SPD) or GMRES (`symmetric=false`) preconditioned by
///                     hypre BoomerAMG through PETSc                     [iterative]
///  - `amg_gamg`       the same with PETSc's own smoothed-aggregation GAMG [iterative]
///  - `pfmg`           CG preconditioned by hypre's structured-grid multigrid PFMG, for the
///                     7-point systems of the grid fluid (needs `set_grid`) [iterative]
///  - `mumps`          MUMPS through PETSc: LDLᵀ for `symmetric` (checked, as cholmod's;
///                     indefinite matrices too), else LU; under mpirun the factorisation
///                     is distributed over the ranks                        [direct]
///  - `superlu_dist`   SuperLU_DIST's LU through PETSc (any nonsingular matrix), distributed
///                     over the ranks under mpirun                          [direct]
///
/// Conventions of every backend:
///  - `cholmod` and `cg_ic` check symmetry in `setup` (|A − Aᵀ| ≤ 1e-12 max|A|) and throw
///    `SolverError` for a nonsymmetric matrix rather than use half of it;
///  - iterative solves start from x (zeros if x has the wrong size or is not finite), stop
///    on the *true* residual ||b − A x|| ≤ rel_tol ||b|| (restarting if the Krylov method's
///    recursive residual drifted), and return x = 0, iterations = 0 for b = 0;
///  - the direct solvers factor a 64-bit-index copy of A (SuiteSparse's int versions ran
///    out of workspace on 3D problems of a few 100k unknowns).
///
/// PETSc (and with it MPI) is initialised lazily by the first `amg`/`amg_gamg` solver and
/// finalised at program exit; a program that never makes one never touches MPI. PETSc
/// errors become `SolverError`; a failing MPI start (e.g. a bad `OMPI_MCA_*` setting) is
/// Open MPI's and aborts. The one-time start costs ~0.1–0.2 s (it is not in `setup_s`).
///
/// Symmetric but possibly indefinite systems (e.g. 3n × 3n StVK stiffness under
/// compression): try `cholmod`; its `setup` throws `SolverError` when the matrix is not
/// SPD, and the caller falls back to `umfpack`, which takes any nonsingular matrix.
#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "core/types.hpp"

namespace tetfsi {

enum class SolverKind {
  Cholmod,
  Umfpack,
  BiCgStabIlut,
  CgIc,
  Amg,
  AmgGamg,
  Pfmg,
  Mumps,
  SuperluDist
};
inline constexpr EnumNames<SolverKind, 9> k_solver_kind_names{
    "linear solver",
    {{{SolverKind::Cholmod, "cholmod"},
      {SolverKind::Umfpack, "umfpack"},
      {SolverKind::BiCgStabIlut, "bicgstab_ilut"},
      {SolverKind::CgIc, "cg_ic"},
      {SolverKind::Amg, "amg"},
      {SolverKind::AmgGamg, "amg_gamg"},
      {SolverKind::Pfmg, "pfmg"},
      {SolverKind::Mumps, "mumps"},
      {SolverKind::SuperluDist, "superlu_dist"}}}};

/// Whether `kind` factorises (one solve = one iteration, to round-off).
bool is_direct_solver(SolverKind kind);

/// All backend names in a stable order, e.g. for `--help` and benchmarks.
const std::vector<std::string>& solver_names();
/// Name ↔ kind. @throws InputError naming the unknown name and the valid ones.
SolverKind parse_solver_kind(const std::string& name);
std::string to_string(SolverKind kind);

struct SolverOptions {
  double rel_tol = 1e-8;        ///< iterative: stop when ||b − A x|| ≤ rel_tol ||b||
  int max_iterations = 1000;    ///< iterative: give up (converged = false) after this many
  bool symmetric = true;        ///< matrix is symmetric (amg: CG if true, GMRES otherwise)
  double ilut_drop_tol = 1e-4;  ///< bicgstab_ilut: IncompleteLUT drop tolerance
  int ilut_fill = 20;           ///< bicgstab_ilut: IncompleteLUT fill factor
};

struct SolveReport {
  std::string backend;     ///< backend name, as in solver_names()
  bool converged = false;  ///< residual ≤ rel_tol (iterative) or factorization succeeded (direct)
  int iterations = 0;      ///< Krylov iterations (1 for a direct solve)
  double residual = 0.0;   ///< true relative residual ||b − A x|| / ||b|| (0 if b = 0)
  double setup_s = 0.0;    ///< seconds of the last setup() (factorization / preconditioner)
  double solve_s = 0.0;    ///< seconds of this solve
  /// The round-off floor of the true relative residual, measured when an iterative solve
  /// stops above rel_tol (0 otherwise): what evaluating the operator adds to any residual.
  double floor = 0.0;
  /// The iteration stopped because the true residual no longer decreased (not because it
  /// ran out of iterations).
  bool stagnated = false;
};

/// Where the unknowns of a system sit on a regular grid of dims[0] × dims[1] × dims[2] cells
/// (cell id i + dims[0] (j + dims[1] k)): unknown u is cell cells[u], ids increasing.
struct GridLayout {
  std::array<Index, 3> dims{0, 0, 0};
  std::vector<Index> cells;
};

/// A solver for A x = b with A fixed between `setup` and any number of `solve` calls.
class LinearSolver {
 public:
  virtual ~LinearSolver() = default;
  virtual std::string name() const = 0;
  /// The grid cells of the unknowns of the next `setup`'s matrix. Structured backends
  /// (`pfmg`) need it; the others ignore it.
  virtual void set_grid(const GridLayout& /*layout*/) {}
  /// Analyse/factor A or build the preconditioner. A must stay alive until the next setup.
  /// @throws SolverError if the factorization fails (e.g. CHOLMOD on a non-SPD matrix).
  virtual void setup(const SparseMatrix& A) = 0;
  /// Solve A x = b. For iterative backends x is the initial guess on entry.
  /// Never throws for non-convergence: the report says so.
  virtual SolveReport solve(const VecX& b, VecX& x) = 0;
};

std::unique_ptr<LinearSolver> make_linear_solver(SolverKind kind, const SolverOptions& opts = {});

/// A direct solver set up for a symmetric A that is usually positive definite (a body's
/// trapezoidal or tangent matrix): CHOLMOD, or UMFPACK when CHOLMOD finds A not positive
/// definite (StVK under strong compression).
/// @throws SolverError if both factorizations fail.
std::unique_ptr<LinearSolver> factor_symmetric(const SparseMatrix& A);

/// One application of hypre BoomerAMG (a V-cycle, tuned as for `amg`, options prefix
/// `tetfsi_amg_`) as a preconditioner z ≈ P⁻¹ r, for Krylov methods written outside the
/// solver layer (coupling/coupled_system.cpp).
class AmgPreconditioner {
 public:
  virtual ~AmgPreconditioner() = default;
  /// P must stay alive until the next setup. @throws SolverError if the setup fails.
  virtual void setup(const SparseMatrix& P) = 0;
  virtual void apply(const VecX& r, VecX& z) = 0;
  virtual double setup_seconds() const = 0;
};
/// @throws SolverError if PETSc cannot be initialised.
std::unique_ptr<AmgPreconditioner> make_amg_preconditioner();
/// One V-cycle of hypre's structured multigrid PFMG (as the `pfmg` backend's) on P's
/// 7-point part over `layout`'s cells; P's entries joining cells that are no face neighbours
/// (the bodies' couplings Jᵀ D J) are moved to the diagonal by their absolute value.
/// @throws SolverError if MPI cannot be started.
std::unique_ptr<AmgPreconditioner> make_pfmg_preconditioner(const GridLayout& layout);

/// Start the AMG backends' libraries (PETSc, and with it Open MPI) now, if nobody did; a
/// failure is left for the first AMG solver to report. Call it before a run allocates its
/// meshes: Open MPI's start (singleton, without mpirun) forks a helper process, and every page
/// the parent holds then is copy-on-write until it writes it again — started lazily at the
/// first solve of `smoke_plume` at 268k cells, that cost the next two remeshes 0.8 s.
void start_amg_backends();

/// True relative residual ||b − A x||₂ / ||b||₂ (||A x||₂ if b = 0, so x = 0 gives 0).
/// @param A n × n, @param b length n, @param x length n.
double relative_residual(const SparseMatrix& A, const VecX& b, const VecX& x);

/// Whether A is square and |A_ij − A_ji| ≤ rel_tol · max|A| for all i, j.
bool is_symmetric(const SparseMatrix& A, double rel_tol = 1e-12);

namespace detail {

/// A backend's set-up: release(), then build(); if build throws, release() again (no
/// half-built solver: solve() refuses until a set-up succeeds) and rethrow, a SolverError
/// as "<name>: <message>". @returns the seconds it took.
double setup_or_release(const std::string& name, const std::function<void()>& build,
                        const std::function<void()>& release);

}  // namespace detail

}  // namespace tetfsi
