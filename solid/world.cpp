#include "solid/world.hpp"

#include <algorithm>

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::solid {

SolidStepReport SolidWorld::step(double h, PhaseTimes& times) {
  SolidStepReport report;
  for (SolidBody& body : bodies) {
    TrapezoidalSystem sys;
    {
      ScopedTimer timer(times, "assemble");
      // A u = b  [Chentanez06, Eq. (4)] with f_p = 0 (no fluid here).
      sys = assemble_trapezoidal(body, h, body.external_forces(gravity), trapezoid);
    }
    VecX u = flat(body.velocity);  // initial guess for iterative backends
    SolveReport rep;
    {
      ScopedTimer timer(times, "solve");
      auto solver = make_linear_solver(linear_solver, solver_options);
      try {
        solver->setup(sys.A);
      } catch (const SolverError& e) {
        // A = M/h + C + (h/2)K' is SPD unless K' is strongly indefinite (large compression);
        // LU still solves it.
        if (linear_solver != SolverKind::Cholmod) throw;
        if (!m_warned_fallback) {
          logger().warn(
              "body '{}': cholmod failed ({}): A is not positive definite; falling "
              "back to umfpack (warned once)",
              body.name(), e.what());
          m_warned_fallback = true;
        }
        solver = make_linear_solver(SolverKind::Umfpack, solver_options);
        solver->setup(sys.A);
      }
      rep = solver->solve(sys.b, u);
    }
    report.converged = report.converged && rep.converged;
    report.iterations += rep.iterations;
    report.residual = std::max(report.residual, rep.residual);
    {
      ScopedTimer timer(times, "update");
      advance_trapezoidal(body, u, h);  // [Chentanez06, Eq. (5)]
      report.contacts += resolve_collisions(body, obstacles);
    }
    TETFSI_REQUIRE(SolverError, body.displacement.allFinite() && body.velocity.allFinite(),
                   "body '{}': state became non-finite at step with h = {}; reduce time.dt or "
                   "raise rayleigh damping",
                   body.name(), h);
    if (!rep.converged)
      logger().warn("body '{}': linear solve ({}) did not converge: relative residual {:.3g}",
                    body.name(), rep.backend, rep.residual);
  }
  return report;
}

double SolidWorld::kinetic_energy() const {
  double e = 0.0;
  for (const SolidBody& b : bodies) e += b.kinetic_energy();
  return e;
}

double SolidWorld::elastic_energy() const {
  double e = 0.0;
  for (const SolidBody& b : bodies) e += b.elastic_energy();
  return e;
}

}  // namespace tetfsi::solid
