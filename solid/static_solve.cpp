#include "solid/static_solve.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/dof_elimination.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "solid/nonlinear_trapezoid.hpp"

namespace tetfsi::solid {

namespace {

/// Norm of v restricted to free DOFs.
double free_norm(const VecX& v, const std::vector<std::uint8_t>& fixed) {
  double s = 0.0;
  for (Index i = 0; i < v.size(); ++i)
    if (!fixed[i]) s += v[i] * v[i];
  return std::sqrt(s);
}

/// Eliminate the fixed DOFs of K' symmetrically: their rows and columns zero but a diagonal
/// of the free DOFs' mean |K'_ii| (so the matrix keeps its scale). Δ = 0 there when r = 0.
void eliminate_fixed(SparseMatrix& Kp, const std::vector<std::uint8_t>& fixed) {
  const Index n = Kp.cols();
  double diag_scale = 0.0;
  Index nfree = 0;
  for (Index c = 0; c < n; ++c)
    if (!fixed[c]) {
      diag_scale += std::abs(Kp.coeff(c, c));
      ++nfree;
    }
  diag_scale = nfree > 0 && diag_scale > 0.0 ? diag_scale / nfree : 1.0;
  eliminate_dofs(Kp, fixed, [&](Index) { return diag_scale; });
}

/// Solve K' Δ = r on the free DOFs (fixed rows/cols eliminated symmetrically, Δ = 0 there):
/// CHOLMOD first (or the requested backend), UMFPACK if the factorization fails because K'
/// is not positive definite (compressed, buckling states).
VecX solve_newton_system(SparseMatrix& Kp, const VecX& r, const std::vector<std::uint8_t>& fixed,
                         SolverKind kind, const std::string& body) {
  const Index n = static_cast<Index>(r.size());
  eliminate_fixed(Kp, fixed);
  VecX rhs = r;
  for (Index i = 0; i < n; ++i)
    if (fixed[i]) rhs[i] = 0.0;

  VecX delta = VecX::Zero(n);
  auto solver = make_linear_solver(kind);
  try {
    solver->setup(Kp);
  } catch (const SolverError& e) {
    if (kind == SolverKind::Umfpack) throw;
    logger().debug("body '{}': static solve: {} failed ({}); using umfpack", body, to_string(kind),
                   e.what());
    solver = make_linear_solver(SolverKind::Umfpack);
    solver->setup(Kp);
  }
  const SolveReport rep = solver->solve(rhs, delta);
  TETFSI_REQUIRE(SolverError, rep.converged && delta.allFinite(),
                 "body '{}': static solve: linear solve with {} failed (relative residual {:.3g})",
                 body, rep.backend, rep.residual);
  return delta;
}

/// ||A||_∞ = max over rows of Σ_j |a_ij| (A symmetric: computed over columns).
double max_row_abs_sum(const SparseMatrix& A) {
  double m = 0.0;
  for (Index c = 0; c < A.outerSize(); ++c) {
    double s = 0.0;
    for (SparseMatrix::InnerIterator it(A, c); it; ++it) s += std::abs(it.value());
    m = std::max(m, s);
  }
  return m;
}

}  // namespace

StaticSolveReport solve_static(SolidBody& body, const VecX& f_e, const StaticSolveOptions& opts) {
  TETFSI_REQUIRE(InputError, opts.load_steps >= 1 && opts.max_iterations >= 1 && opts.rel_tol > 0.0,
                 "body '{}': static solve needs load_steps >= 1, max_iterations >= 1, rel_tol > 0",
                 body.name());
  const Index ndof = body.num_dofs();
  TETFSI_CHECK(f_e.size() == ndof, "f_e has size {}, expected {}", f_e.size(), ndof);
  const auto& fixed = body.fixed_dofs();
  const StvkElasticity& elastic = body.elasticity();
  const MatX3& X = body.rest_positions();
  body.velocity.setZero();
  const double nfree = static_cast<double>(ndof - body.num_fixed_dofs());

  StaticSolveReport report;
  VecX K;
  SparseMatrix Kp;
  // Reference for the relative residual: the load, or (for pure prescribed-displacement
  // problems, f_e = 0) the initial out-of-balance force.
  const double ref =
      std::max(free_norm(f_e, fixed), free_norm(elastic.forces(body.positions()), fixed));
  if (ref == 0.0) {
    report.converged = true;
    return report;
  }

  for (int step = 1; step <= opts.load_steps; ++step) {
    const VecX f = f_e * (static_cast<double>(step) / opts.load_steps);
    bool step_converged = false;
    for (int it = 0; it <= opts.max_iterations; ++it) {
      const MatX3 x = X + body.displacement;
      elastic.forces_and_jacobian(x, K, Kp);
      VecX r = f - K;  // out-of-balance force = −∇Π
      for (Index i = 0; i < ndof; ++i)
        if (fixed[i]) r[i] = 0.0;
      const double r_norm = r.norm();
      report.residual = r_norm / ref;
      // Round-off floor: x carries an absolute error ε max|x|, which K' turns into a force
      // error of about ε max|x| ||K'||_∞ per DOF. Slender or stiff bodies under small loads
      // cannot get below it, whatever rel_tol says.
      const double floor = std::numeric_limits<double>::epsilon() * x.cwiseAbs().maxCoeff() *
                           max_row_abs_sum(Kp) * std::sqrt(nfree);
      if (report.residual <= opts.rel_tol || r_norm <= floor) {
        if (report.residual > opts.rel_tol)
          logger().debug(
              "body '{}': static solve stopped at the round-off floor (relative "
              "residual {:.3g}, floor {:.3g})",
              body.name(), report.residual, floor / ref);
        step_converged = true;
        break;
      }
      if (it == opts.max_iterations) break;
      ++report.iterations;
      const VecX delta = solve_newton_system(Kp, r, fixed, opts.linear_solver, body.name());

      // Backtracking (Armijo) line search on Π(d) = W(X + d) − fᵀd.
      const VecX d0 = flat(body.displacement);
      const double pi0 = elastic.energy(x) - f.dot(d0);
      const double slope = -r.dot(delta);  // ∇Π · Δ
      double alpha = 1.0;
      if (slope < 0.0) {
        const double slack = 1e-13 * (std::abs(pi0) + std::abs(f.dot(d0)) + elastic.energy(x));
        for (int ls = 0; ls < 30; ++ls) {
          const VecX d = d0 + alpha * delta;
          const double pi = elastic.energy(X + as_nodes(d)) - f.dot(d);
          if (pi <= pi0 + 1e-4 * alpha * slope + slack) break;
          alpha *= 0.5;
        }
      }  // else: not a descent direction (indefinite K'), take the plain Newton step
      flat(body.displacement) = d0 + alpha * delta;
      TETFSI_REQUIRE(SolverError, body.displacement.allFinite(),
                     "body '{}': static solve produced a non-finite displacement", body.name());
    }
    if (!step_converged) {
      throw SolverError(fmt::format(
          "body '{}': static Newton solve did not converge in {} iterations at load step {}/{} "
          "(relative residual {:.3g} > {:.3g}); raise load_steps or max_iterations",
          body.name(), opts.max_iterations, step, opts.load_steps, report.residual, opts.rel_tol));
    }
  }
  report.converged = true;
  logger().debug("body '{}': static solve converged in {} Newton iterations (residual {:.3g})",
                 body.name(), report.iterations, report.residual);
  return report;
}

EquilibriumReport solve_static_iterated(SolidBody& body, const VecX& f_e,
                                        const EquilibriumOptions& opt, int load_steps) {
  TETFSI_REQUIRE(InputError, load_steps >= 1, "body '{}': load_steps must be >= 1, got {}",
                 body.name(), load_steps);
  const Index ndof = body.num_dofs();
  TETFSI_CHECK(f_e.size() == ndof, "f_e has size {}, expected {}", f_e.size(), ndof);
  const auto& fixed = body.fixed_dofs();
  const MatX3& X = body.rest_positions();
  const VecX d_fixed = flat(body.displacement);
  auto positions = [&](const VecX& d) {
    MatX3 x = X;
    flat(x) += d;
    return x;
  };
  double load = 0.0;  // the fraction of f_e applied
  EquilibriumProblem problem;
  problem.residual = [&](const VecX& d) {
    VecX r = load * f_e - body.elasticity().forces(positions(d));
    for (Index i = 0; i < ndof; ++i)
      if (fixed[i]) r[i] = 0.0;
    return r;
  };
  problem.factor = [&](const VecX& d) {
    SparseMatrix Kp = body.elasticity().jacobian(positions(d));
    eliminate_fixed(Kp, fixed);
    return factor_inverse(Kp);
  };
  EquilibriumHistory history;
  VecX d = d_fixed;
  EquilibriumReport rep;
  rep.converged = true;
  for (int step = 1; step <= load_steps && rep.converged; ++step) {
    load = static_cast<double>(step) / load_steps;
    const EquilibriumReport r = solve_equilibrium(problem, d, opt, history);
    rep.converged = r.converged;
    rep.iterations += r.iterations;
    rep.evaluations += r.evaluations;
    rep.factorizations += r.factorizations;
    rep.updates += r.updates;
    rep.skipped_updates += r.skipped_updates;
    rep.line_searches += r.line_searches;
    rep.force_ratio = r.force_ratio;
    rep.energy_ratio = r.energy_ratio;
    if (!r.converged) rep.failure = fmt::format("load step {}/{}: {}", step, load_steps, r.failure);
  }
  if (rep.converged) {
    flat(body.displacement) = d;
    body.velocity.setZero();
  }
  return rep;
}

}  // namespace tetfsi::solid
