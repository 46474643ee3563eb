#pragma once
/// @file fluid_driver.hpp
/// The fluid of a scene, stepped with the solids. Every step the fluid mesh is rebuilt around
/// every body's boundary triangles (coupling::body_surface) at given node positions (refined
/// where the fluid asks for it, fluid::FluidSimulation::refinement_field). Then either
///  - one-way (`step`; DESIGN.md §2 steps 2–6 without the coupled solve): the bodies have
///    stepped alone; the mesh is built around them at X + d, the fluid is advected onto it and
///    projected with the bodies' surface velocities as the Solid-face velocities; or
///  - two-way (`step_coupled`, with coupling parameters): coupling::CoupledStepper advances
///    the bodies and the fluid together (simultaneous [Chentanez06, Eq. (7)] or splitting),
///    asking this driver for the mesh around the positions it needs.
/// Used by the run loop (run.cpp) and `tetfsi bench step`.
#include <optional>
#include <string>
#include <vector>

#include "core/timer.hpp"
#include "coupling/coupled_step.hpp"
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
  /// Wall seconds of transfer + forces + pressure (two-way: + the coupled assembly and
  /// solve, which include the bodies' Eq. (4)), summed.
  double fluid_s = 0.0;
  long long pressure_iterations = 0;  ///< summed over steps
  int unconverged_pressure_solves = 0;
  double max_divergence = 0.0;  ///< max over steps of max |D u| after the projection (1/s)
  double max_cfl = 0.0;
  double smoke_mass = 0.0;            ///< at the end (kg)
  double fluid_kinetic_energy = 0.0;  ///< at the end (J)
  double ms_per_remesh() const { return remeshes > 0 ? 1e3 * remesh_s / remeshes : 0.0; }
};

/// The two-way coupling over a run (coupling::CoupledStepReport of every step).
struct CouplingSummary {
  std::string scheme;  ///< coupling::to_string of the scheme
  std::string solver;  ///< coupling::to_string(CoupledSolverKind)
  int coupled_steps = 0;
  long long iterations = 0;          ///< of the coupled solves, summed
  double max_residual = 0.0;         ///< worst relative residual of any coupled solve
  int unconverged_solves = 0;        ///< coupled solves that reported converged = false
  double max_interface_power = 0.0;  ///< max over steps of |pᵀ Jᵀ u| (W)
  Index max_enclosed_regions = 0;    ///< most enclosed regions in one step
  double max_volume_drift = 0.0;     ///< max over steps and regions of |after − target| / target
  double enclosed_volume = 0.0;  ///< Σ of the enclosed regions' volume after the last step (m³)
  /// Steps whose mesh had to be built around the bodies at tⁿ because the predicted surfaces
  /// x* = x + h u could not be meshed (e.g. a body predicted out of the box).
  int unpredicted_meshes = 0;
  long long solid_iterations = 0;  ///< splitting: the bodies' own solves, summed
  double total_energy = 0.0;  ///< fluid kinetic + solid kinetic + elastic after the last step (J)
};

class FluidDriver {
 public:
  /// @param coupling set: two-way coupling with these parameters (`step_coupled`)
  FluidDriver(const FluidSpec& spec, const solid::SolidWorld& world,
              std::optional<coupling::CouplingParams> coupling = std::nullopt);

  /// Build the mesh of t = 0 around the bodies and start the fluid at rest on it.
  /// @throws MeshError as rebuild.
  void start(const solid::SolidWorld& world, PhaseTimes& phases);
  /// Rebuild the mesh around the bodies (already moved to t + h) and step the fluid by h.
  /// Phases: remesh, transfer, forces, pressure_assembly, pressure_solve (and output for the
  /// mesh's quality summary). On failure the mesh and state of the last good step stay.
  /// @throws MeshError naming the body if a body is not strictly inside the fluid box or the
  ///   remesh fails; SolverError if the fluid step fails.
  void step(const solid::SolidWorld& world, double h, PhaseTimes& phases);
  /// Two-way coupled runs: advance the world and the fluid by h together
  /// (coupling::CoupledStepper::step, the mesh built by this driver as in `step`). Phases:
  /// remesh (and output for the mesh's quality summary), transfer, forces, coupled_assembly,
  /// coupled_solve, solid, update. On failure the world (restored by the stepper) and the
  /// fluid stay at the last good step.
  /// @throws MeshError naming the body if a body is not strictly inside the fluid box (at tⁿ⁺¹
  ///   or, simultaneous, also at tⁿ) or the remesh fails; SolverError if a solve fails or the
  ///   state becomes non-finite.
  coupling::CoupledStepReport step_coupled(solid::SolidWorld& world, double h, PhaseTimes& phases);
  /// True if the driver was made with coupling parameters.
  bool coupled() const { return m_stepper.has_value(); }
  /// Only rebuild the mesh (static runs); the fluid restarts at rest on it.
  void rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases);

  /// The current fluid mesh (nullptr before start succeeded).
  const mesh::TetMesh* mesh() const;
  /// The fields of the current state, for a frame.
  FluidFrameFields frame_fields() const;
  const FluidStepStats& stats() const { return m_stats; }
  const FluidSummary& summary() const { return m_summary; }
  /// Two-way runs: the coupling figures of the last step (unset before it) and over the run.
  const std::optional<CoupledStepStats>& coupled_stats() const { return m_coupled_stats; }
  const std::optional<CouplingSummary>& coupling_summary() const { return m_coupling_summary; }
  const fluid::FluidSimulation& simulation() const { return m_sim; }
  /// The last remesh's report.
  const mesh::RemeshReport& remesh_report() const { return m_report; }

 private:
  /// The mesh around the bodies at `positions` (one #n × 3 matrix per body, every node), with
  /// the remesh phase, the stats' mesh figures and the summary's remesh bookkeeping.
  /// @throws MeshError (see `step`).
  mesh::TetMesh build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases);
  /// Every body's nodes at X + d.
  static std::vector<MatX3> current_positions(const solid::SolidWorld& world);
  /// @param x the body's compact surface vertices (BodySurface::nodes order)
  void check_inside(size_t index, const MatX3& x) const;
  std::vector<fluid::SolidSurfaceMotion> surface_motion(const solid::SolidWorld& world) const;
  /// The stats and summary of a fluid step that took `seconds`.
  void record_fluid_step(const fluid::FluidStepReport& r, double seconds);

  FluidSpec m_spec;
  std::vector<coupling::BodySurface> m_bodies;
  std::vector<std::string> m_names;  ///< per body
  std::string m_legend;              ///< "body 0 is 'sheet', body 1 is 'flag'"
  fluid::FluidSimulation m_sim;
  bool m_started = false;
  mesh::RemeshReport m_report;
  FluidStepStats m_stats;
  FluidSummary m_summary;
  std::optional<coupling::CoupledStepper> m_stepper;  ///< two-way runs
  std::optional<CoupledStepStats> m_coupled_stats;
  std::optional<CouplingSummary> m_coupling_summary;
};

}  // namespace tetfsi::tools
