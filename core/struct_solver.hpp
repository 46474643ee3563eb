#pragma once
/// @file struct_solver.hpp
/// Internal: the `pfmg` backend, CG preconditioned by one V-cycle of hypre's PFMG
/// (semicoarsening geometric multigrid on a structured grid, through hypre's Struct
/// interface) [Ashby & Falgout 1996; Falgout & Jones 2000]. Keeps hypre out of every header;
/// only `core/struct_solver.cpp` includes it.
///
/// It solves the 7-point systems of the MAC-grid fluid: LinearSolver::set_grid says which
/// grid cell each unknown is (cells not listed get an identity row), `setup` copies A's
/// entries into the grid's stencil (each must join a cell to itself or to one of its six
/// face neighbours), and `solve` runs hypre's PCG to ||b − A x|| ≤ rel_tol ||b|| on the true
/// residual. The set-up is a few passes over the grid instead of BoomerAMG's graph
/// coarsening. Under mpirun each rank owns a slab of z-planes and the solution is gathered
/// to every rank (core/ranks.hpp).
#include <memory>

#include "core/linear_solver.hpp"

namespace tetfsi::detail {

/// @throws SolverError if MPI cannot be started (through PETSc).
std::unique_ptr<LinearSolver> make_pfmg_solver(const SolverOptions& opts);

/// One PFMG V-cycle as a preconditioner (see tetfsi::make_pfmg_preconditioner).
std::unique_ptr<AmgPreconditioner> make_pfmg_preconditioner(const GridLayout& layout);

}  // namespace tetfsi::detail
