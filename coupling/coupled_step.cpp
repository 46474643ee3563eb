#include "coupling/coupled_step.hpp"

#include <cmath>

#include "core/error.hpp"

namespace tetfsi::coupling {

namespace {

/// d, u and time of the world, to leave it at tⁿ when a step fails.
struct Snapshot {
  double time = 0.0;
  std::vector<std::pair<MatX3, MatX3>> state;
  explicit Snapshot(const solid::SolidWorld& w) : time(w.time) {
    for (const auto& b : w.bodies) state.emplace_back(b.displacement, b.velocity);
  }
  /// Σ f_b · (d_b − d_bⁿ) over the free bodies: the work of the forces f (J).
  double work(const solid::SolidWorld& w, const std::vector<VecX>& f) const {
    double sum = 0.0;
    for (size_t i = 0; i < state.size() && i < f.size(); ++i) {
      const solid::SolidBody& b = w.bodies[i];
      if (b.is_kinematic() || f[i].size() != 3 * b.num_nodes()) continue;
      sum += f[i].dot(flat(b.displacement) - flat(state[i].first));
    }
    return sum;
  }
  void restore(solid::SolidWorld& w) const {
    w.time = time;
    for (size_t i = 0; i < state.size(); ++i) {
      w.bodies[i].displacement = state[i].first;
      w.bodies[i].velocity = state[i].second;
    }
  }
};

}  // namespace

CoupledStepper::CoupledStepper(CouplingParams params, const solid::SolidWorld& world)
    : m_params(std::move(params)), m_scheme(make_scheme(m_params)) {
  for (const solid::SolidBody& b : world.bodies) m_surfaces.push_back(body_surface(b));
}

CoupledStepReport CoupledStepper::step(solid::SolidWorld& world, CoupledFluid& fluid, double h,
                                       PhaseTimes& phases) {
  TETFSI_REQUIRE(InputError, std::isfinite(h) && h > 0, "coupled step: dt must be > 0, got {}", h);
  TETFSI_CHECK(m_surfaces.size() == world.bodies.size(),
               "coupled step: the world has {} bodies, the stepper was made for {}",
               world.bodies.size(), m_surfaces.size());
  const Snapshot snap(world);
  const double t1 = world.time + h;
  CoupledStepReport rep;
  rep.scheme = m_params.scheme;
  StepContext ctx{world, fluid, m_surfaces, h, phases};
  try {
    std::unique_ptr<PredictedFluid> pred;
    CoupledSolution sol = m_scheme->advance(ctx, pred, rep);
    rep.solve = sol.report;
    rep.fluid_work = snap.work(world, sol.fluid_force);
    rep.fluid = fluid.commit(std::move(pred), sol);
  } catch (...) {
    snap.restore(world);
    throw;
  }
  rep.fluid.converged = rep.solve.converged;
  rep.fluid.iterations = rep.solve.iterations;
  rep.fluid.residual = rep.solve.residual;
  rep.fluid.divergence_before = rep.solve.divergence_before;
  rep.fluid.divergence_after = rep.solve.divergence_after;
  world.time = t1;
  rep.solid_kinetic_energy = world.kinetic_energy();
  rep.elastic_energy = world.elastic_energy();
  return rep;
}

}  // namespace tetfsi::coupling
