#pragma once
/// @file static_solve.hpp
/// Static equilibrium K(d) = f_e by Newton's method with a backtracking line search on the
/// total potential Π(d) = W(X + d) − f_eᵀ d; used for the CSM benchmarks.
#include "core/linear_solver.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

struct StaticSolveOptions {
  /// Stop when ||f_e − K(d)||_free ≤ rel_tol ||f_e||_free, or when the residual reaches the
  /// round-off floor ε max|x| ||K'||_∞ sqrt(#free) (stiff, slender bodies under small loads).
  /// If f_e = 0 on the free DOFs (pure prescribed displacements) the reference is the
  /// initial out-of-balance force instead of ||f_e||.
  double rel_tol = 1e-9;
  int max_iterations = 60;                         ///< Newton iterations per load step
  int load_steps = 1;                              ///< apply f_e in this many equal increments
  SolverKind linear_solver = SolverKind::Cholmod;  ///< falls back to UMFPACK if not SPD
};

struct StaticSolveReport {
  bool converged = false;
  int iterations = 0;     ///< Newton iterations summed over load steps
  double residual = 0.0;  ///< final relative residual
};

/// Solve for the body's displacement in place (fixed DOFs keep their value; velocity is
/// set to zero). Starts from the current displacement.
/// @throws SolverError if Newton does not converge, naming the body and residual.
StaticSolveReport solve_static(SolidBody& body, const VecX& f_e,
                               const StaticSolveOptions& opts = {});

}  // namespace tetfsi::solid
