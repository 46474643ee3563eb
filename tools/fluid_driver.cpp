#include "tools/fluid_driver.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include "core/error.hpp"
#include "core/log.hpp"
#include "fluid/operators.hpp"
#include "mesh/quality.hpp"

namespace tetfsi::tools {

FluidDriver::FluidDriver(const FluidSpec& spec, const solid::SolidWorld& world)
    : m_spec(spec), m_sim(spec.params) {
  // Each body's boundary (SolidBody::boundary_triangles of its rest mesh) is compacted once
  // to the nodes it uses; every rebuild only gathers their positions X + d.
  for (const solid::SolidBody& b : world.bodies) {
    Boundary bd;
    const MatX3i& tris = b.boundary_triangles();
    VecXi local = VecXi::Constant(b.num_nodes(), -1);
    std::vector<Index> nodes;
    bd.triangles.resize(tris.rows(), 3);
    for (Index t = 0; t < tris.rows(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const Index v = tris(t, k);
        if (local[v] < 0) {
          local[v] = static_cast<Index>(nodes.size());
          nodes.push_back(v);
        }
        bd.triangles(t, k) = local[v];
      }
    }
    bd.nodes = Eigen::Map<const VecXi>(nodes.data(), static_cast<Index>(nodes.size()));
    m_bodies.push_back(std::move(bd));
    m_legend += fmt::format("{}body {} is '{}'", m_legend.empty() ? "" : ", ",
                            m_bodies.size() - 1, b.name());
  }
}

void FluidDriver::check_inside(const solid::SolidBody& b, size_t index, const MatX3& x,
                               const VecXi& nodes) const {
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
        b.name(), index, fmt_vec(lo), fmt_vec(hi), nodes[k], fmt_vec(p), fmt_vec(blo),
        fmt_vec(bhi)));
  }
}

mesh::TetMesh FluidDriver::build_mesh(const solid::SolidWorld& world, PhaseTimes& phases) {
  ScopedTimer timer(phases, "remesh");
  std::vector<mesh::SolidSurface> solids(world.bodies.size());
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    const solid::SolidBody& b = world.bodies[i];
    const Boundary& bd = m_bodies[i];
    mesh::SolidSurface& s = solids[i];
    s.body = static_cast<int>(i);
    s.triangles = bd.triangles;
    s.vertices.resize(bd.nodes.size(), 3);
    for (Index k = 0; k < bd.nodes.size(); ++k) {
      const Index v = bd.nodes[k];
      s.vertices.row(k) = b.rest_positions().row(v) + b.displacement.row(v);
    }
    check_inside(b, i, s.vertices, bd.nodes);
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
    const Boundary& bd = m_bodies[i];
    s[i].triangles = bd.triangles;
    s[i].velocity.resize(bd.nodes.size(), 3);
    for (Index k = 0; k < bd.nodes.size(); ++k)
      s[i].velocity.row(k) = world.bodies[i].velocity.row(bd.nodes[k]);
  }
  return s;
}

void FluidDriver::start(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_started = false;
  m_sim.initialize(build_mesh(world, phases));
  m_started = true;
}

void FluidDriver::rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_sim.initialize(build_mesh(world, phases));
  m_started = true;
}

void FluidDriver::step(const solid::SolidWorld& world, double h, PhaseTimes& phases) {
  TETFSI_CHECK(m_started, "FluidDriver::step before start");
  mesh::TetMesh m = build_mesh(world, phases);
  PhaseTimes fp;
  const double t0 = now_seconds();
  const fluid::FluidStepReport r = m_sim.step(std::move(m), h, surface_motion(world), fp);
  m_summary.fluid_s += now_seconds() - t0;
  phases.add("transfer", fp.get("transfer"));
  phases.add("forces", fp.get("forces"));
  phases.add("pressure_assembly", fp.get("assembly"));
  phases.add("pressure_solve", fp.get("solve"));
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
