#pragma once
/// @file petsc_solver.hpp
/// Internal: the PETSc-backed `amg` (hypre BoomerAMG), `amg_gamg` (PETSc GAMG), `mumps` and
/// `superlu_dist` (direct factorisations) solvers.
/// Keeps PETSc out of every header; only `core/petsc_solver.cpp` includes PETSc.
///
/// PETSc is initialised on the first call of `make_petsc_solver` (which also initialises MPI
/// if nobody did), with PETSc's signal handler off and no `.petscrc` read, and finalised at
/// exit. Tuning can be overridden at run time through `PETSC_OPTIONS` with the prefixes
/// `tetfsi_amg_`, `tetfsi_gamg_`, (GAMG, `symmetric = false`) `tetfsi_gamg_nonsym_` and
/// `tetfsi_mumps_`, `tetfsi_superlu_dist_`, e.g.
/// `PETSC_OPTIONS="-tetfsi_amg_pc_hypre_boomeramg_strong_threshold 0.6"`.
#include <memory>
#include <string>

#include "core/linear_solver.hpp"

namespace tetfsi::detail {

/// Initialise PETSc (and MPI) now if nobody did: "" on success, else why it failed.
std::string start_petsc();

/// @param kind SolverKind::Amg, AmgGamg, Mumps or SuperluDist.
/// @throws SolverError if PETSc cannot be initialised.
std::unique_ptr<LinearSolver> make_petsc_solver(SolverKind kind, const SolverOptions& opts);

/// BoomerAMG as a preconditioner (see tetfsi::make_amg_preconditioner).
std::unique_ptr<AmgPreconditioner> make_petsc_preconditioner();

}  // namespace tetfsi::detail
