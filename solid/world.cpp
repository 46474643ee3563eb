#include "solid/world.hpp"

#include <algorithm>
#include <memory>
#include <optional>

#include "core/error.hpp"
#include "core/log.hpp"
#include "solid/floor_contact.hpp"

namespace tetfsi::solid {

namespace {

/// A kinematic body's motion is prescribed: pins or loads on it would be silently ignored.
void check_kinematic(const SolidBody& body) {
  TETFSI_REQUIRE(InputError, body.num_fixed_dofs() == 0,
                 "body '{}' is kinematic: it cannot have pins ({} fixed DOFs); its motion is "
                 "prescribed",
                 body.name(), body.num_fixed_dofs());
  TETFSI_REQUIRE(InputError, body.applied_force.isZero(0.0),
                 "body '{}' is kinematic: it cannot have loads (applied_force is not zero); its "
                 "motion is prescribed",
                 body.name());
}

}  // namespace

void SolidWorld::set_kinematic_states() {
  for (SolidBody& body : bodies) {
    if (body.is_kinematic()) body.set_kinematic_state(time);
  }
}

void SolidWorld::solve_linear(const SparseMatrix& A, const VecX& b, VecX& x,
                              const std::string& what, SolidStepReport& report) {
  auto solver = make_linear_solver(linear_solver, solver_options);
  try {
    solver->setup(A);
  } catch (const SolverError& e) {
    // A = M/h + C + (h/2)K' is SPD unless K' is strongly indefinite (large compression);
    // LU still solves it.
    if (linear_solver != SolverKind::Cholmod) throw;
    if (!m_warned_fallback) {
      logger().warn(
          "{}: cholmod failed ({}): A is not positive definite; falling back to umfpack "
          "(warned once)",
          what, e.what());
      m_warned_fallback = true;
    }
    solver = make_linear_solver(SolverKind::Umfpack, solver_options);
    solver->setup(A);
  }
  const SolveReport rep = solver->solve(b, x);
  report.converged = report.converged && rep.converged;
  report.iterations += rep.iterations;
  report.residual = std::max(report.residual, rep.residual);
  if (!rep.converged)
    logger().warn("{}: linear solve ({}) did not converge: relative residual {:.3g}", what,
                  rep.backend, rep.residual);
}

SolidStepReport SolidWorld::step(double h, PhaseTimes& times) {
  for (const SolidBody& body : bodies) {
    if (body.is_kinematic()) check_kinematic(body);
  }
  if (contact.enabled) {
    TETFSI_REQUIRE(InputError, integrator == Integrator::Linearized,
                   "contact between bodies needs solid.integrator \"linearized\" (got \"{}\"): "
                   "remove the contact section or change the integrator",
                   to_string(integrator));
    return step_together(h, times);
  }
  SolidStepReport report;
  const double t_new = time + h;
  if (m_history.size() != bodies.size()) m_history.resize(bodies.size());
  for (size_t bi = 0; bi < bodies.size(); ++bi) {
    SolidBody& body = bodies[bi];
    if (body.is_kinematic()) {
      ScopedTimer timer(times, "update");
      body.set_kinematic_state(t_new);  // exact: evaluated at t, not integrated
      continue;
    }
    if (integrator != Integrator::Linearized) {
      // iterated to equilibrium, the body advanced: see [BatheSonnad80, Eqs. (1)–(13)]
      EquilibriumOptions opt = equilibrium;
      opt.method = iteration_method(integrator);
      EquilibriumReport er;
      {
        ScopedTimer timer(times, "solve");
        er = step_nonlinear(body, h, body.external_forces(gravity), opt, m_history[bi]);
      }
      TETFSI_REQUIRE(SolverError, er.converged,
                     "body '{}': the {} iteration {} at t = {:.6g} s (h = {:.3g} s); raise "
                     "solid.max_iterations, reduce time.dt, or use solid.integrator bfgs or newton",
                     body.name(), to_string(integrator), er.failure, time, h);
      report.equilibrium_iterations = std::max(report.equilibrium_iterations, er.iterations);
      report.equilibrium_evaluations += er.evaluations;
    } else {
      TrapezoidalSystem sys;
      {
        ScopedTimer timer(times, "assemble");
        // A u = b, see [Chentanez06, Eq. (4)], with f_p = 0 (no fluid here).
        sys = assemble_trapezoidal(body, h, body.external_forces(gravity), trapezoid);
      }
      VecX u = flat(body.velocity);  // initial guess for iterative backends
      // one solve per round of the floor contacts' active set (floor_contact.hpp)
      const BodySolve solve = [&](const SparseMatrix& A, const VecX& b, VecX& x) {
        ScopedTimer timer(times, "solve");
        solve_linear(A, b, x, fmt::format("body '{}'", body.name()), report);
      };
      // Eq. (5) [Chentanez06] and the obstacles
      report.contacts +=
          step_with_floor_contacts(body, sys, obstacles, gravity, h, solve, u, times);
    }
    if (integrator != Integrator::Linearized) {
      ScopedTimer timer(times, "update");
      report.contacts += resolve_collisions(body, obstacles);
    }
    TETFSI_REQUIRE(SolverError, body.displacement.allFinite() && body.velocity.allFinite(),
                   "body '{}': state became non-finite at step with h = {}; reduce time.dt or "
                   "raise rayleigh damping",
                   body.name(), h);
  }
  time = t_new;
  return report;
}

SolidStepReport SolidWorld::step_together(double h, PhaseTimes& times) {
  SolidStepReport report;
  const Index nb = static_cast<Index>(bodies.size());
  std::vector<TrapezoidalSystem> sys(nb);
  std::vector<std::unique_ptr<FloorContacts>> floors(nb);
  std::vector<Index> dof0(nb + 1, 0);
  for (Index b = 0; b < nb; ++b) {
    SolidBody& body = bodies[b];
    dof0[b + 1] = dof0[b];
    if (body.is_kinematic()) continue;
    ScopedTimer timer(times, "assemble");
    // A u = b, see [Chentanez06, Eq. (4)], with f_p = 0 (no fluid here).
    sys[b] = assemble_trapezoidal(body, h, body.external_forces(gravity), trapezoid);
    floors[b] = std::make_unique<FloorContacts>(body, obstacles, gravity, h);
    dof0[b + 1] += body.num_dofs();
  }
  std::optional<BodyContacts> contacts;
  {
    ScopedTimer timer(times, "contact");  // before kinematic bodies move: xⁿ, uⁿ
    contacts.emplace(bodies, contact, gravity, h);
  }
  for (SolidBody& body : bodies)
    if (body.is_kinematic()) {
      ScopedTimer timer(times, "update");
      body.set_kinematic_state(time + h);
    }
  const Index ns = dof0[nb];
  std::vector<SparseMatrix> A(nb);
  std::vector<VecX> rhs(nb), prescribed(nb), u(nb);
  std::vector<std::vector<std::uint8_t>> fixed(nb);
  std::vector<BodyDofs> dofs(nb);
  VecX x(ns);
  for (Index b = 0; b < nb; ++b) {
    u[b] = flat(bodies[b].velocity);  // kinematic: uⁿ⁺¹; the others: the guess
    if (floors[b]) x.segment(dof0[b], u[b].size()) = u[b];
  }
  for (bool again = true; again;) {
    for (Index b = 0; b < nb; ++b)
      if (floors[b]) {
        floors[b]->constrain(sys[b], A[b], rhs[b], fixed[b], prescribed[b]);
        dofs[b] = {dof0[b], &fixed[b], &prescribed[b]};
      } else {
        dofs[b] = {-1, nullptr, &u[b]};
      }
    ContactSystem cs;
    {
      ScopedTimer timer(times, "contact");
      cs = contacts->system(dofs, ns);
    }
    {
      ScopedTimer timer(times, "solve");
      SparseMatrix K = stack_blocks(A, dof0) + cs.A;
      VecX r = cs.b;
      for (Index b = 0; b < nb; ++b)
        if (floors[b]) r.segment(dof0[b], rhs[b].size()) += rhs[b];
      solve_linear(K, r, x, "the bodies in contact", report);
    }
    if (logger().should_log(spdlog::level::debug)) {
      double ke = 0.0;
      for (Index b = 0; b < nb; ++b)
        if (floors[b])
          for (Index i = 0; i < bodies[b].num_nodes(); ++i)
            ke += 0.5 * bodies[b].lumped_mass()[i] * x.segment<3>(dof0[b] + 3 * i).squaredNorm();
      logger().debug("contact solve: t = {:.4g}, {} pairs, |x| max {:.3g}, kinetic {:.4g} J", time,
                     contacts->report().active, x.cwiseAbs().maxCoeff(), ke);
    }
    again = false;
    for (Index b = 0; b < nb; ++b)
      if (floors[b]) {
        u[b] = x.segment(dof0[b], bodies[b].num_dofs());
        if (floors[b]->update(u[b], nullptr)) again = true;
      }
    ScopedTimer timer(times, "contact");
    if (contacts->update(u)) again = true;
  }
  {
    ScopedTimer timer(times, "update");
    for (Index b = 0; b < nb; ++b) {
      if (!floors[b]) continue;
      advance_trapezoidal(bodies[b], u[b], h);  // see [Chentanez06, Eq. (5)]
      report.contacts += floors[b]->land(bodies[b]);
    }
    contacts->land(bodies);
  }
  {
    ScopedTimer timer(times, "contact");
    contacts->measure(bodies);
  }
  for (const SolidBody& body : bodies)
    TETFSI_REQUIRE(SolverError, body.displacement.allFinite() && body.velocity.allFinite(),
                   "body '{}': state became non-finite at step with h = {}; reduce time.dt or "
                   "raise rayleigh damping",
                   body.name(), h);
  report.body_contact = contacts->report();  // (optional)
  time += h;
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

void SolidWorld::save_state(CheckpointWriter& w, const std::string& prefix) const {
  w.put(prefix + "time", time);
  w.put(prefix + "bodies", static_cast<std::int64_t>(bodies.size()));
  for (size_t b = 0; b < bodies.size(); ++b) {
    const std::string p = fmt::format("{}body/{}/", prefix, b);
    w.put(p + "name", bodies[b].name());
    w.put(p + "displacement", bodies[b].displacement);
    w.put(p + "velocity", bodies[b].velocity);
  }
  w.put(prefix + "histories", static_cast<std::int64_t>(m_history.size()));
  for (size_t b = 0; b < m_history.size(); ++b)
    save_history(m_history[b], w, fmt::format("{}history/{}/", prefix, b));
}

void SolidWorld::load_state(const CheckpointReader& r, const std::string& prefix) {
  const std::int64_t nb = r.get_int(prefix + "bodies");
  if (nb != static_cast<std::int64_t>(bodies.size()))
    r.fail(fmt::format("it holds {} bodies, the scene has {}: it is from another scene", nb,
                       bodies.size()));
  std::vector<std::pair<MatX3, MatX3>> state;
  for (size_t b = 0; b < bodies.size(); ++b) {
    const std::string p = fmt::format("{}body/{}/", prefix, b);
    const std::string name = r.get_text(p + "name");
    if (name != bodies[b].name())
      r.fail(fmt::format("its body {} is '{}', the scene's is '{}': it is from another scene", b,
                         name, bodies[b].name()));
    MatX3 d = r.get<MatX3>(p + "displacement"), u = r.get<MatX3>(p + "velocity");
    if (d.rows() != bodies[b].num_nodes() || u.rows() != bodies[b].num_nodes())
      r.fail(
          fmt::format("body '{}' has {} nodes there and {} in the scene: it is from another "
                      "scene (or mesh)",
                      name, d.rows(), bodies[b].num_nodes()));
    state.emplace_back(std::move(d), std::move(u));
  }
  const std::int64_t nh = r.get_int(prefix + "histories");
  if (nh != 0 && nh != nb) r.fail(fmt::format("it holds {} histories for {} bodies", nh, nb));
  std::vector<EquilibriumHistory> history;
  for (std::int64_t b = 0; b < nh; ++b)
    history.push_back(load_history(r, fmt::format("{}history/{}/", prefix, b)));
  // Everything read: only now change the world.
  time = r.get_double(prefix + "time");
  for (size_t b = 0; b < bodies.size(); ++b) {
    bodies[b].displacement = std::move(state[b].first);
    bodies[b].velocity = std::move(state[b].second);
  }
  m_history = std::move(history);
}

}  // namespace tetfsi::solid
