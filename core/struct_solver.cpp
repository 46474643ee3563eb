#include "core/struct_solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <vector>

#include <fmt/format.h>

// The C API only (Open MPI's C++ bindings would need libmpi_cxx).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <HYPRE_struct_ls.h>
#include <HYPRE_utilities.h>
#include <mpi.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "core/petsc_solver.hpp"
#include "core/ranks.hpp"
#include "core/timer.hpp"

namespace tetfsi::detail {

namespace {

/// hypre's calls return an error flag; turn a nonzero one into a SolverError.
#define TETFSI_HYPRE(call)                                                                   \
  do {                                                                                       \
    const HYPRE_Int tetfsi_hypre_err_ = (call);                                              \
    if (tetfsi_hypre_err_ != 0) {                                                            \
      HYPRE_ClearAllErrors();                                                                \
      throw SolverError(fmt::format("hypre error {} in {}", (int)tetfsi_hypre_err_, #call)); \
    }                                                                                        \
  } while (0)

/// MPI (through PETSc) and hypre up, once per process.
void ensure_hypre() {
  static std::once_flag once;
  static std::string error;
  std::call_once(once, [] {
    error = start_petsc();
    if (error.empty() && HYPRE_Init() != 0) error = "HYPRE_Init failed";
  });
  TETFSI_REQUIRE(SolverError, error.empty(), "pfmg: cannot start MPI and hypre: {}; use amg",
                 error);
}

/// The 7-point stencil: entry 0 the cell itself, then −x, +x, −y, +y, −z, +z.
constexpr std::array<std::array<HYPRE_Int, 3>, 7> k_offsets{
    {{0, 0, 0}, {-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}}};

/// The stencil entry joining cell (i, j, k) to (i2, j2, k2), −1 if they are not neighbours.
int stencil_entry(const std::array<Index, 3>& a, const std::array<Index, 3>& b) {
  for (int e = 0; e < 7; ++e)
    if (b[0] - a[0] == k_offsets[e][0] && b[1] - a[1] == k_offsets[e][1] &&
        b[2] - a[2] == k_offsets[e][2])
      return e;
  return -1;
}

/// The grid fluid's 7-point system on hypre's Struct interface, and PFMG's V-cycle on it:
/// the unknowns' bounding box (each rank its slab of z-planes), A's stencil, the vectors b
/// and x. The CG solver and the preconditioner below each hold one.
class StructSystem {
 public:
  /// @param lump entries between cells that are no face neighbours move to the diagonal by
  ///   their absolute value (a matrix no smaller than A: stays SPD for an SPD A); without
  ///   it such an entry is a SolverError
  explicit StructSystem(bool lump) : m_lump(lump) { ensure_hypre(); }
  StructSystem(const StructSystem&) = delete;
  StructSystem& operator=(const StructSystem&) = delete;
  ~StructSystem() { release(); }

  void set_grid(const GridLayout& layout) {
    TETFSI_CHECK(layout.dims[0] > 0 && layout.dims[1] > 0 && layout.dims[2] > 0,
                 "pfmg: grid of {} x {} x {} cells", layout.dims[0], layout.dims[1],
                 layout.dims[2]);
    m_layout = layout;
  }
  /// The unknowns (set_grid's cells).
  Index size() const { return static_cast<Index>(m_layout.cells.size()); }

  /// The grid, stencil, matrix and vectors for A, and the V-cycle (not set up).
  void build(const SparseMatrix& A);
  void release() {
    if (m_vcycle) HYPRE_StructPFMGDestroy(m_vcycle);
    if (m_A) HYPRE_StructMatrixDestroy(m_A);
    if (m_b) HYPRE_StructVectorDestroy(m_b);
    if (m_x) HYPRE_StructVectorDestroy(m_x);
    if (m_stencil) HYPRE_StructStencilDestroy(m_stencil);
    if (m_grid) HYPRE_StructGridDestroy(m_grid);
    m_vcycle = nullptr;
    m_A = nullptr;
    m_b = m_x = nullptr;
    m_stencil = nullptr;
    m_grid = nullptr;
  }

  /// Copy this slab's part of an unknown vector into a grid vector (0 off the unknowns).
  void to_grid(const VecX& v, HYPRE_StructVector g) const;
  /// This slab's unknowns of v from a grid vector, then every rank's to every rank.
  void from_grid(HYPRE_StructVector g, VecX& v) const;

  MPI_Comm comm() const { return rank_count() > 1 ? MPI_COMM_WORLD : MPI_COMM_SELF; }
  HYPRE_StructMatrix A() const { return m_A; }
  HYPRE_StructVector b() const { return m_b; }
  HYPRE_StructVector x() const { return m_x; }
  HYPRE_StructSolver vcycle() const { return m_vcycle; }

 private:
  /// This rank's box of the grid, [lo, hi) per axis: the unknowns' bounding box, its
  /// z-planes split among the ranks; and its unknowns [u0, u1) (unknowns are in cell order).
  struct Slab {
    std::array<Index, 3> lo{0, 0, 0}, hi{0, 0, 0};
    Index u0 = 0, u1 = 0;
    bool empty() const { return hi[2] <= lo[2]; }
    Index cells() const { return (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]); }
    /// Position of grid cell (i, j, k) in the slab's x-fastest order.
    Index at(const std::array<Index, 3>& c) const {
      return (c[0] - lo[0]) + (hi[0] - lo[0]) * ((c[1] - lo[1]) + (hi[1] - lo[1]) * (c[2] - lo[2]));
    }
    void extents(HYPRE_Int* l, HYPRE_Int* u) const {
      for (int a = 0; a < 3; ++a) {
        l[a] = static_cast<HYPRE_Int>(lo[a]);
        u[a] = static_cast<HYPRE_Int>(hi[a] - 1);
      }
    }
  };

  std::array<Index, 3> ijk(Index c) const {
    const auto& d = m_layout.dims;
    return {c % d[0], (c / d[0]) % d[1], c / (d[0] * d[1])};
  }

  void make_vcycle();
  /// Stencil values of this rank's slab (7 per cell, x fastest) from A.
  std::vector<double> stencil_values(const SparseMatrix& A) const;

  bool m_lump;
  GridLayout m_layout;
  Slab m_slab;
  std::vector<Index> m_slab_begin;  ///< per rank: the first unknown of its slab (+ the end)
  HYPRE_StructGrid m_grid = nullptr;
  HYPRE_StructStencil m_stencil = nullptr;
  HYPRE_StructMatrix m_A = nullptr;
  HYPRE_StructVector m_b = nullptr, m_x = nullptr;
  HYPRE_StructSolver m_vcycle = nullptr;
};

/// `pfmg`: hypre's CG preconditioned by one V-cycle.
class PfmgSolver final : public LinearSolver {
 public:
  explicit PfmgSolver(const SolverOptions& opts) : m_opts(opts), m_sys(false) {}
  PfmgSolver(const PfmgSolver&) = delete;
  PfmgSolver& operator=(const PfmgSolver&) = delete;
  ~PfmgSolver() override { release(); }

  std::string name() const override { return "pfmg"; }
  void set_grid(const GridLayout& layout) override { m_sys.set_grid(layout); }

  void setup(const SparseMatrix& A) override {
    m_setup_s = detail::setup_or_release(
        name(),
        [&] {
          m_sys.build(A);
          m_matrix = &A;
          make_cg();
        },
        [&] { release(); });
  }

  SolveReport solve(const VecX& b, VecX& x) override;

 private:
  void make_cg();
  void release() {
    if (m_cg) HYPRE_StructPCGDestroy(m_cg);
    m_cg = nullptr;
    m_matrix = nullptr;
    m_sys.release();
  }

  SolverOptions m_opts;
  StructSystem m_sys;
  const SparseMatrix* m_matrix = nullptr;
  HYPRE_StructSolver m_cg = nullptr;
  double m_setup_s = 0.0;
};

std::vector<double> StructSystem::stencil_values(const SparseMatrix& A) const {
  std::vector<double> v(7 * static_cast<std::size_t>(m_slab.cells()), 0.0);
  for (Index c = 0; c < m_slab.cells(); ++c) v[7 * c] = 1.0;  // identity off the unknowns
  // A is symmetric: column i holds row i's entries.
  parallel_for_chunks(m_slab.u1 - m_slab.u0, 8192, [&](Index begin, Index end) {
    for (Index i = m_slab.u0 + begin; i < m_slab.u0 + end; ++i) {
      const Index c = m_layout.cells[i];
      const auto a = ijk(c);
      double* row = &v[7 * static_cast<std::size_t>(m_slab.at(a))];
      row[0] = 0.0;
      for (SparseMatrix::InnerIterator it(A, i); it; ++it) {
        const Index c2 = m_layout.cells[it.row()];
        const int e = stencil_entry(a, ijk(c2));
        if (e < 0 && m_lump) {
          row[0] += std::abs(it.value());
          continue;
        }
        TETFSI_REQUIRE(SolverError, e >= 0,
                       "the matrix joins grid cells {} and {}, which are not face neighbours", c,
                       c2);
        row[e] += it.value();
      }
    }
  });
  return v;
}

void StructSystem::build(const SparseMatrix& A) {
  const auto& d = m_layout.dims;
  const Index n = static_cast<Index>(m_layout.cells.size());
  TETFSI_REQUIRE(SolverError, n > 0 && A.rows() == n && A.cols() == n,
                 "needs the grid cells of the unknowns (LinearSolver::set_grid) and a square "
                 "matrix over them: {} cells for a {} x {} matrix; pfmg serves the grid fluid "
                 "(fluid.discretization \"grid\") only",
                 n, A.rows(), A.cols());
  // The unknowns' bounding box (a liquid fills part of the grid), each rank its z-planes of
  // it; the unknowns of a rank's planes follow one another in cell order.
  std::array<Index, 3> lo = ijk(m_layout.cells.front()), hi = lo;
  for (const Index c : m_layout.cells) {
    const auto q = ijk(c);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], q[a]);
      hi[a] = std::max(hi[a], q[a] + 1);
    }
  }
  const int nr = rank_count();
  m_slab_begin.assign(nr + 1, n);
  Index u = 0;
  for (int r = 0; r < nr; ++r) {
    const RowRange planes = rank_rows(hi[2] - lo[2], r, nr);
    while (u < n && m_layout.cells[u] < d[0] * d[1] * (lo[2] + planes.begin)) ++u;
    m_slab_begin[r] = u;
    if (r == rank_index()) {
      m_slab.lo = {lo[0], lo[1], lo[2] + planes.begin};
      m_slab.hi = {hi[0], hi[1], lo[2] + planes.end};
    }
  }
  m_slab.u0 = m_slab_begin[rank_index()];
  m_slab.u1 = m_slab_begin[rank_index() + 1];

