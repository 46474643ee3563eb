#include "tools/fluid_driver.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include "core/error.hpp"
#include "core/log.hpp"
#include "fluid/operators.hpp"
#include "mesh/quality.hpp"

namespace tetfsi::tools {

FluidDriver::FluidDriver(const FluidSpec& spec, const solid::SolidWorld& world,
                         std::optional<coupling::CouplingParams> coupling)
    : m_spec(spec), m_sim(spec.params) {
  // Each body's boundary (SolidBody::boundary_triangles of its rest mesh) is compacted once
  // to the nodes it uses, as the coupled stepper does; every rebuild only gathers their
  // positions.
  for (const solid::SolidBody& b : world.bodies) {
    m_bodies.push_back(coupling::body_surface(b));
    m_names.push_back(b.name());
    m_legend += fmt::format("{}body {} is '{}'", m_legend.empty() ? "" : ", ",
                            m_bodies.size() - 1, b.name());
  }
  if (coupling) {
    CouplingSummary c;
    c.scheme = coupling::to_string(coupling->scheme);
    c.solver = coupling::to_string(coupling->solve.solver);
    m_coupling_summary = c;
    m_stepper.emplace(std::move(*coupling), world);
  }
}

void FluidDriver::check_inside(size_t index, const MatX3& x) const {
  const Vec3& lo = m_spec.domain.lo;
  const Vec3& hi = m_spec.domain.hi;
  for (Index k = 0; k < x.rows(); ++k) {
    const Vec3 p = x.row(k).transpose();
    if ((p.array() > lo.array()).all() && (p.array() < hi.array()).all()) continue;
    const Vec3 blo = x.colwise().minCoeff().transpose();
    const Vec3 bhi = x.colwise().maxCoeff().transpose();
    throw MeshError(fmt::format(
        "body '{}' (bodies[{}]) is not strictly inside the fluid box {}..{}: node {} is at {} "
        "and the body spans {}..{}; enlarge fluid.domain or keep the body inside",
        m_names[index], index, fmt_vec(lo), fmt_vec(hi), m_bodies[index].nodes[k], fmt_vec(p),
        fmt_vec(blo), fmt_vec(bhi)));
  }
}

std::vector<MatX3> FluidDriver::current_positions(const solid::SolidWorld& world) {
  std::vector<MatX3> x;
  x.reserve(world.bodies.size());
  for (const solid::SolidBody& b : world.bodies) x.push_back(b.positions());
  return x;
}

mesh::TetMesh FluidDriver::build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases) {
  ScopedTimer timer(phases, "remesh");
  TETFSI_CHECK(positions.size() == m_bodies.size(), "fluid remesh: {} position sets for {} bodies",
               positions.size(), m_bodies.size());
  std::vector<mesh::SolidSurface> solids(m_bodies.size());
  for (size_t i = 0; i < m_bodies.size(); ++i) {
    const coupling::BodySurface& bd = m_bodies[i];
    mesh::SolidSurface& s = solids[i];
    s.body = static_cast<int>(i);
    s.triangles = bd.triangles;
    TETFSI_CHECK(bd.nodes.size() == 0 || positions[i].rows() > bd.nodes.maxCoeff(),
                 "fluid remesh: {} positions for body '{}', its surface uses node {}",
                 positions[i].rows(), m_names[i], bd.nodes.maxCoeff());
    s.vertices.resize(bd.nodes.size(), 3);
    for (Index k = 0; k < bd.nodes.size(); ++k) s.vertices.row(k) = positions[i].row(bd.nodes[k]);
    check_inside(i, s.vertices);
  }
  mesh::Sizing sizing = m_spec.sizing;
  if (m_started) sizing.refine = m_sim.refinement_field();  // finer where smoke / vorticity is
  mesh::RemeshReport report;
  mesh::TetMesh m;
  try {
    m = mesh::remesh(m_spec.domain, solids, sizing, &report);
  } catch (const std::exception& e) {
    // tetfsi errors, and also what CGAL or the allocator may throw (std::logic_error,
    // std::bad_alloc): the run stops like on any failed step instead of losing its summary.
    std::string why = e.what();
    if (why.rfind("remesh: ", 0) == 0) why = why.substr(8);
    throw MeshError(fmt::format("fluid remesh: {} ({})", why, m_legend));
  }
  const double seconds = timer.stop();

  ScopedTimer quality_timer(phases, "output");
  const mesh::QualitySummary q = mesh::summarize_quality(m);
  m_report = report;
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
  return m;
}

