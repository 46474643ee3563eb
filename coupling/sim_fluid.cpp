/// @file sim_fluid.cpp
/// The bodies as every fluid of a simulation sees them (RemeshPolicy) and the fluid of a
/// setup (make_sim_fluid, sim_fluid.hpp).
#include "coupling/sim_fluid.hpp"

#include <exception>

#include "core/error.hpp"
#include "core/log.hpp"
#include "coupling/grid_fluid.hpp"
#include "coupling/tet_fluid.hpp"

namespace tetfsi::coupling {

std::vector<MatX3> body_positions(const solid::SolidWorld& world) {
  std::vector<MatX3> x;
  x.reserve(world.bodies.size());
  for (const solid::SolidBody& b : world.bodies) x.push_back(b.positions());
  return x;
}

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

std::vector<mesh::SolidSurface> RemeshPolicy::place(const std::vector<MatX3>& positions) const {
  return place_surfaces(m_domain, m_surfaces, m_names, positions);
}

std::unique_ptr<SimFluid> make_sim_fluid(const FluidSetup& setup, const RemeshPolicy& policy) {
  if (setup.grid) return std::make_unique<GridSimFluid>(setup.params, *setup.grid, policy);
  return std::make_unique<TetSimFluid>(setup.params, policy);
}

}  // namespace tetfsi::coupling