  TETFSI_HYPRE(HYPRE_StructGridCreate(comm(), 3, &m_grid));
  HYPRE_Int elo[3], ehi[3];
  m_slab.extents(elo, ehi);
  if (!m_slab.empty()) TETFSI_HYPRE(HYPRE_StructGridSetExtents(m_grid, elo, ehi));
  TETFSI_HYPRE(HYPRE_StructGridAssemble(m_grid));
  TETFSI_HYPRE(HYPRE_StructStencilCreate(3, 7, &m_stencil));
  for (int e = 0; e < 7; ++e) {
    HYPRE_Int off[3] = {k_offsets[e][0], k_offsets[e][1], k_offsets[e][2]};
    TETFSI_HYPRE(HYPRE_StructStencilSetElement(m_stencil, e, off));
  }
  TETFSI_HYPRE(HYPRE_StructMatrixCreate(comm(), m_grid, m_stencil, &m_A));
  TETFSI_HYPRE(HYPRE_StructMatrixInitialize(m_A));
  if (!m_slab.empty()) {
    std::vector<double> values = stencil_values(A);
    HYPRE_Int entries[7] = {0, 1, 2, 3, 4, 5, 6};
    TETFSI_HYPRE(HYPRE_StructMatrixSetBoxValues(m_A, elo, ehi, 7, entries, values.data()));
  }
  TETFSI_HYPRE(HYPRE_StructMatrixAssemble(m_A));
  for (HYPRE_StructVector* v : {&m_b, &m_x}) {
    TETFSI_HYPRE(HYPRE_StructVectorCreate(comm(), m_grid, v));
    TETFSI_HYPRE(HYPRE_StructVectorInitialize(*v));
    TETFSI_HYPRE(HYPRE_StructVectorAssemble(*v));
  }
  make_vcycle();
}

