#pragma once
/// @file ranks.hpp
/// MPI ranks (Open MPI, started through PETSc; MPI stays out of this header).
///
/// Under `mpirun -np N tetfsi run SCENE` the linear solves that go through PETSc and hypre
/// (the `amg`, `amg_gamg`, `mumps`, `superlu_dist` and `pfmg` solvers and the BoomerAMG / PFMG
/// preconditioners of the coupled Schur-CG) are distributed: rank r owns the rows
/// rank_rows(n, r, N) of each matrix (a slab of z-planes for `pfmg`), PETSc and hypre solve
/// over all ranks, and the solution is gathered back to every rank (allgather_rows). Around
/// the solves the ranks work in one of two ways (RanksMode, `TETFSI_RANKS`):
///  - `driver` (the default): rank 0 alone advances the state, on all of the node's threads;
///    the other ranks (solve workers) wait, asleep, for rank 0's solves and join them
///    (core/solve_ranks.hpp): rank 0 sends them each matrix and right-hand side.
///  - `replicated`: every rank builds the same meshes and advances the same state, each on
///    its share of the node's cores, and the state stays the same on every rank.
/// Rank 0 writes the output. Without mpirun (or with -np 1) there is one rank and nothing
/// here communicates.
#include <string>
#include <vector>

#include "core/types.hpp"

namespace tetfsi {

/// Whether this process was started by an MPI launcher (Open MPI's mpirun / mpiexec sets
/// OMPI_COMM_WORLD_SIZE; PMI_SIZE and PMIX_RANK are checked too).
bool started_by_mpirun();

/// Start MPI now (through PETSc) if this process was started by mpirun; a no-op otherwise
/// and on every later call. Call it first thing in main, before any thread starts.
/// @throws SolverError "MPI cannot start: ..." if MPI or PETSc cannot be initialised.
void start_ranks();

/// This process's rank (0 without MPI) and the number of ranks (1 without MPI).
int rank_index();
int rank_count();

/// How the ranks share a run (see the file comment): `TETFSI_RANKS` = `driver` (default) or
/// `replicated`, read by start_ranks.
enum class RanksMode { Driver, Replicated };
RanksMode ranks_mode();
/// The ranks that advance the simulation's state: 1 with driver ranks, rank_count() with
/// replicated ones.
int simulation_rank_count();
/// This rank only joins rank 0's solves (driver ranks, rank > 0).
bool is_solve_worker();
/// Rank 0 of driver ranks with workers: its PETSc and hypre solves go through the workers.
bool drives_solve_workers();
/// A solve worker's whole life (is_solve_worker()): join rank 0's solves until rank 0 stops
/// (at its exit, whatever the reason). Returns the exit code (0).
int serve_solves();
inline bool is_root_rank() {
  return rank_index() == 0;
}

/// The ranks of this job on this machine (Open MPI's OMPI_COMM_WORLD_LOCAL_SIZE; 1 without
/// mpirun): with replicated ranks the default thread count shares the cores among them.
int ranks_on_this_node();

/// The rows [begin, end) of an n-row system that rank `rank` of `count` owns: contiguous
/// blocks, the first n % count of them one row longer.
struct RowRange {
  Index begin = 0, end = 0;
  Index size() const { return end - begin; }
};
RowRange rank_rows(Index n, int rank, int count);

/// x (length n on every rank) gets on every rank the rows each rank owns (rank_rows) from
/// that rank: MPI_Allgatherv. A no-op with one rank.
void allgather_rows(double* x, Index n);
/// x on every rank gets rows [begin[r], begin[r + 1]) from rank r (begin: rank_count() + 1
/// entries, non-decreasing): MPI_Allgatherv. A no-op with one rank.
void allgather_blocks(double* x, const std::vector<Index>& begin);

/// Whether `value` is the same on every rank (bit for bit). True with one rank.
bool same_on_all_ranks(double value);

/// Rank 0's `text` on every rank (MPI_Bcast of its length and bytes). `text` with one rank.
std::string root_decides(const std::string& text);

}  // namespace tetfsi
