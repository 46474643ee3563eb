/// @file solve_ranks.cpp
/// Driver ranks (solve_ranks.hpp): rank 0's mirrored solvers and the workers' loop.
#include "core/solve_ranks.hpp"

#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <thread>
#include <utility>
#include <vector>

// The C API only (Open MPI's C++ bindings would need libmpi_cxx).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/petsc_solver.hpp"
#include "core/ranks.hpp"
#include "core/struct_solver.hpp"

namespace tetfsi::detail {

namespace {

/// What rank 0 asks of the workers.
enum class Op : std::int32_t {
  MakeSolver,          ///< kind, options
  MakePreconditioner,  ///< kind Amg (BoomerAMG) or Pfmg; a grid layout follows for Pfmg
  SetGrid,             ///< a grid layout follows
  Setup,               ///< a matrix follows
  Solve,               ///< b and x follow
  Apply,               ///< r follows
  Destroy,
  Stop,
};

/// The fixed part of a call: one non-blocking broadcast, the only one a worker waits for.
struct Header {
  Op op = Op::Stop;
  std::int32_t id = 0;  ///< the mirrored object
  std::int32_t kind = 0;
  std::int32_t symmetric = 0;
  std::int32_t max_iterations = 0;
  std::int32_t pad = 0;
  double rel_tol = 0.0;
};

MPI_Comm g_comm = MPI_COMM_NULL;  ///< rank 0 and the workers' own (a duplicate of WORLD)
bool g_released = false;          ///< rank 0 has stopped the workers
int g_next_id = 0;                ///< rank 0: the next mirrored object's id

void check_mpi(int err, const char* what) {
  TETFSI_REQUIRE(SolverError, err == MPI_SUCCESS,
                 "driver ranks: {} failed with MPI error {}; run with one rank or "
                 "TETFSI_RANKS=replicated",
                 what, err);
}

/// Broadcast h from rank 0. A worker sleeps between tests (100 µs) once a short spin has not
/// found it, so that rank 0's threads keep the cores while it waits.
void broadcast_header(Header& h) {
  MPI_Request req = MPI_REQUEST_NULL;
  check_mpi(MPI_Ibcast(&h, sizeof h, MPI_BYTE, 0, g_comm, &req), "MPI_Ibcast");
  if (rank_index() == 0) {
    check_mpi(MPI_Wait(&req, MPI_STATUS_IGNORE), "MPI_Wait");
    return;
  }
  for (int tests = 0;; ++tests) {
    int done = 0;
    check_mpi(MPI_Test(&req, &done, MPI_STATUS_IGNORE), "MPI_Test");
    if (done) return;
    if (tests > 200) std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
}

/// Broadcast n values from rank 0 (n the same on every rank).
template <class T>
void broadcast(T* data, std::int64_t n, MPI_Datatype type) {
  for (std::int64_t done = 0; done < n;) {  // counts are int
    const int part = static_cast<int>(std::min<std::int64_t>(n - done, 1 << 30));
    check_mpi(MPI_Bcast(data + done, part, type, 0, g_comm), "MPI_Bcast");
    done += part;
  }
}

std::int64_t broadcast_size(std::int64_t n) {
  broadcast(&n, 1, MPI_INT64_T);
  return n;
}

/// v on rank 0 to every rank (resized on the workers).
void broadcast_vector(VecX& v) {
  const std::int64_t n = broadcast_size(v.size());
  if (rank_index() != 0) v.resize(static_cast<Index>(n));
  broadcast(v.data(), n, MPI_DOUBLE);
}

/// Rank 0's side of broadcast_vector, without a copy (MPI_Bcast only reads at the root).
void send_vector(const VecX& v) {
  broadcast_vector(const_cast<VecX&>(v));
}

/// a (rank 0's, compressed) to every rank: its sizes, then its arrays (the workers' a is
/// resized to receive them). static_assert: Index is MPI_INT.
void broadcast_matrix(SparseMatrix& a) {
  static_assert(sizeof(Index) == sizeof(int));
  std::int64_t dims[3] = {a.rows(), a.cols(), a.nonZeros()};
  broadcast(dims, 3, MPI_INT64_T);
  if (rank_index() != 0) {
    a.resize(static_cast<Index>(dims[0]), static_cast<Index>(dims[1]));
    a.resizeNonZeros(static_cast<Index>(dims[2]));
  }
  broadcast(a.outerIndexPtr(), dims[1] + 1, MPI_INT);
  broadcast(a.innerIndexPtr(), dims[2], MPI_INT);
  broadcast(a.valuePtr(), dims[2], MPI_DOUBLE);
}

/// Rank 0's side of broadcast_matrix: a itself when compressed (MPI_Bcast only reads at the
/// root), else a compressed copy.
void send_matrix(const SparseMatrix& a) {
  if (a.isCompressed()) return broadcast_matrix(const_cast<SparseMatrix&>(a));
  SparseMatrix compressed = a;
  compressed.makeCompressed();
  broadcast_matrix(compressed);
}

/// g on rank 0 to every rank (the workers' g is overwritten; rank 0's only read).
void broadcast_layout(GridLayout& g) {
  std::int64_t dims[3] = {g.dims[0], g.dims[1], g.dims[2]};
  broadcast(dims, 3, MPI_INT64_T);
  const std::int64_t n = broadcast_size(static_cast<std::int64_t>(g.cells.size()));
  if (rank_index() != 0) {
    for (int d = 0; d < 3; ++d) g.dims[d] = static_cast<Index>(dims[d]);
    g.cells.resize(static_cast<std::size_t>(n));
  }
  broadcast(g.cells.data(), n, MPI_INT);
}

/// Rank 0's side of broadcast_layout, without a copy.
void send_layout(const GridLayout& g) {
  broadcast_layout(const_cast<GridLayout&>(g));
}

/// The same solver on every rank (rank 0's inside its served solver).
std::unique_ptr<LinearSolver> make_inner_solver(SolverKind kind, const SolverOptions& opts) {
  return kind == SolverKind::Pfmg ? make_pfmg_solver(opts) : make_petsc_solver(kind, opts);
}
std::unique_ptr<AmgPreconditioner> make_inner_preconditioner(SolverKind kind,
                                                             const GridLayout& layout) {
  return kind == SolverKind::Pfmg ? detail::make_pfmg_preconditioner(layout)
                                  : detail::make_petsc_preconditioner();
}

/// Send a call to the workers (rank 0); the arguments follow with the broadcast_* above.
void call(Op op, int id, SolverKind kind = SolverKind::Amg, const SolverOptions* opts = nullptr) {
  TETFSI_CHECK(!g_released, "driver ranks: a solver call after the workers stopped");
  Header h;
  h.op = op;
  h.id = id;
  h.kind = static_cast<std::int32_t>(kind);
  if (opts != nullptr) {
    h.symmetric = opts->symmetric ? 1 : 0;
    h.max_iterations = opts->max_iterations;
    h.rel_tol = opts->rel_tol;
  }
  broadcast_header(h);
}

// ---- rank 0 ----------------------------------------------------------------------------------

/// Rank 0's handle on an object mirrored on the workers: its id, and the Destroy call when it
/// goes. A served object declares it after its inner solver, so that the Destroy goes out
/// before the inner solver is destroyed (members go in reverse order), as the workers do it.
class Mirrored {
 public:
  Mirrored() = default;
  Mirrored(const Mirrored&) = delete;
  Mirrored& operator=(const Mirrored&) = delete;
  ~Mirrored() {
    if (!g_released) call(Op::Destroy, id);
  }
  const int id = g_next_id++;
};

class ServedSolver final : public LinearSolver {
 public:
  ServedSolver(SolverKind kind, const SolverOptions& opts) {
    call(Op::MakeSolver, m_mirror.id, kind, &opts);
    m_inner = make_inner_solver(kind, opts);
  }
  std::string name() const override { return m_inner->name(); }
  void set_grid(const GridLayout& layout) override {
    call(Op::SetGrid, m_mirror.id);
    send_layout(layout);
    m_inner->set_grid(layout);
  }
  void setup(const SparseMatrix& A) override {
    call(Op::Setup, m_mirror.id);
    send_matrix(A);
    m_inner->setup(A);
  }
  SolveReport solve(const VecX& b, VecX& x) override {
    call(Op::Solve, m_mirror.id);
    send_vector(b);
    send_vector(x);
    return m_inner->solve(b, x);
  }

 private:
  std::unique_ptr<LinearSolver> m_inner;
  Mirrored m_mirror;  // after m_inner: see Mirrored
};

class ServedPreconditioner final : public AmgPreconditioner {
 public:
  explicit ServedPreconditioner(const GridLayout* layout) {
    const SolverKind kind = layout != nullptr ? SolverKind::Pfmg : SolverKind::Amg;
    call(Op::MakePreconditioner, m_mirror.id, kind);
    if (layout != nullptr) send_layout(*layout);
    m_inner = make_inner_preconditioner(kind, layout != nullptr ? *layout : GridLayout{});
  }
  void setup(const SparseMatrix& P) override {
    call(Op::Setup, m_mirror.id);
    send_matrix(P);
    m_inner->setup(P);
  }
  void apply(const VecX& r, VecX& z) override {
    call(Op::Apply, m_mirror.id);
    send_vector(r);
    m_inner->apply(r, z);
  }
  double setup_seconds() const override { return m_inner->setup_seconds(); }

 private:
  std::unique_ptr<AmgPreconditioner> m_inner;
  Mirrored m_mirror;  // after m_inner: see Mirrored
};

// ---- a worker --------------------------------------------------------------------------------

/// A worker's copy of one of rank 0's solvers, and the matrix it was set up with (which must
/// outlive the set-up).
struct Mirror {
  std::unique_ptr<LinearSolver> solver;
  std::unique_ptr<AmgPreconditioner> preconditioner;
  SparseMatrix matrix;
};

/// Receive the arguments of call h, then make it on the worker's copy.
void serve(const Header& h, std::map<int, Mirror>& objects) {
  const auto kind = static_cast<SolverKind>(h.kind);
  switch (h.op) {
    case Op::MakeSolver: {
      SolverOptions opts;
      opts.symmetric = h.symmetric != 0;
      opts.max_iterations = h.max_iterations;
      opts.rel_tol = h.rel_tol;
      objects[h.id].solver = make_inner_solver(kind, opts);
      return;
    }
    case Op::MakePreconditioner: {
      GridLayout layout;
      if (kind == SolverKind::Pfmg) broadcast_layout(layout);
      objects[h.id].preconditioner = make_inner_preconditioner(kind, layout);
      return;
    }
    case Op::SetGrid: {
      GridLayout layout;
      broadcast_layout(layout);
      objects.at(h.id).solver->set_grid(layout);
      return;
    }
    case Op::Setup: {  // the arguments first, whatever happens after: rank 0 sends them
      SparseMatrix a;
      broadcast_matrix(a);
      Mirror& m = objects.at(h.id);
      m.matrix = std::move(a);
      if (m.solver)
        m.solver->setup(m.matrix);
      else
        m.preconditioner->setup(m.matrix);
      return;
    }
    case Op::Solve: {
      VecX b, x;
      broadcast_vector(b);
      broadcast_vector(x);
      objects.at(h.id).solver->solve(b, x);
      return;
    }
    case Op::Apply: {
      VecX r, z;
      broadcast_vector(r);
      objects.at(h.id).preconditioner->apply(r, z);
      return;
    }
    case Op::Destroy:
      objects.erase(h.id);
      return;
    case Op::Stop:
      return;
  }
}

}  // namespace

void start_solve_ranks() {
  check_mpi(MPI_Comm_dup(MPI_COMM_WORLD, &g_comm), "MPI_Comm_dup");
  // After PETSc's finaliser (start_petsc registered it), so this runs before it.
  if (rank_index() == 0) std::atexit(release_solve_workers);
}

int serve_solves() {
  std::signal(SIGINT, SIG_IGN);  // rank 0 decides when the run stops
  std::signal(SIGTERM, SIG_IGN);
  std::map<int, Mirror> objects;
  for (;;) {
    Header h;
    broadcast_header(h);
    if (h.op == Op::Stop) break;
    try {
      serve(h, objects);
    } catch (const std::exception& e) {
      // Rank 0 made the same call on the same data and failed alike: it reports.
      logger().debug("solve worker {}: {}", rank_index(), e.what());
    }
  }
  return 0;
}

void release_solve_workers() {
  if (g_released || g_comm == MPI_COMM_NULL || rank_index() != 0) return;
  Header h;
  h.op = Op::Stop;
  broadcast_header(h);
  g_released = true;
}

std::unique_ptr<LinearSolver> make_served_solver(SolverKind kind, const SolverOptions& opts) {
  return std::make_unique<ServedSolver>(kind, opts);
}

std::unique_ptr<AmgPreconditioner> make_served_preconditioner(const GridLayout* layout) {
  return std::make_unique<ServedPreconditioner>(layout);
}

}  // namespace tetfsi::detail
