#pragma once
/// @file coupled_test_utils.hpp
/// A fluid box with solid bodies, stepped by coupling::FsiSimulation — the library's own
/// simulation object, with its remesh policy, as the run loop uses it; no application layer.
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "coupling/grid_fluid.hpp"
#include "coupling/simulation.hpp"
#include "coupling/tet_fluid.hpp"
#include "fluid/tet/simulation.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"
#include "tests/fluid/fluid_test_utils.hpp"

namespace tetfsi::test {

struct CoupledRig {
  mesh::FluidDomain domain;
  mesh::Sizing sizing;
  fluid::FluidParams fluid_params;
  coupling::CouplingParams coupling;
  std::optional<coupling::GridSetup> grid;  ///< set: the fluid on this MAC grid
  std::unique_ptr<coupling::FsiSimulation> sim;

  /// The bodies: the rig's own before start(), the simulation's after.
  solid::SolidWorld& world() { return sim ? sim->world() : m_world; }
  /// The tet fluid (after start(), tet rigs).
  fluid::FluidSimulation& fluid() { return *coupling::tet_fluid(sim->fluid()); }
  /// The grid fluid (after start(), grid rigs).
  fluid::GridFluid& grid_fluid() { return *coupling::grid_fluid(sim->fluid()); }
  const std::vector<coupling::BodySurface>& surfaces() const {
    return sim->remesh_policy()->surfaces();
  }

  /// The fluid mesh around every body at the given node positions (the simulation's policy).
  mesh::TetMesh build(const std::vector<MatX3>& x) const {
    return sim->remesh_policy()->build(x, nullptr);
  }

  /// Build the simulation (two-way, `coupling`) and the fluid at rest on the mesh of t = 0.
  void start() {
    sim = std::make_unique<coupling::FsiSimulation>(
        std::move(m_world), coupling::FluidSetup{domain, sizing, fluid_params, grid}, coupling);
    PhaseTimes phases;
    sim->start(phases);
  }

  coupling::CoupledStepReport step(double h) {
    PhaseTimes phases;
    return *sim->step(h, phases).coupled;
  }

 private:
  solid::SolidWorld m_world;
};

/// The fluid of a rig: water with gravity in the unit box, open (pressure 0) at the top.
inline void water_box_open_top(CoupledRig& r) {
  r.domain = box_domain(Vec3::Zero(), Vec3::Ones());
  mesh::DomainPatch top;
  top.kind = mesh::FaceKind::Open;
  top.side = 5;
  top.lo = Vec2(0, 0);
  top.hi = Vec2(1, 1);
  r.domain.patches.push_back(top);
  r.fluid_params.density = 1000;
  r.fluid_params.gravity = Vec3(0, 0, -9.81);
  r.fluid_params.patches.resize(1);
}

}  // namespace tetfsi::test
