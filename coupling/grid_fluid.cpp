/// @file grid_fluid.cpp
/// GridSimFluid (grid_fluid.hpp): the grid fluid of a simulation.
#include "coupling/grid_fluid.hpp"

#include <cmath>

#include "core/error.hpp"
#include "core/log.hpp"
#include "fluid/grid/interface.hpp"

namespace tetfsi::coupling {

GridSimFluid::GridSimFluid(const fluid::FluidParams& params, const GridSetup& grid,
                           const RemeshPolicy& policy)
    : m_grid(params, grid.spec, policy.domain()), m_forces(grid.forces), m_policy(policy) {}

void GridSimFluid::start(const solid::SolidWorld& world, PhaseTimes&) {
  m_started = false;
  m_cache.valid = false;
  std::vector<mesh::SolidSurface> surfaces = m_policy.place(body_positions(world));
  try {
    // The remesher's checks (intersections, nesting) at t = 0: the grid would take them.
    mesh::check_solid_surfaces(m_policy.domain(), surfaces, "fluid grid");
    m_grid.initialize(std::move(surfaces));
  } catch (const Error& e) {  // classify_grid and the checks name bodies by index
    throw InputError(fmt::format("{} ({})", e.what(), m_policy.legend()));
  }
  m_started = true;
}

void GridSimFluid::rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes&) {
  m_cache.valid = false;
  m_grid.initialize(m_policy.place(body_positions(world)));
  m_started = true;
}

FluidStepAlone GridSimFluid::step_alone(const solid::SolidWorld& world, double h,
                                        PhaseTimes& phases, PhaseTimes& fluid_phases) {
  const std::vector<fluid::SolidSurfaceMotion> motion = surface_motion(world, m_policy.surfaces());
  std::vector<mesh::SolidSurface> s;
  {
    ScopedTimer timer(phases, "remesh");  // the surfaces around the bodies
    s = m_policy.place(body_positions(world));
  }
  FluidStepAlone r;
  const double t0 = now_seconds();
  // The output's J for the step's grid, built beside the (serial) pressure solve.
  m_cache.valid = false;
  GridForceCache cache;
  std::function<void(const fluid::GridCells&)> alongside;
  if (!m_policy.surfaces().empty())
    alongside = [&](const fluid::GridCells& gc) {
      fill_grid_force_cache(gc, body_interfaces(world, m_policy.surfaces()), m_forces,
                            m_grid.params(), m_grid.time() + h, cache);
    };
  r.report = m_grid.step(std::move(s), motion, h, fluid_phases, alongside);
  if (cache.valid && cache.time == m_grid.time()) m_cache = std::move(cache);
  r.seconds = now_seconds() - t0;
  return r;
}

std::unique_ptr<CoupledFluid> GridSimFluid::coupled(std::vector<BodyInterface> bodies,
                                                    PhaseTimes&) {
  return std::make_unique<GridCoupledFluid>(m_grid, m_policy.domain(), m_policy.surfaces(),
                                            m_policy.names(), std::move(bodies), m_forces,
                                            &m_cache);
}

Index GridSimFluid::cells() const {
  const fluid::GridCells& gc = m_grid.cells();
  Index n = 0;
  for (Index c = 0; c < gc.grid.num_cells(); ++c) n += gc.fluid(c) ? 1 : 0;
  return n;
}

std::vector<VecX> GridSimFluid::body_forces(const solid::SolidWorld& world) const {
  TETFSI_CHECK(m_started, "GridSimFluid::body_forces: the grid fluid has not started");
  return grid_current_forces(m_grid, body_interfaces(world, m_policy.surfaces()), m_forces,
                             &m_cache);
}