void StructSystem::make_vcycle() {
  // One V-cycle per CG iteration, symmetric red–black Gauss–Seidel (1 sweep each way), the
  // Galerkin coarse operators (the masked cells and the pins make the coefficients jump).
  TETFSI_HYPRE(HYPRE_StructPFMGCreate(comm(), &m_vcycle));
  TETFSI_HYPRE(HYPRE_StructPFMGSetMaxIter(m_vcycle, 1));
  TETFSI_HYPRE(HYPRE_StructPFMGSetTol(m_vcycle, 0.0));
  TETFSI_HYPRE(HYPRE_StructPFMGSetZeroGuess(m_vcycle));
  // Measured on dam_break at 249,600 cells: 12 iterations; weighted Jacobi 16 (1.4x the
  // time), no skipped relaxation 10 (1.2x), 2 + 2 sweeps 9 (the same time), non-Galerkin
  // coarse stencils the same.
  TETFSI_HYPRE(HYPRE_StructPFMGSetRelaxType(m_vcycle, 2));
  TETFSI_HYPRE(HYPRE_StructPFMGSetRAPType(m_vcycle, 0));
  TETFSI_HYPRE(HYPRE_StructPFMGSetNumPreRelax(m_vcycle, 1));
  TETFSI_HYPRE(HYPRE_StructPFMGSetNumPostRelax(m_vcycle, 1));
}

