#include "coupling/simulation.hpp"

#include <exception>

#include "core/error.hpp"
#include "core/log.hpp"
#include "coupling/tet_fluid.hpp"

namespace tetfsi::coupling {

namespace {

std::vector<MatX3> current_positions(const solid::SolidWorld& world) {
  std::vector<MatX3> x;
  x.reserve(world.bodies.size());
  for (const solid::SolidBody& b : world.bodies) x.push_back(b.positions());
  return x;
}

}  // namespace

RemeshPolicy::RemeshPolicy(mesh::FluidDomain domain, mesh::Sizing sizing,
                           const solid::SolidWorld& world)
    : m_domain(std::move(domain)), m_sizing(std::move(sizing)) {
  // Each body's boundary (SolidBody::boundary_triangles of its rest mesh) is compacted once to
  // the nodes it uses; every rebuild only gathers their positions.
  for (const solid::SolidBody& b : world.bodies) {
    m_surfaces.push_back(body_surface(b));
    m_names.push_back(b.name());
    m_legend += fmt::format("{}body {} is '{}'", m_legend.empty() ? "" : ", ",
                            m_surfaces.size() - 1, b.name());
  }
}

mesh::TetMesh RemeshPolicy::build(const std::vector<MatX3>& positions,
                                  const fluid::RefineField* refine,
                                  mesh::RemeshReport* report) const {
  TETFSI_CHECK(positions.size() == m_surfaces.size(),
               "fluid remesh: {} position sets for {} bodies", positions.size(), m_surfaces.size());
  std::vector<mesh::SolidSurface> solids = place_surfaces(m_domain, m_surfaces, m_names, positions);
  mesh::Sizing sizing = m_sizing;
  if (refine) sizing.refine = *refine;  // finer where smoke / vorticity is
  try {
    return m_remesher.remesh(m_domain, solids, sizing, report);
  } catch (const std::exception& e) {
    // tetfsi errors, and also what CGAL or the allocator may throw (std::logic_error,
    // std::bad_alloc): the run stops like on any failed step instead of losing its summary.
    std::string why = e.what();
    if (why.rfind("remesh: ", 0) == 0) why = why.substr(8);
    throw MeshError(fmt::format("fluid remesh: {} ({})", why, m_legend));
  }
}

FsiSimulation::FsiSimulation(solid::SolidWorld world, std::optional<FluidSetup> fluid,
                             std::optional<CouplingParams> coupling)
    : m_world(std::move(world)) {
  TETFSI_REQUIRE(InputError, fluid || !coupling, "a two-way coupling ({}) needs a fluid",
                 coupling ? to_string(coupling->scheme) : "");
  if (!fluid) return;
  if (fluid->grid) {
    m_grid.emplace(fluid->params, fluid->grid->spec, fluid->domain);
    m_grid_forces = fluid->grid->forces;
  } else {
    m_fluid.emplace(fluid->params);
  }
  m_policy.emplace(std::move(fluid->domain), std::move(fluid->sizing), m_world);
  if (coupling) m_stepper.emplace(std::move(*coupling), m_world);
}

const fluid::FluidSimulation& FsiSimulation::fluid() const {
  TETFSI_CHECK(m_fluid.has_value(), "FsiSimulation::fluid: the simulation has no fluid");
  return *m_fluid;
}

fluid::FluidSimulation& FsiSimulation::fluid() {
  TETFSI_CHECK(m_fluid.has_value(), "FsiSimulation::fluid: the simulation has no fluid");
  return *m_fluid;
}

double FsiSimulation::fluid_time() const {
  if (m_grid) return m_grid->time();
  return m_fluid ? m_fluid->time() : 0.0;
}

std::vector<mesh::SolidSurface> FsiSimulation::grid_surfaces(
    const std::vector<MatX3>& positions) const {
  return place_surfaces(m_policy->domain(), m_policy->surfaces(), m_policy->names(), positions);
}

const mesh::TetMesh* FsiSimulation::mesh() const {
  return m_fluid && m_started ? &m_fluid->mesh() : nullptr;
}

mesh::TetMesh FsiSimulation::build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases) {
  ScopedTimer timer(phases, "remesh");
  mesh::RemeshReport report;
  fluid::RefineField refine;
  if (m_started) refine = m_fluid->refinement_field();
  mesh::TetMesh m = m_policy->build(positions, m_started ? &refine : nullptr, &report);
  const double seconds = timer.stop();
  if (m_observer) m_observer(m, report, seconds, phases);
  return m;
}

void FsiSimulation::start(PhaseTimes& phases) {
  if (m_grid) {
    m_started = false;
    m_grid_cache.valid = false;
    std::vector<mesh::SolidSurface> surfaces = grid_surfaces(current_positions(m_world));
    try {
      // The remesher's checks (intersections, nesting) at t = 0: the grid would take them.
      mesh::check_solid_surfaces(m_policy->domain(), surfaces, "fluid grid");
      m_grid->initialize(std::move(surfaces));
    } catch (const Error& e) {  // classify_grid and the checks name bodies by index
      throw InputError(fmt::format("{} ({})", e.what(), m_policy->legend()));
    }
    m_started = true;
  }
  if (!m_fluid) return;
  m_started = false;
  m_fluid->initialize(build_mesh(current_positions(m_world), phases));
  m_started = true;
}

void FsiSimulation::rebuild_at_rest(PhaseTimes& phases) {
  if (m_grid) {
    m_grid_cache.valid = false;
    m_grid->initialize(grid_surfaces(current_positions(m_world)));
    m_started = true;
  }
  if (!m_fluid) return;
  m_fluid->initialize(build_mesh(current_positions(m_world), phases));
  m_started = true;
}