namespace {

/// The pressure read on one side of every body triangle (side-aware, a quarter of the
/// smallest cell from the centroid along ±n); NaN where that side sees no fluid cell.
double side_pressure(const fluid::GridCells& gc, const VecX& p, const Vec3& x) {
  const auto st = fluid::grid_cell_stencil(gc, x);
  if (st.empty()) return NAN;
  double v = 0.0;
  for (const auto& [c, w] : st) v += w * p[c];
  return v;
}

/// The bodies' boundary triangles at `world`'s positions into `f`, with the pressure on each
/// side and the fluid's nodal forces `force` (per body) on their points.
void add_surfaces(const fluid::GridFluid& g, const solid::SolidWorld& world,
                  const std::vector<BodySurface>& surf, const std::vector<VecX>& force,
                  fluid::GridFrameFields& f) {
  const fluid::GridCells& gc = g.cells();
  const VecX& p = g.state().p;
  Index np = 0, nt = 0;
  for (const auto& s : surf) {
    np += s.nodes.size();
    nt += s.triangles.rows();
  }
  f.surface_points.resize(np, 3);
  f.surface_force.resize(np, 3);
  f.surface_triangles.resize(nt, 3);
  f.surface_body.resize(nt);
  f.surface_pressure.resize(nt);
  f.surface_pressure_jump.resize(nt);
  const double eps = 0.25 * gc.grid.h.minCoeff();
  Index p0 = 0, t0 = 0;
  for (size_t b = 0; b < surf.size(); ++b) {
    const MatX3 x = world.bodies[b].positions();
    for (Index k = 0; k < surf[b].nodes.size(); ++k) {
      const Index node = surf[b].nodes[k];
      f.surface_points.row(p0 + k) = x.row(node);
      f.surface_force.row(p0 + k) = force[b].segment<3>(3 * node).transpose();
    }
    for (Index t = 0; t < surf[b].triangles.rows(); ++t) {
      Vec3 v[3];
      for (int k = 0; k < 3; ++k) {
        f.surface_triangles(t0 + t, k) = p0 + surf[b].triangles(t, k);
        v[k] = f.surface_points.row(p0 + surf[b].triangles(t, k)).transpose();
      }
      const Vec3 n = (v[1] - v[0]).cross(v[2] - v[0]).normalized();
      const Vec3 c = (v[0] + v[1] + v[2]) / 3.0;
      const double out = side_pressure(gc, p, c + eps * n);
      const double in = side_pressure(gc, p, c - eps * n);
      f.surface_body[t0 + t] = static_cast<int>(b);
      f.surface_pressure[t0 + t] = out;
      f.surface_pressure_jump[t0 + t] = std::isfinite(in) ? out - in : NAN;
    }
    p0 += surf[b].nodes.size();
    t0 += surf[b].triangles.rows();
  }
}

}  // namespace

fluid::FluidFrame GridSimFluid::frame(const solid::SolidWorld& world) const {
  fluid::FluidFrame frame;
  if (!m_started) return frame;
  fluid::GridFrameFields f = fluid::grid_frame_fields(m_grid);
  // the bodies' boundary triangles and the fluid's nodal forces on them (J of the scene's
  // fluid.grid.pressure_forces, total pressure)
  add_surfaces(m_grid, world, m_policy.surfaces(), body_forces(world), f);
  frame.geometry = std::move(f);
  return frame;
}

std::string GridSimFluid::start_summary(double seconds) const {
  const VecXi& body = m_grid.cells().cell_body;
  const Index fluid_cells = (body.array() < 0).count();
  return fmt::format("fluid grid at t = 0: {} of {} cells fluid, classified in {:.3g} s\n",
                     fluid_cells, body.size(), seconds);
}

void GridSimFluid::save_state(CheckpointWriter& w, const std::string& prefix) const {
  m_grid.save_state(w, prefix + "grid/");
  w.put(prefix + "grid/cache/valid", m_cache.valid);
  if (m_cache.valid) {
    w.put(prefix + "grid/cache/time", m_cache.time);
    w.put(prefix + "grid/cache/Jc", m_cache.Jc);
    w.put(prefix + "grid/cache/Jp", m_cache.Jp);
  }
}

void GridSimFluid::load_state(const CheckpointReader& r, const std::string& prefix) {
  m_grid.load_state(r, prefix + "grid/");
  m_cache = GridForceCache{};
  if (r.get_bool(prefix + "grid/cache/valid")) {
    m_cache.time = r.get_double(prefix + "grid/cache/time");
    m_cache.Jc = r.get_sparse(prefix + "grid/cache/Jc");
    m_cache.Jp = r.get_sparse(prefix + "grid/cache/Jp");
    m_cache.valid = true;
  }
  m_started = true;
}

}  // namespace tetfsi::coupling
