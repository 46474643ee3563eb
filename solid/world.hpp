#pragma once
/// @file world.hpp
/// The solid-only step driver: bodies, gravity and obstacles advanced together with the
/// linearised trapezoidal rule; kinematic bodies (SolidBody::kinematic) follow their
/// prescribed motion instead. (The coupled driver in coupling/ replaces it once the fluid
/// exists; it keeps the same per-body systems.)
#include <optional>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/equilibrium.hpp"
#include "core/linear_solver.hpp"
#include "core/timer.hpp"
#include "solid/contact.hpp"
#include "solid/integrator.hpp"
#include "solid/nonlinear_trapezoid.hpp"
#include "solid/obstacles.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

struct SolidStepReport {
  bool converged = true;  ///< every body's linear solve converged
  int iterations = 0;     ///< linear-solver iterations summed over bodies
  double residual = 0.0;  ///< worst relative residual over bodies
  Index contacts = 0;     ///< nodes in contact with obstacles after the step
  /// Nonlinear integrators: the most iterations any body took ([BatheSonnad80], Table I's
  /// count) and the residual evaluations summed over bodies.
  int equilibrium_iterations = 0;
  int equilibrium_evaluations = 0;
  /// Contact between bodies (SolidWorld::contact enabled): the step's set and figures.
  std::optional<ContactReport> body_contact;
};

class SolidWorld {
 public:
  std::vector<SolidBody> bodies;
  std::vector<Obstacle> obstacles;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);  ///< m/s²
  SolverKind linear_solver = SolverKind::Cholmod;
  SolverOptions solver_options;
  Trapezoid trapezoid = Trapezoid::Paper;  ///< linearized integrator: see integrator.hpp
  /// `Linearized`: [Chentanez06, Eqs. (4)–(5)], one linear solve per step. The others iterate
  /// the nonlinear trapezoidal rule to equilibrium (nonlinear_trapezoid.hpp) with
  /// `equilibrium`'s tolerances (its `method` is taken from the integrator).
  Integrator integrator = Integrator::Linearized;
  EquilibriumOptions equilibrium;
  /// Contact between bodies and self-contact (contact.hpp); with it, the deformable bodies are
  /// solved together in one system (linearised integrator only).
  ContactParams contact;
  /// Simulated time (s): advanced by h at the end of every successful `step`. Kinematic
  /// bodies are evaluated at it (set_kinematic_states).
  double time = 0.0;

  /// Advance every body by h. A deformable body: assemble [Chentanez06, Eq. (4)], solve,
  /// apply Eq. (5) (or, with a nonlinear integrator, iterate [BatheSonnad80, Eq. (6)] to
  /// equilibrium), resolve collisions. A kinematic body: d and u set exactly from its motion
  /// at time + h (timed as "update"; no solve, no collisions, nothing in the report). Then
  /// time += h. Phases "assemble", "solve", "update" are timed into `times`.
  /// @throws InputError naming a kinematic body that has fixed DOFs or applied loads;
  ///   SolverError if a solve fails, an iteration does not converge or the state becomes
  ///   non-finite, naming the body (bodies not yet advanced stay at tⁿ).
  SolidStepReport step(double h, PhaseTimes& times);

  /// Set every kinematic body's d and u from its motion at `time` (e.g. after building the
  /// world, so that the initial state is on the path). Deformable bodies are left alone.
  void set_kinematic_states();

  double kinetic_energy() const;
  double elastic_energy() const;

  /// The state the next step reads, as records under `prefix` (core/checkpoint.hpp): time,
  /// every body's d and u (kinematic bodies too: they are set from their motion anyway), and
  /// the nonlinear integrators' histories. Loads, obstacles and materials come from the scene.
  void save_state(CheckpointWriter& w, const std::string& prefix) const;
  /// Restore save_state's records into a world built from the same scene.
  /// @throws CheckpointError naming the record if the bodies differ (count, names, nodes).
  void load_state(const CheckpointReader& r, const std::string& prefix);

 private:
  /// The linearised step of every body together with the contacts between them.
  SolidStepReport step_together(double h, PhaseTimes& times);
  /// A x = b by linear_solver (CHOLMOD falling back to UMFPACK), into `report`.
  void solve_linear(const SparseMatrix& A, const VecX& b, VecX& x, const std::string& what,
                    SolidStepReport& report);
  bool m_warned_fallback = false;             ///< the CHOLMOD → UMFPACK fallback was logged once
  std::vector<EquilibriumHistory> m_history;  ///< per body, nonlinear integrators
};

}  // namespace tetfsi::solid
