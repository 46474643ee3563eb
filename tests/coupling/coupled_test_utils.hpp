#pragma once
/// @file coupled_test_utils.hpp
/// A fluid box with solid bodies, stepped by coupling::CoupledStepper: the remesher builds the
/// fluid mesh around the bodies' surfaces as the run loop does (tools/fluid_driver.cpp).
#include <utility>
#include <vector>

#include "coupling/coupled_step.hpp"
#include "fluid/simulation.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"
#include "tests/fluid/fluid_test_utils.hpp"

namespace tetfsi::test {

struct CoupledRig {
  solid::SolidWorld world;
  mesh::FluidDomain domain;
  mesh::Sizing sizing;
  fluid::FluidParams fluid_params;
  coupling::CouplingParams coupling;

  std::unique_ptr<fluid::FluidSimulation> fluid;
  std::unique_ptr<coupling::CoupledStepper> stepper;

  /// The fluid mesh around every body at the given node positions.
  mesh::TetMesh build(const std::vector<MatX3>& x) const {
    std::vector<mesh::SolidSurface> s(world.bodies.size());
    for (size_t b = 0; b < s.size(); ++b) {
      const coupling::BodySurface& bs = stepper->surfaces()[b];
      s[b].body = static_cast<int>(b);
      s[b].triangles = bs.triangles;
      s[b].vertices.resize(bs.nodes.size(), 3);
      for (Index k = 0; k < bs.nodes.size(); ++k) s[b].vertices.row(k) = x[b].row(bs.nodes[k]);
    }
    return mesh::remesh(domain, s, sizing);
  }

  /// Build the stepper and the fluid at rest on the mesh of t = 0.
  void start() {
    stepper = std::make_unique<coupling::CoupledStepper>(coupling, world);
    fluid = std::make_unique<fluid::FluidSimulation>(fluid_params);
    std::vector<MatX3> x;
    for (const auto& b : world.bodies) x.push_back(b.positions());
    fluid->initialize(build(x));
  }

  coupling::CoupledStepReport step(double h) {
    PhaseTimes phases;
    return stepper->step(
        world, *fluid, [this](const std::vector<MatX3>& x) { return build(x); }, h, phases);
  }
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
