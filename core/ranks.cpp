#include "core/ranks.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <vector>

#ifdef __linux__
#include <sched.h>
#endif

// The C API only (Open MPI's C++ bindings would need libmpi_cxx).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/petsc_solver.hpp"
#include "core/solve_ranks.hpp"

namespace tetfsi {

namespace {

int g_rank = 0;
int g_count = 1;
RanksMode g_mode = RanksMode::Driver;

bool env_set(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0';
}

/// MPI is up (this process started it through PETSc, or a host program did).
bool mpi_up() {
  int up = 0, down = 0;
  MPI_Initialized(&up);
  MPI_Finalized(&down);
  return up != 0 && down == 0 && g_count > 1;
}

}  // namespace

bool started_by_mpirun() {
  return env_set("OMPI_COMM_WORLD_SIZE") || env_set("PMI_SIZE") || env_set("PMIX_RANK");
}

namespace {

/// TETFSI_RANKS: driver (default) or replicated.
/// @throws InputError for another value.
RanksMode mode_from_environment() {
  const char* v = std::getenv("TETFSI_RANKS");
  if (v == nullptr || *v == '\0' || std::strcmp(v, "driver") == 0) return RanksMode::Driver;
  if (std::strcmp(v, "replicated") == 0) return RanksMode::Replicated;
  throw InputError(fmt::format(
      "TETFSI_RANKS is '{}': it must be driver (rank 0 runs the step, the other ranks join its "
      "solves) or replicated (every rank runs the step)",
      v));
}

/// Let this process run on every online core. Open MPI binds each rank to one core (for up to
/// 2 ranks, by default), which would put all of a driver rank 0's threads on one core. The
/// kernel keeps the process within its cgroup's cores whatever the mask.
void unbind_from_cores() {
#ifdef __linux__
  cpu_set_t all;
  CPU_ZERO(&all);
  const unsigned n = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned c = 0; c < n && c < CPU_SETSIZE; ++c) CPU_SET(c, &all);
  if (sched_setaffinity(0, sizeof all, &all) != 0)
    logger().debug("rank 0: cannot widen its core binding ({})", std::strerror(errno));
#endif
}

}  // namespace

void start_ranks() {
  static bool done = false;
  if (done || !started_by_mpirun()) return;
  done = true;
  const std::string error = detail::start_petsc();
  TETFSI_REQUIRE(SolverError, error.empty(),
                 "MPI cannot start: {}; run without mpirun, or check the Open MPI installation "
                 "(as root it needs OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1)",
                 error);
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &g_count);
  g_mode = mode_from_environment();  // every rank fails alike, rank 0 says it
  if (g_mode == RanksMode::Driver && g_count > 1) {
    detail::start_solve_ranks();
    if (g_rank == 0) unbind_from_cores();  // before TBB starts its threads
  }
}

int rank_index() {
  return g_rank;
}
int rank_count() {
  return g_count;
}

RanksMode ranks_mode() {
  return g_mode;
}
int simulation_rank_count() {
  return g_mode == RanksMode::Driver ? 1 : g_count;
}
bool is_solve_worker() {
  return g_mode == RanksMode::Driver && g_rank > 0;
}
bool drives_solve_workers() {
  return g_mode == RanksMode::Driver && g_rank == 0 && g_count > 1;
}
int serve_solves() {
  return detail::serve_solves();
}

int ranks_on_this_node() {
  const char* v = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
  if (v == nullptr) return 1;
  const int n = std::atoi(v);
  return n >= 1 ? n : 1;
}

RowRange rank_rows(Index n, int rank, int count) {
  const Index base = n / count, extra = n % count;
  RowRange r;
  r.begin = rank * base + std::min<Index>(rank, extra);
  r.end = r.begin + base + (rank < extra ? 1 : 0);
  return r;
}

void allgather_rows(double* x, Index n) {
  if (!mpi_up()) return;
  std::vector<Index> begin(g_count + 1, n);
  for (int r = 0; r < g_count; ++r) begin[r] = rank_rows(n, r, g_count).begin;
  allgather_blocks(x, begin);
}

void allgather_blocks(double* x, const std::vector<Index>& begin) {
  if (!mpi_up()) return;
  TETFSI_CHECK(static_cast<int>(begin.size()) == g_count + 1,
               "allgather_blocks: {} block starts for {} ranks", begin.size(), g_count);
  std::vector<int> counts(g_count), offsets(g_count);
  for (int r = 0; r < g_count; ++r) {
    counts[r] = static_cast<int>(begin[r + 1] - begin[r]);
    offsets[r] = static_cast<int>(begin[r]);
  }
  const int err = MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, x, counts.data(),
                                 offsets.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  TETFSI_REQUIRE(SolverError, err == MPI_SUCCESS, "MPI_Allgatherv failed with error {}", err);
}

bool same_on_all_ranks(double value) {
  if (!mpi_up()) return true;
  long long bits = 0;
  static_assert(sizeof bits == sizeof value);
  std::memcpy(&bits, &value, sizeof bits);
  long long lo = 0, hi = 0;
  MPI_Allreduce(&bits, &lo, 1, MPI_LONG_LONG, MPI_MIN, MPI_COMM_WORLD);
  MPI_Allreduce(&bits, &hi, 1, MPI_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
  return lo == hi;
}

std::string root_decides(const std::string& text) {
  if (!mpi_up()) return text;
  long long n = static_cast<long long>(text.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  std::string out = g_rank == 0 ? text : std::string(static_cast<size_t>(n), '\0');
  if (n > 0) MPI_Bcast(out.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD);
  return out;
}

}  // namespace tetfsi