void PfmgSolver::make_cg() {
  // CG on the true 2-norm: stop on ||r|| ≤ rel_tol ||b||, as the other backends.
  TETFSI_HYPRE(HYPRE_StructPCGCreate(m_sys.comm(), &m_cg));
  TETFSI_HYPRE(HYPRE_StructPCGSetTol(m_cg, m_opts.rel_tol));
  TETFSI_HYPRE(HYPRE_StructPCGSetAbsoluteTol(m_cg, 0.0));
  TETFSI_HYPRE(HYPRE_StructPCGSetTwoNorm(m_cg, 1));
  TETFSI_HYPRE(HYPRE_StructPCGSetRelChange(m_cg, 0));
  TETFSI_HYPRE(HYPRE_StructPCGSetMaxIter(m_cg, m_opts.max_iterations));
  TETFSI_HYPRE(HYPRE_StructPCGSetPrecond(m_cg, HYPRE_StructPFMGSolve, HYPRE_StructPFMGSetup,
                                         m_sys.vcycle()));
  TETFSI_HYPRE(HYPRE_StructPCGSetup(m_cg, m_sys.A(), m_sys.b(), m_sys.x()));
}

/// One V-cycle as the coupled Schur-CG's preconditioner (see make_pfmg_preconditioner).
class PfmgPreconditioner final : public AmgPreconditioner {
 public:
  explicit PfmgPreconditioner(const GridLayout& layout) : m_sys(true) { m_sys.set_grid(layout); }

  void setup(const SparseMatrix& P) override {
    m_setup_s = detail::setup_or_release(
        "pfmg",
        [&] {
          m_sys.build(P);
          TETFSI_HYPRE(HYPRE_StructPFMGSetup(m_sys.vcycle(), m_sys.A(), m_sys.b(), m_sys.x()));
        },
        [&] { m_sys.release(); });
  }

  /// z = one V-cycle on r from zero.
  void apply(const VecX& r, VecX& z) override {
    const Index n = m_sys.size();
    TETFSI_CHECK(m_sys.vcycle() != nullptr && r.size() == n,
                 "pfmg preconditioner: apply before setup or wrong size ({} for {})", r.size(), n);
    z = VecX::Zero(n);
    try {
      m_sys.to_grid(r, m_sys.b());
      TETFSI_HYPRE(HYPRE_StructVectorSetConstantValues(m_sys.x(), 0.0));
      TETFSI_HYPRE(HYPRE_StructPFMGSolve(m_sys.vcycle(), m_sys.A(), m_sys.b(), m_sys.x()));
      m_sys.from_grid(m_sys.x(), z);
    } catch (const SolverError& e) {
      throw SolverError(fmt::format("pfmg preconditioner: {}", e.what()));
    }
  }
  double setup_seconds() const override { return m_setup_s; }

 private:
  StructSystem m_sys;
  double m_setup_s = 0.0;
};