std::vector<fluid::SolidSurfaceMotion> FluidDriver::surface_motion(
    const solid::SolidWorld& world) const {
  std::vector<fluid::SolidSurfaceMotion> s(world.bodies.size());
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    const coupling::BodySurface& bd = m_bodies[i];
    s[i].triangles = bd.triangles;
    s[i].velocity.resize(bd.nodes.size(), 3);
    for (Index k = 0; k < bd.nodes.size(); ++k)
      s[i].velocity.row(k) = world.bodies[i].velocity.row(bd.nodes[k]);
  }
  return s;
}

void FluidDriver::start(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_started = false;
  m_sim.initialize(build_mesh(current_positions(world), phases));
  m_started = true;
}

void FluidDriver::rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_sim.initialize(build_mesh(current_positions(world), phases));
  m_started = true;
}

void FluidDriver::step(const solid::SolidWorld& world, double h, PhaseTimes& phases) {
  TETFSI_CHECK(m_started, "FluidDriver::step before start");
  mesh::TetMesh m = build_mesh(current_positions(world), phases);
  PhaseTimes fp;
  const double t0 = now_seconds();
  const fluid::FluidStepReport r = m_sim.step(std::move(m), h, surface_motion(world), fp);
  const double seconds = now_seconds() - t0;
  phases.add("transfer", fp.get("transfer"));
  phases.add("forces", fp.get("forces"));
  phases.add("pressure_assembly", fp.get("assembly"));
  phases.add("pressure_solve", fp.get("solve"));
  record_fluid_step(r, seconds);
}

coupling::CoupledStepReport FluidDriver::step_coupled(solid::SolidWorld& world, double h,
                                                      PhaseTimes& phases) {
  TETFSI_CHECK(m_started && m_stepper,
               "FluidDriver::step_coupled before start or without coupling parameters");
  // The builder times the remesh (and the mesh's quality summary) into `phases` itself; the
  // stepper's own phases are collected apart to tell the fluid's share.
  const coupling::MeshBuilder build = [this, &phases](const std::vector<MatX3>& x) {
    return build_mesh(x, phases);
  };
  PhaseTimes sp;
  const coupling::CoupledStepReport rep = m_stepper->step(world, m_sim, build, h, sp);
  for (const auto& [name, seconds] : sp.entries()) phases.add(name, seconds);
  record_fluid_step(rep.fluid, sp.get("transfer") + sp.get("forces") + sp.get("coupled_assembly") +
                                   sp.get("coupled_solve"));

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
        rep.solve.backend, world.time, rep.solve.residual, rep.solve.iterations);
  }
  s.max_interface_power = std::max(s.max_interface_power, std::abs(rep.solve.interface_power));
  s.max_enclosed_regions =
      std::max(s.max_enclosed_regions, static_cast<Index>(rep.solve.enclosed.size()));
  s.max_volume_drift = std::max(s.max_volume_drift, c.enclosed_volume_drift);
  s.enclosed_volume = c.enclosed_volume;
  if (!rep.predicted_mesh) ++s.unpredicted_meshes;
  s.solid_iterations += rep.solid_iterations;
  s.total_energy = c.total_energy;
  return rep;
}

void FluidDriver::record_fluid_step(const fluid::FluidStepReport& r, double seconds) {
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
    logger().warn("fluid CFL number {:.3g} at t = {:.6g} s: semi-Lagrangian advection stays "
                  "stable but smears; reduce time.dt for accuracy",
                  r.cfl, m_sim.time());
}

const mesh::TetMesh* FluidDriver::mesh() const { return m_started ? &m_sim.mesh() : nullptr; }

FluidFrameFields FluidDriver::frame_fields() const {
  FluidFrameFields f;
  const fluid::FluidState& s = m_sim.state();
  f.pressure = s.p;
  f.face_velocity = s.u;
  f.density = s.density;
  f.temperature = s.temperature;
  const fluid::VelocityField v = m_sim.velocity_field();  // one reconstruction for all three
  f.vorticity = v.vorticity_magnitude();
  f.divergence = fluid::divergence(m_sim.mesh(), s.u);
  f.cell_velocity = v.cell_velocities();
  f.vertex_velocity = v.vertex_velocities();
  return f;
}

}  // namespace tetfsi::tools
