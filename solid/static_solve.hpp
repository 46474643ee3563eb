#pragma once
/// @file static_solve.hpp
/// Static equilibrium K(d) = f_e by Newton's method with a backtracking line search on the
/// total potential Π(d) = W(X + d) − f_eᵀ d; used for the CSM benchmarks.
#include "core/equilibrium.hpp"
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

/// Static equilibrium by the iterations of [BatheSonnad80, Eqs. (8)–(13)] with the inertia
/// left out (as the seed says they apply): g(d) = f_e − K(d) on the free DOFs, coefficient
/// matrix K'(d) (Newton: at every iterate; modified Newton and BFGS: the tangent
/// matrix at the start of each load step, or the first one's with opt.keep_matrix), line
/// search and RTOL/ETOL as in `opt`; f_e applied in `load_steps` equal increments (an
/// incremental static analysis). Starts from the current displacement, sets the result
/// (velocity zero) if every increment converged.
/// @return the report (iterations etc. summed over increments; the first failure's message);
///   the body is unchanged if an increment did not converge.
EquilibriumReport solve_static_iterated(SolidBody& body, const VecX& f_e,
                                        const EquilibriumOptions& opt, int load_steps = 1);

}  // namespace tetfsi::solid
