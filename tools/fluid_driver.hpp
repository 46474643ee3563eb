#pragma once
/// @file fluid_driver.hpp
/// The fluid of a scene, stepped beside the solids (one-way: the bodies move the fluid,
/// DESIGN.md §2 steps 2–6 without the coupled solve): every step the fluid mesh is rebuilt
/// around every body's boundary triangles at their current positions X + d (refined where the
/// fluid asks for it, fluid::FluidSimulation::refinement_field), then the fluid is advected
/// onto it and projected with the bodies' surface velocities as the Solid-face velocities.
/// Used by the run loop (run.cpp) and `tetfsi bench step`.
#include <optional>
#include <string>
#include <vector>

#include "core/timer.hpp"
#include "fluid/simulation.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"
#include "tools/output.hpp"
#include "tools/scene.hpp"

namespace tetfsi::tools {

/// The fluid over a run (fluid scenes only).
struct FluidSummary {
  int remeshes = 0;               ///< fluid meshes built (step 0 and after every step)
  double remesh_s = 0.0;          ///< wall seconds in the remesh phase, summed
  double max_remesh_s = 0.0;      ///< the slowest one (s)
  Index cells = 0, vertices = 0;  ///< of the last mesh
  double min_dihedral_deg = 0.0;  ///< smallest dihedral angle over every mesh (degrees)
  Index max_slivers = 0;          ///< most cells with min dihedral < 5° in one mesh
  int fluid_steps = 0;            ///< fluid steps taken
  double fluid_s = 0.0;           ///< wall seconds of transfer + forces + pressure, summed
  long long pressure_iterations = 0;  ///< summed over steps
  int unconverged_pressure_solves = 0;
  double max_divergence = 0.0;  ///< max over steps of max |D u| after the projection (1/s)
  double max_cfl = 0.0;
  double smoke_mass = 0.0;            ///< at the end (kg)
  double fluid_kinetic_energy = 0.0;  ///< at the end (J)
  double ms_per_remesh() const { return remeshes > 0 ? 1e3 * remesh_s / remeshes : 0.0; }
};

class FluidDriver {
 public:
  FluidDriver(const FluidSpec& spec, const solid::SolidWorld& world);

  /// Build the mesh of t = 0 around the bodies and start the fluid at rest on it.
  /// @throws MeshError as rebuild.
  void start(const solid::SolidWorld& world, PhaseTimes& phases);
  /// Rebuild the mesh around the bodies (already moved to t + h) and step the fluid by h.
  /// Phases: remesh, transfer, forces, pressure_assembly, pressure_solve (and output for the
  /// mesh's quality summary). On failure the mesh and state of the last good step stay.
  /// @throws MeshError naming the body if a body is not strictly inside the fluid box or the
  ///   remesh fails; SolverError if the fluid step fails.
  void step(const solid::SolidWorld& world, double h, PhaseTimes& phases);
  /// Only rebuild the mesh (static runs); the fluid restarts at rest on it.
  void rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases);

  /// The current fluid mesh (nullptr before start succeeded).
  const mesh::TetMesh* mesh() const;
  /// The fields of the current state, for a frame.
  FluidFrameFields frame_fields() const;
  const FluidStepStats& stats() const { return m_stats; }
  const FluidSummary& summary() const { return m_summary; }
  const fluid::FluidSimulation& simulation() const { return m_sim; }
  /// The last remesh's report.
  const mesh::RemeshReport& remesh_report() const { return m_report; }

 private:
  struct Boundary {
    VecXi nodes;       ///< body node of each compact surface vertex
    MatX3i triangles;  ///< boundary triangles in compact numbering
  };
  mesh::TetMesh build_mesh(const solid::SolidWorld& world, PhaseTimes& phases);
  void check_inside(const solid::SolidBody& b, size_t index, const MatX3& x,
                    const VecXi& nodes) const;
  std::vector<fluid::SolidSurfaceMotion> surface_motion(const solid::SolidWorld& world) const;

  FluidSpec m_spec;
  std::vector<Boundary> m_bodies;
  std::string m_legend;  ///< "body 0 is 'sheet', body 1 is 'flag'"
  fluid::FluidSimulation m_sim;
  bool m_started = false;
  mesh::RemeshReport m_report;
  FluidStepStats m_stats;
  FluidSummary m_summary;
};

}  // namespace tetfsi::tools