void StructSystem::to_grid(const VecX& v, HYPRE_StructVector g) const {
  if (m_slab.empty()) return;
  std::vector<double> values(static_cast<std::size_t>(m_slab.cells()), 0.0);
  for (Index i = m_slab.u0; i < m_slab.u1; ++i) values[m_slab.at(ijk(m_layout.cells[i]))] = v[i];
  HYPRE_Int lo[3], hi[3];
  m_slab.extents(lo, hi);
  TETFSI_HYPRE(HYPRE_StructVectorSetBoxValues(g, lo, hi, values.data()));
}

void StructSystem::from_grid(HYPRE_StructVector g, VecX& v) const {
  if (!m_slab.empty()) {
    std::vector<double> values(static_cast<std::size_t>(m_slab.cells()));
    HYPRE_Int lo[3], hi[3];
    m_slab.extents(lo, hi);
    TETFSI_HYPRE(HYPRE_StructVectorGetBoxValues(g, lo, hi, values.data()));
    for (Index i = m_slab.u0; i < m_slab.u1; ++i) v[i] = values[m_slab.at(ijk(m_layout.cells[i]))];
  }
  allgather_blocks(v.data(), m_slab_begin);
}

SolveReport PfmgSolver::solve(const VecX& b, VecX& x) {
  TETFSI_CHECK(m_cg != nullptr, "pfmg: solve() called before setup()");
  const Index n = m_sys.size();
  TETFSI_CHECK(b.size() == n, "pfmg: right-hand side has length {} for {} unknowns", b.size(), n);
  const double t0 = now_seconds();
  SolveReport rep{name(), true, 0, 0.0, m_setup_s, 0.0};
  if (x.size() != n || !x.allFinite()) x = VecX::Zero(n);
  const double bnorm = b.norm();
  if (bnorm == 0.0) {
    x.setZero();
    rep.solve_s = now_seconds() - t0;
    return rep;
  }
  const auto true_residual = [&] { return (b - *m_matrix * x).norm() / bnorm; };
  rep.residual = true_residual();
  // Restart from x when hypre's recursive residual met the tolerance and the true one did
  // not (rare; a few restarts at most), as the PETSc backends do.
  for (int round = 0; round <= 5; ++round) {
    const int left = m_opts.max_iterations - rep.iterations;
    if (rep.residual <= m_opts.rel_tol || left <= 0) break;
    try {
      TETFSI_HYPRE(HYPRE_StructPCGSetMaxIter(m_cg, left));
      m_sys.to_grid(b, m_sys.b());
      m_sys.to_grid(x, m_sys.x());
      const VecX x_before = x;
      // A breakdown (e.g. an indefinite matrix) comes back as a hypre error flag: keep x.
      const HYPRE_Int err = HYPRE_StructPCGSolve(m_cg, m_sys.A(), m_sys.b(), m_sys.x());
      HYPRE_ClearAllErrors();
      HYPRE_Int its = 0;
      HYPRE_StructPCGGetNumIterations(m_cg, &its);
      rep.iterations += static_cast<int>(its);
      m_sys.from_grid(m_sys.x(), x);
      rep.residual = true_residual();
      if (!std::isfinite(rep.residual)) {
        x = x_before;
        rep.residual = true_residual();
        break;
      }
      if (its == 0 || (err != 0 && rep.residual > m_opts.rel_tol)) break;
    } catch (const SolverError& e) {
      throw SolverError(fmt::format("pfmg: {}", e.what()));
    }
  }
  rep.converged = rep.residual <= m_opts.rel_tol;
  if (!rep.converged)
    logger().debug("pfmg: not converged after {} iterations, residual {:.3g}", rep.iterations,
                   rep.residual);
  rep.solve_s = now_seconds() - t0;
  return rep;
}

}  // namespace

std::unique_ptr<AmgPreconditioner> make_pfmg_preconditioner(const GridLayout& layout) {
  return std::make_unique<PfmgPreconditioner>(layout);
}

std::unique_ptr<LinearSolver> make_pfmg_solver(const SolverOptions& opts) {
  TETFSI_REQUIRE(InputError, opts.symmetric,
                 "pfmg: the structured multigrid is CG's preconditioner: symmetric systems only");
  return std::make_unique<PfmgSolver>(opts);
}

}  // namespace tetfsi::detail
