#include "run/run_stats.hpp"

#include <algorithm>
#include <cmath>

#include "core/log.hpp"
#include "io/state_io.hpp"
#include "io/stats_columns.hpp"
#include "mesh/quality.hpp"

namespace tetfsi::app {

RunRecorder::RunRecorder(const coupling::FsiSimulation& sim) {
  if (!sim.fluid()->builds_meshes()) {  // no mesh: the mesh columns stay empty (nan)
    m_stats.quality = mesh::quality_columns(mesh::QualitySummary{});
    m_summary.min_dihedral_deg = NAN;
  }
  if (const coupling::CouplingParams* p = sim.coupling()) {
    CouplingSummary c;
    c.scheme = coupling::to_string(p->scheme);
    c.solver = coupling::to_string(p->solve.solver);
    m_coupling_summary = c;
  }
}

coupling::MeshObserver RunRecorder::mesh_observer() {
  return [this](const mesh::TetMesh& m, const mesh::RemeshReport& report, double seconds,
                PhaseTimes& phases) { record_mesh(m, report, seconds, phases); };
}

void RunRecorder::record_mesh(const mesh::TetMesh& m, const mesh::RemeshReport& report,
                              double seconds, PhaseTimes& phases) {
  ScopedTimer quality_timer(phases, "output");
  const mesh::QualitySummary q = mesh::summarize_quality(m);
  m_stats.cells = m.num_tets();
  m_stats.vertices = m.num_vertices();
  m_stats.steiner_points = report.steiner_points;
  m_stats.recovery_rounds = report.recovery_rounds;
  m_stats.remesh_incremental = report.incremental ? 1 : 0;
  m_stats.vertices_removed = report.vertices_removed;
  m_stats.vertices_inserted = report.vertices_inserted;
  m_stats.remesh_s = report.seconds_total;
  m_stats.quality = mesh::quality_columns(q);
  FluidSummary& f = m_summary;
  if (std::isfinite(q.min_dihedral_deg))
    f.min_dihedral_deg =
        f.remeshes == 0 ? q.min_dihedral_deg : std::min(f.min_dihedral_deg, q.min_dihedral_deg);
  f.max_slivers = std::max(f.max_slivers, q.slivers);
  f.remeshes += 1;
  f.remesh_s += seconds;
  f.max_remesh_s = std::max(f.max_remesh_s, seconds);
  f.cells = m_stats.cells;
  f.vertices = m_stats.vertices;
}

void RunRecorder::record(const coupling::FsiStepReport& r, const coupling::FsiSimulation& sim) {
  m_stats.cells = sim.fluid()->cells();
  m_summary.cells = m_stats.cells;
  if (r.coupled) {
    record_fluid_step(r.coupled->fluid, r.fluid_s, sim.fluid_time());
    record_coupled_step(*r.coupled, sim.world().time);
  } else if (r.fluid) {
    record_fluid_step(*r.fluid, r.fluid_s, sim.fluid_time());
  }
}

void RunRecorder::record_fluid_step(const fluid::FluidStepReport& r, double seconds, double time) {
  m_summary.fluid_s += seconds;
  FluidStepStats& s = m_stats;
  s.pressure_iterations = r.iterations;
  s.pressure_residual = r.residual;
  s.divergence_before = r.divergence_before;
  s.divergence = r.divergence_after;
  s.fluid_kinetic_energy = r.kinetic_energy;
  s.smoke_mass = r.smoke_mass;
  s.inflow_flux = r.inflow_flux;
  s.outflow_flux = r.outflow_flux;
  s.solid_flux = r.solid_flux;
  s.max_speed = r.max_speed;
  s.cfl = r.cfl;
  s.traces_clamped = r.traces_clamped;
  s.liquid_volume = r.liquid_volume;
  s.liquid_volume_drift = r.liquid_volume_drift;
  s.liquid_shift = r.liquid_shift;
  s.liquid_area = r.liquid_area;
  s.liquid_particles = r.liquid_particles;
  s.liquid_advect_s = r.liquid_advect_s;
  s.liquid_surface_s = r.liquid_surface_s;
  s.liquid_p2g_s = r.liquid_p2g_s;
  FluidSummary& f = m_summary;
  f.fluid_steps += 1;
  f.pressure_iterations += r.iterations;
  if (!r.converged) ++f.unconverged_pressure_solves;
  f.max_divergence = std::max(f.max_divergence, r.divergence_after);
  f.max_cfl = std::max(f.max_cfl, r.cfl);
  f.smoke_mass = r.smoke_mass;
  f.fluid_kinetic_energy = r.kinetic_energy;
  if (r.cfl > 5.0)
    logger().warn(
        "fluid CFL number {:.3g} at t = {:.6g} s: semi-Lagrangian advection stays "
        "stable but smears; reduce time.dt for accuracy",
        r.cfl, time);
}

void RunRecorder::record_coupled_step(const coupling::CoupledStepReport& rep, double time) {
  CoupledStepStats c;
  c.iterations = rep.solve.iterations;
  c.residual = rep.solve.residual;
  c.interface_power = rep.solve.interface_power;
  c.total_energy = rep.total_energy();
  c.contact_rounds = rep.contact_rounds;
  for (const coupling::EnclosedRegion& e : rep.solve.enclosed) {
    c.enclosed_volume += e.after;
    if (e.target > 0)
      c.enclosed_volume_drift =
          std::max(c.enclosed_volume_drift, std::abs(e.after - e.target) / e.target);
  }
  m_coupled_stats = c;

  CouplingSummary& s = *m_coupling_summary;
  s.coupled_steps += 1;
  s.iterations += rep.solve.iterations;
  s.max_residual = std::max(s.max_residual, rep.solve.residual);
  if (rep.solve.solves_at_floor > 0) {
    ++s.steps_at_floor;
    s.max_floor = std::max(s.max_floor, rep.solve.floor);
  }
  if (!rep.solve.converged) {
    ++s.unconverged_solves;
    if (rep.solve.stagnated)
      logger().warn(
          "coupled solve ({}) did not converge at t = {:.6g} s: its residual stagnated at {:.3g} "
          "after {} iterations, above its round-off floor {:.3g}; try coupling.solver = umfpack",
          rep.solve.backend, time, rep.solve.residual, rep.solve.iterations, rep.solve.floor);
    else
      logger().warn(
          "coupled solve ({}) did not converge at t = {:.6g} s: residual {:.3g} after {} "
          "iterations; raise coupling.max_iterations or try coupling.solver = umfpack",
          rep.solve.backend, time, rep.solve.residual, rep.solve.iterations);
  }
  s.max_interface_power = std::max(s.max_interface_power, std::abs(rep.solve.interface_power));
  s.max_interface_imbalance =
      std::max(s.max_interface_imbalance, std::abs(rep.solve.interface_imbalance));
  s.max_enclosed_regions =
      std::max(s.max_enclosed_regions, static_cast<Index>(rep.solve.enclosed.size()));
  s.max_volume_drift = std::max(s.max_volume_drift, c.enclosed_volume_drift);
  s.enclosed_volume = c.enclosed_volume;
  if (!rep.predicted_mesh) ++s.unpredicted_meshes;
  s.solid_iterations += rep.solid_iterations;
  s.total_energy = c.total_energy;
}

namespace {

/// The last step's fluid figures that have a checkpoint record (io/stats_columns.hpp).
template <class S, class F>
void visit_fields_step(S& s, F&& f) {
  visit_records(fluid_mesh_columns(), s, f);
  visit_records(fluid_step_columns(), s, f);
}

template <class S, class F>
void visit_fields_fluid(S& s, F&& f) {  // FluidSummary
  f("remeshes", s.remeshes);
  f("remesh_s", s.remesh_s);
  f("max_remesh_s", s.max_remesh_s);
  f("cells", s.cells);
  f("vertices", s.vertices);
  f("min_dihedral_deg", s.min_dihedral_deg);
  f("max_slivers", s.max_slivers);
  f("fluid_steps", s.fluid_steps);
  f("fluid_s", s.fluid_s);
  f("pressure_iterations", s.pressure_iterations);
  f("unconverged_pressure_solves", s.unconverged_pressure_solves);
  f("max_divergence", s.max_divergence);
  f("max_cfl", s.max_cfl);
  f("smoke_mass", s.smoke_mass);
  f("fluid_kinetic_energy", s.fluid_kinetic_energy);
}

template <class S, class F>
void visit_fields_coupled(S& s, F&& f) {  // CoupledStepStats
  visit_records(coupled_columns(), s, f);
}

template <class S, class F>
void visit_fields_coupling(S& s, F&& f) {  // CouplingSummary
  f("scheme", s.scheme);
  f("solver", s.solver);
  f("coupled_steps", s.coupled_steps);
  f("iterations", s.iterations);
  f("max_residual", s.max_residual);
  f("unconverged_solves", s.unconverged_solves);
  f("steps_at_floor", s.steps_at_floor);
  f("max_floor", s.max_floor);
  f("max_interface_power", s.max_interface_power);
  f("max_interface_imbalance", s.max_interface_imbalance);
  f("max_enclosed_regions", s.max_enclosed_regions);
  f("max_volume_drift", s.max_volume_drift);
  f("enclosed_volume", s.enclosed_volume);
  f("unpredicted_meshes", s.unpredicted_meshes);
  f("solid_iterations", s.solid_iterations);
  f("total_energy", s.total_energy);
}

}  // namespace

void RunRecorder::save_state(CheckpointWriter& w) const {
  const std::string p = "run/recorder/";
  visit_fields_step(m_stats, RecordSaver{w, p + "step/"});
  std::vector<std::string> names;
  std::vector<double> values;
  for (const auto& [name, value] : m_stats.quality) {
    names.push_back(name);
    values.push_back(value);
  }
  put_lines(w, p + "step/quality_names", names);
  w.put(p + "step/quality", values);
  visit_fields_fluid(m_summary, RecordSaver{w, p + "fluid/"});
  w.put(p + "has_coupled_step", m_coupled_stats.has_value());
  if (m_coupled_stats) visit_fields_coupled(*m_coupled_stats, RecordSaver{w, p + "coupled_step/"});
  w.put(p + "has_coupling", m_coupling_summary.has_value());
  if (m_coupling_summary)
    visit_fields_coupling(*m_coupling_summary, RecordSaver{w, p + "coupling/"});
}

void RunRecorder::load_state(const CheckpointReader& r) {
  const std::string p = "run/recorder/";
  visit_fields_step(m_stats, RecordLoader{r, p + "step/"});
  const std::vector<std::string> names = get_lines(r, p + "step/quality_names");
  const std::vector<double> values = r.get_vector<double>(p + "step/quality");
  if (names.size() < values.size()) r.fail(p + "step/quality_names: fewer names than values");
  m_stats.quality.clear();
  for (std::size_t i = 0; i < values.size(); ++i) m_stats.quality.emplace_back(names[i], values[i]);
  visit_fields_fluid(m_summary, RecordLoader{r, p + "fluid/"});
  m_coupled_stats.reset();
  if (r.get_bool(p + "has_coupled_step")) {
    CoupledStepStats c;
    visit_fields_coupled(c, RecordLoader{r, p + "coupled_step/"});
    m_coupled_stats = c;
  }
  if (r.get_bool(p + "has_coupling") != m_coupling_summary.has_value())
    r.fail(p + "has_coupling: the checkpoint's run and this one differ in coupling");
  if (m_coupling_summary)
    visit_fields_coupling(*m_coupling_summary, RecordLoader{r, p + "coupling/"});
}

}  // namespace tetfsi::app