FsiStepReport FsiSimulation::step(double h, PhaseTimes& phases) {
  TETFSI_CHECK(!has_fluid() || m_started, "FsiSimulation::step before start");
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
  const std::vector<fluid::SolidSurfaceMotion> motion =
      surface_motion(m_world, m_policy->surfaces());
  if (m_grid) {
    std::vector<mesh::SolidSurface> s;
    {
      ScopedTimer timer(phases, "remesh");  // the surfaces around the bodies
      s = grid_surfaces(current_positions(m_world));
    }
    const double t0 = now_seconds();
    // The output's J for the step's grid, built beside the (serial) pressure solve.
    m_grid_cache.valid = false;
    GridForceCache cache;
    std::function<void(const fluid::GridCells&)> alongside;
    if (!m_policy->surfaces().empty())
      alongside = [&](const fluid::GridCells& gc) {
        fill_grid_force_cache(gc, body_interfaces(m_world, m_policy->surfaces()), m_grid_forces,
                              m_grid->params(), m_grid->time() + h, cache);
      };
    r.fluid = m_grid->step(std::move(s), motion, h, fp, alongside);
    if (cache.valid && cache.time == m_grid->time()) m_grid_cache = std::move(cache);
    r.fluid_s = now_seconds() - t0;
  } else {
    mesh::TetMesh m = build_mesh(current_positions(m_world), phases);
    const double t0 = now_seconds();
    r.fluid = m_fluid->step(std::move(m), h, motion, fp);
    r.fluid_s = now_seconds() - t0;
  }
  phases.add("transfer", fp.get("transfer"));
  phases.add("forces", fp.get("forces"));
  phases.add("pressure_assembly", fp.get("assembly"));
  phases.add("pressure_solve", fp.get("solve"));
  return r;
}

FsiStepReport FsiSimulation::step_two_way(double h, PhaseTimes& phases) {
  // The builder times the remesh (and the observer's work) into `phases` itself; the
  // stepper's own phases are collected apart to tell the fluid's share.
  PhaseTimes sp;
  FsiStepReport r;
  std::vector<BodyInterface> bodies = body_interfaces(m_world, m_policy->surfaces());
  if (m_grid) {
    GridCoupledFluid fluid(*m_grid, m_policy->domain(), m_policy->surfaces(), m_policy->names(),
                           std::move(bodies), m_grid_forces, &m_grid_cache);
    r.coupled = m_stepper->step(m_world, fluid, h, sp);
  } else {
    const MeshBuilder build = [this, &phases](const std::vector<MatX3>& x) {
      return build_mesh(x, phases);
    };
    TetCoupledFluid fluid(*m_fluid, build, std::move(bodies));
    r.coupled = m_stepper->step(m_world, fluid, h, sp);
  }
  for (const auto& [name, seconds] : sp.entries()) phases.add(name, seconds);
  r.fluid_s =
      sp.get("transfer") + sp.get("forces") + sp.get("coupled_assembly") + sp.get("coupled_solve");
  return r;
}

std::vector<VecX> FsiSimulation::grid_fluid_forces() const {
  TETFSI_CHECK(m_grid && m_started, "FsiSimulation::grid_fluid_forces: no started grid fluid");
  return grid_current_forces(*m_grid, body_interfaces(m_world, m_policy->surfaces()), m_grid_forces,
                             &m_grid_cache);
}

void FsiSimulation::save_state(CheckpointWriter& w) const {
  w.put("sim/kind", std::string(m_grid ? "grid" : m_fluid ? "tet" : "solid"));
  w.put("sim/two_way", two_way());
  if (two_way()) w.put("sim/scheme", std::string(to_string(m_stepper->params().scheme)));
  m_world.save_state(w, "sim/solid/");
  w.put("sim/fluid_started", m_started);
  if (m_started && m_fluid) m_fluid->save_state(w, "sim/fluid/");
  if (m_started && m_grid) {
    m_grid->save_state(w, "sim/grid/");
    w.put("sim/grid/cache/valid", m_grid_cache.valid);
    if (m_grid_cache.valid) {
      w.put("sim/grid/cache/time", m_grid_cache.time);
      w.put("sim/grid/cache/Jc", m_grid_cache.Jc);
      w.put("sim/grid/cache/Jp", m_grid_cache.Jp);
    }
  }
  if (m_stepper) m_stepper->save_state(w, "sim/scheme/");
}

void FsiSimulation::load_state(const CheckpointReader& r) {
  const std::string kind = r.get_text("sim/kind");
  const std::string mine = m_grid ? "grid" : m_fluid ? "tet" : "solid";
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
  m_started = r.get_bool("sim/fluid_started");
  if (m_started && m_fluid) m_fluid->load_state(r, "sim/fluid/");
  if (m_started && m_grid) {
    m_grid->load_state(r, "sim/grid/");
    m_grid_cache = GridForceCache{};
    if (r.get_bool("sim/grid/cache/valid")) {
      m_grid_cache.time = r.get_double("sim/grid/cache/time");
      m_grid_cache.Jc = r.get_sparse("sim/grid/cache/Jc");
      m_grid_cache.Jp = r.get_sparse("sim/grid/cache/Jp");
      m_grid_cache.valid = true;
    }
  }
  if (m_stepper) m_stepper->load_state(r, "sim/scheme/");
}

}  // namespace tetfsi::coupling
