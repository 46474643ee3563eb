#include "tools/run_stats.hpp"

#include <algorithm>
#include <cmath>

#include "core/log.hpp"
#include "fluid/operators.hpp"
#include "mesh/quality.hpp"

namespace tetfsi::tools {

RunRecorder::RunRecorder(const coupling::FsiSimulation& sim) {
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
  if (r.coupled) {
    record_fluid_step(r.coupled->fluid, r.fluid_s, sim.fluid().time());
    record_coupled_step(*r.coupled, sim.world().time);
  } else if (r.fluid) {
    record_fluid_step(*r.fluid, r.fluid_s, sim.fluid().time());
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
  if (!rep.solve.converged) {
    ++s.unconverged_solves;
    logger().warn(
        "coupled solve ({}) did not converge at t = {:.6g} s: residual {:.3g} after {} "
        "iterations; raise coupling.max_iterations or try coupling.solver = umfpack",
        rep.solve.backend, time, rep.solve.residual, rep.solve.iterations);
  }
  s.max_interface_power = std::max(s.max_interface_power, std::abs(rep.solve.interface_power));
  s.max_enclosed_regions =
      std::max(s.max_enclosed_regions, static_cast<Index>(rep.solve.enclosed.size()));
  s.max_volume_drift = std::max(s.max_volume_drift, c.enclosed_volume_drift);
  s.enclosed_volume = c.enclosed_volume;
  if (!rep.predicted_mesh) ++s.unpredicted_meshes;
  s.solid_iterations += rep.solid_iterations;
  s.total_energy = c.total_energy;
}

FluidFrameFields frame_fields(const fluid::FluidSimulation& sim) {
  FluidFrameFields f;
  const fluid::FluidState& s = sim.state();
  f.pressure = s.p;
  f.face_velocity = s.u;
  f.density = s.density;
  f.temperature = s.temperature;
  const fluid::VelocityField v = sim.velocity_field();  // one reconstruction for all three
  f.vorticity = v.vorticity_magnitude();
  f.divergence = fluid::divergence(sim.mesh(), s.u);
  f.cell_velocity = v.cell_velocities();
  f.vertex_velocity = v.vertex_velocities();
  return f;
}

}  // namespace tetfsi::tools
