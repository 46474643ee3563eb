#include "coupling/simulation.hpp"

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::coupling {

FsiSimulation::FsiSimulation(solid::SolidWorld world, std::optional<FluidSetup> fluid,
                             std::optional<CouplingParams> coupling)
    : m_world(std::move(world)) {
  TETFSI_REQUIRE(InputError, fluid || !coupling, "a two-way coupling ({}) needs a fluid",
                 coupling ? to_string(coupling->scheme) : "");
  if (!fluid) return;
  m_policy = std::make_unique<const RemeshPolicy>(fluid->domain, fluid->sizing, m_world);
  m_fluid = make_sim_fluid(*fluid, *m_policy);
  if (coupling) m_stepper.emplace(std::move(*coupling), m_world);
}

void FsiSimulation::set_mesh_observer(MeshObserver observer) {
  if (m_fluid) m_fluid->set_mesh_observer(std::move(observer));
}

double FsiSimulation::fluid_time() const {
  return m_fluid ? m_fluid->time() : 0.0;
}

fluid::FluidFrame FsiSimulation::fluid_frame() const {
  return m_fluid ? m_fluid->frame(m_world) : fluid::FluidFrame{};
}

std::vector<VecX> FsiSimulation::fluid_forces() const {
  TETFSI_CHECK(fluid_started(), "FsiSimulation::fluid_forces: no started fluid");
  return m_fluid->body_forces(m_world);
}

void FsiSimulation::start(PhaseTimes& phases) {
  if (m_fluid) m_fluid->start(m_world, phases);
}

void FsiSimulation::rebuild_at_rest(PhaseTimes& phases) {
  if (m_fluid) m_fluid->rebuild_at_rest(m_world, phases);
}

FsiStepReport FsiSimulation::step(double h, PhaseTimes& phases) {
  TETFSI_CHECK(!has_fluid() || fluid_started(), "FsiSimulation::step before start");
  if (m_stepper) return step_two_way(h, phases);
  return step_one_way(h, phases);
}

FsiStepReport FsiSimulation::step_one_way(double h, PhaseTimes& phases) {
  FsiStepReport r;
  const double ts = now_seconds();
  r.solid = m_world.step(h, phases);
  r.solid_s = now_seconds() - ts;
  if (!has_fluid()) return r;
  PhaseTimes fp;
  FluidStepAlone f = m_fluid->step_alone(m_world, h, phases, fp);
  r.fluid = std::move(f.report);
  r.fluid_s = f.seconds;
  phases.add("transfer", fp.get("transfer"));
  phases.add("forces", fp.get("forces"));
  phases.add("pressure_assembly", fp.get("assembly"));
  phases.add("pressure_solve", fp.get("solve"));
  return r;
}

FsiStepReport FsiSimulation::step_two_way(double h, PhaseTimes& phases) {
  // The fluid times the remesh (and the observer's work) into `phases` itself; the
  // stepper's own phases are collected apart to tell the fluid's share.
  PhaseTimes sp;
  FsiStepReport r;
  const std::unique_ptr<CoupledFluid> fluid =
      m_fluid->coupled(body_interfaces(m_world, m_policy->surfaces()), phases);
  r.coupled = m_stepper->step(m_world, *fluid, h, sp);
  for (const auto& [name, seconds] : sp.entries()) phases.add(name, seconds);
  r.fluid_s =
      sp.get("transfer") + sp.get("forces") + sp.get("coupled_assembly") + sp.get("coupled_solve");
  return r;
}

void FsiSimulation::save_state(CheckpointWriter& w) const {
  w.put("sim/kind", std::string(m_fluid ? m_fluid->kind() : "solid"));
  w.put("sim/two_way", two_way());
  if (two_way()) w.put("sim/scheme", std::string(to_string(m_stepper->params().scheme)));
  m_world.save_state(w, "sim/solid/");
  w.put("sim/fluid_started", fluid_started());
  if (fluid_started()) m_fluid->save_state(w, "sim/");
  if (m_stepper) m_stepper->save_state(w, "sim/scheme/");
}

void FsiSimulation::load_state(const CheckpointReader& r) {
  const std::string kind = r.get_text("sim/kind");
  const std::string mine = m_fluid ? m_fluid->kind() : "solid";
  if (kind != mine)
    r.fail(fmt::format("it holds a {} simulation, the scene is a {} one: it is from another scene",
                       kind, mine));
  if (r.get_bool("sim/two_way") != two_way())
    r.fail(fmt::format("it is from a {} run, the scene is {}: it is from another scene",
                       two_way() ? "one-way" : "two-way", two_way() ? "two-way" : "one-way"));
  if (two_way() && r.get_text("sim/scheme") != to_string(m_stepper->params().scheme))
    r.fail(fmt::format("it is from the '{}' coupling scheme, the scene's is '{}'",
                       r.get_text("sim/scheme"), to_string(m_stepper->params().scheme)));
  m_world.load_state(r, "sim/solid/");
  if (r.get_bool("sim/fluid_started") && m_fluid) m_fluid->load_state(r, "sim/");
  if (m_stepper) m_stepper->load_state(r, "sim/scheme/");
}

}  // namespace tetfsi::coupling
