#pragma once
/// @file solve_ranks.hpp
/// Internal: driver ranks (core/ranks.hpp, RanksMode::Driver). Rank 0 advances the state
/// alone; every PETSc or hypre solver it makes (make_linear_solver's `amg`, `amg_gamg`,
/// `mumps`, `superlu_dist`, `pfmg`; make_amg_preconditioner, make_pfmg_preconditioner) is
/// mirrored on the other ranks, the solve workers: each call on rank 0 (set_grid, setup,
/// solve, apply) is first sent to the workers with its arguments (the matrix, the vectors, the
/// grid layout; MPI_Bcast on a communicator of their own), then every rank makes the same call
/// on its own copy of the solver, which distributes the work over the ranks as with replicated
/// ranks (each rank its rows, the solution gathered back). The results on rank 0 are those of
/// replicated ranks bit for bit: the same code runs on the same data.
///
/// A worker waits for rank 0's next call asleep (a non-blocking broadcast tested every
/// 100 µs), so that rank 0's threads have the cores between the solves. A worker ignores
/// Ctrl-C and SIGTERM (rank 0 stops the run and then the workers); it stops when rank 0 says
/// so, at rank 0's exit whatever the reason.
#include <memory>

#include "core/linear_solver.hpp"

namespace tetfsi::detail {

/// Collective over every rank, from start_ranks: the workers' communicator, and on rank 0 the
/// exit hook that stops the workers.
void start_solve_ranks();

/// A worker's life: serve rank 0's solves until rank 0 stops. Returns the process's exit code
/// (0). Call it on every rank but 0 of driver ranks, instead of the command.
int serve_solves();

/// Rank 0: tell the workers to stop (once; later calls do nothing). Also run at exit.
void release_solve_workers();

/// Rank 0's side of a mirrored solver (drives_solve_workers()): kind is a PETSc kind or
/// SolverKind::Pfmg.
std::unique_ptr<LinearSolver> make_served_solver(SolverKind kind, const SolverOptions& opts);
/// Rank 0's side of a mirrored BoomerAMG preconditioner (layout null) or PFMG (its layout).
std::unique_ptr<AmgPreconditioner> make_served_preconditioner(const GridLayout* layout);

}  // namespace tetfsi::detail
