#pragma once
/// @file simulation.hpp
/// The coupled simulation as a library object: FsiSimulation owns the solid world, the fluid
/// (optional; one SimFluid whatever its discretisation, sim_fluid.hpp), the bodies' surfaces
/// in the fluid box (RemeshPolicy) and one coupling scheme (optional), and steps them. Three
/// kinds of run:
///  - solid only (no fluid): the bodies step alone (solid::SolidWorld::step);
///  - one-way (a fluid, no scheme): the bodies step alone, then the fluid steps around them
///    at X + d with the bodies' surface velocities on its Solid faces (SimFluid::step_alone);
///  - two-way (a fluid and a scheme): the scheme advances the bodies and the fluid together
///    (CoupledStepper, scheme.hpp) through the fluid's CoupledFluid (SimFluid::coupled).
/// The application (run/, cli/) parses a scene, builds this, runs the loop and writes output;
/// tests and benchmarks construct it directly.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_step.hpp"
#include "coupling/sim_fluid.hpp"
#include "fluid/frame.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

/// One step of a simulation.
struct FsiStepReport {
  /// Solid-only and one-way runs: the bodies' own step, and its wall seconds.
  std::optional<solid::SolidStepReport> solid;
  double solid_s = 0.0;
  /// Two-way runs: the coupled step (its `fluid` is the fluid's part).
  std::optional<CoupledStepReport> coupled;
  /// One-way runs: the fluid's step.
  std::optional<fluid::FluidStepReport> fluid;
  /// Wall seconds of the fluid's part: transfer + forces + pressure (two-way: + the coupled
  /// assembly and solve, which include the bodies' Eq. (4)).
  double fluid_s = 0.0;
};

class FsiSimulation {
 public:
  /// @param fluid set: a fluid scene (then `start` builds its first mesh)
  /// @param coupling set (with a fluid): two-way with this scheme; unset: one-way
  explicit FsiSimulation(solid::SolidWorld world, std::optional<FluidSetup> fluid = std::nullopt,
                         std::optional<CouplingParams> coupling = std::nullopt);

  /// The observer of every mesh the fluid builds (a tet fluid: every step's).
  void set_mesh_observer(MeshObserver observer);

  /// Fluid scenes: start the fluid at rest around the bodies (SimFluid::start: the mesh of
  /// t = 0, or the grid classified). @throws MeshError as RemeshPolicy::build, InputError.
  void start(PhaseTimes& phases);
  /// Advance by h. Phases: the bodies' (solid one-way: SolidWorld::step's), remesh, transfer,
  /// forces, pressure_assembly and pressure_solve (one-way), coupled_assembly, coupled_solve,
  /// solid, update (two-way). On failure the world (two-way: restored) and the fluid stay at
  /// the last good step. @throws MeshError, SolverError.
  FsiStepReport step(double h, PhaseTimes& phases);
  /// Only rebuild the fluid around the bodies as they are (static runs); it restarts at rest.
  void rebuild_at_rest(PhaseTimes& phases);

  /// Everything the next step reads, as records under "sim/" (core/checkpoint.hpp): the world's
  /// time, every body's d and u, the nonlinear integrators' histories (the kept starting
  /// matrix, BFGS updates), the fluid (its mesh or grid, fields and time), and the coupling
  /// scheme's state carried across steps. A simulation built from the same scene and given
  /// these by load_state steps on bit for bit as this one would.
  void save_state(CheckpointWriter& w) const;
  /// Restore save_state's records into a simulation just built from the same scene (instead
  /// of start()). @throws CheckpointError naming the record if they do not fit this
  /// simulation (other bodies or node counts, another discretisation or scheme).
  void load_state(const CheckpointReader& r);

  solid::SolidWorld& world() { return m_world; }
  const solid::SolidWorld& world() const { return m_world; }
  bool has_fluid() const { return m_fluid != nullptr; }
  bool two_way() const { return m_stepper.has_value(); }
  /// The fluid (nullptr without one), whatever its discretisation.
  const SimFluid* fluid() const { return m_fluid.get(); }
  SimFluid* fluid() { return m_fluid.get(); }
  /// The fluid's time (s) since start (0 without a fluid).
  double fluid_time() const;
  /// The fluid has been started (start succeeded).
  bool fluid_started() const { return m_fluid && m_fluid->started(); }
  /// The fluid's current state as a frame (an empty one without a started fluid).
  fluid::FluidFrame fluid_frame() const;
  /// The fluid's nodal forces on each body (3n, N) of its current state (started fluids).
  std::vector<VecX> fluid_forces() const;
  const RemeshPolicy* remesh_policy() const { return m_policy.get(); }
  /// Two-way runs: the scheme's parameters.
  const CouplingParams* coupling() const { return m_stepper ? &m_stepper->params() : nullptr; }

 private:
  FsiStepReport step_one_way(double h, PhaseTimes& phases);
  FsiStepReport step_two_way(double h, PhaseTimes& phases);

  solid::SolidWorld m_world;
  std::unique_ptr<const RemeshPolicy> m_policy;  ///< its address is the fluid's (a move keeps it)
  std::unique_ptr<SimFluid> m_fluid;
  std::optional<CoupledStepper> m_stepper;
};

}  // namespace tetfsi::coupling
