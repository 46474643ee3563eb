#pragma once
/// @file simulation.hpp
/// The coupled simulation as a library object (DESIGN.md §2): FsiSimulation owns the solid
/// world, the fluid (optional), the remesh policy and one coupling scheme (optional), and
/// steps them. Three kinds of run:
///  - solid only (no fluid): the bodies step alone (solid::SolidWorld::step);
///  - one-way (a fluid, no scheme): the bodies step alone, then the fluid mesh is rebuilt
///    around them at X + d, the fluid advected onto it and projected with the bodies' surface
///    velocities on the Solid faces (fluid::FluidSimulation::step);
///  - two-way (a fluid and a scheme): the scheme advances the bodies and the fluid together
///    (CoupledStepper, scheme.hpp), asking the remesh policy for the mesh around the
///    positions it needs.
/// The application (run/, cli/) parses a scene, builds this, runs the loop and writes output;
/// tests and benchmarks construct it directly.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_step.hpp"
#include "coupling/grid_coupled.hpp"
#include "fluid/simulation.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

/// How the fluid mesh is rebuilt every step: around every body's boundary triangles
/// (body_surface) at given node positions, refined where the fluid asks for it
/// (fluid::FluidSimulation::refinement_field), inside the fluid box.
class RemeshPolicy {
 public:
  RemeshPolicy(mesh::FluidDomain domain, mesh::Sizing sizing, const solid::SolidWorld& world);

  /// The mesh around the bodies at `positions` (one #n × 3 matrix per body, every node).
  /// @param refine if set, replaces the sizing's refinement (the fluid's request, which may
  ///   be empty: none)
  /// @param report if set, the remesher's report
  /// With sizing().incremental, each call starts from the last call's triangulation (the
  /// same mesh as a full rebuild, bit for bit: mesh::Remesher); not for concurrent calls.
  /// @throws MeshError naming the body if a body is not strictly inside the fluid box, or
  ///   naming the bodies if the remesh fails.
  mesh::TetMesh build(const std::vector<MatX3>& positions, const fluid::RefineField* refine,
                      mesh::RemeshReport* report = nullptr) const;

  const mesh::FluidDomain& domain() const { return m_domain; }
  const mesh::Sizing& sizing() const { return m_sizing; }
  const std::vector<BodySurface>& surfaces() const { return m_surfaces; }
  const std::vector<std::string>& names() const { return m_names; }
  /// "body 0 is 'sheet', body 1 is 'flag'"
  const std::string& legend() const { return m_legend; }

 private:
  mesh::FluidDomain m_domain;
  mesh::Sizing m_sizing;
  std::vector<BodySurface> m_surfaces;
  std::vector<std::string> m_names;   ///< per body
  std::string m_legend;               ///< "body 0 is 'sheet', body 1 is 'flag'"
  mutable mesh::Remesher m_remesher;  ///< keeps the last triangulation (Sizing::incremental)
};

/// The regular-grid discretisation of a simulation's fluid (grid_coupled.hpp).
struct GridSetup {
  fluid::GridSpec spec;
  GridPressureForces forces = GridPressureForces::Paper;
};

/// The fluid of a simulation: its box, mesh sizing and physics; with `grid`, on the MAC grid
/// instead of the dynamic tet mesh (the sizing is then unused).
struct FluidSetup {
  mesh::FluidDomain domain;
  mesh::Sizing sizing;
  fluid::FluidParams params;
  std::optional<GridSetup> grid;
};

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

/// Called after every mesh the policy built successfully, with the remesh's wall seconds and
/// the phases of the step (a caller's diagnostics, e.g. the mesh quality).
using MeshObserver = std::function<void(const mesh::TetMesh&, const mesh::RemeshReport&,
                                        double seconds, PhaseTimes& phases)>;

class FsiSimulation {
 public:
  /// @param fluid set: a fluid scene (then `start` builds its first mesh)
  /// @param coupling set (with a fluid): two-way with this scheme; unset: one-way
  explicit FsiSimulation(solid::SolidWorld world, std::optional<FluidSetup> fluid = std::nullopt,
                         std::optional<CouplingParams> coupling = std::nullopt);

  void set_mesh_observer(MeshObserver observer) { m_observer = std::move(observer); }

  /// Fluid scenes: build the mesh of t = 0 around the bodies and start the fluid at rest on
  /// it. @throws MeshError as RemeshPolicy::build.
  void start(PhaseTimes& phases);
  /// Advance by h. Phases: the bodies' (solid one-way: SolidWorld::step's), remesh, transfer,
  /// forces, pressure_assembly and pressure_solve (one-way), coupled_assembly, coupled_solve,
  /// solid, update (two-way). On failure the world (two-way: restored) and the fluid stay at
  /// the last good step. @throws MeshError, SolverError.
  FsiStepReport step(double h, PhaseTimes& phases);
  /// Only rebuild the mesh around the bodies as they are (static runs); the fluid restarts at
  /// rest on it.
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
  bool has_fluid() const { return m_fluid.has_value() || m_grid.has_value(); }
  bool two_way() const { return m_stepper.has_value(); }
  /// The tet fluid (tet fluid scenes only); e.g. to set an initial velocity field after start.
  const fluid::FluidSimulation& fluid() const;
  fluid::FluidSimulation& fluid();
  /// The grid fluid (grid scenes only, else nullptr).
  const fluid::GridFluid* grid() const { return m_grid ? &*m_grid : nullptr; }
  fluid::GridFluid* grid() { return m_grid ? &*m_grid : nullptr; }
  /// The fluid's time (s) since start, either discretisation.
  double fluid_time() const;
  /// The current tet fluid mesh (nullptr before start succeeded, without a fluid, or on the
  /// grid).
  const mesh::TetMesh* mesh() const;
  /// The fluid has been started (start succeeded).
  bool fluid_started() const { return m_started; }
  /// Grid scenes: the grid's pressure forces form.
  GridPressureForces grid_forces() const { return m_grid_forces; }
  /// Grid scenes (started): the fluid's nodal forces on each body (3n, N) on the current grid
  /// — the last step's J where the step built them (grid_current_forces).
  std::vector<VecX> grid_fluid_forces() const;
  const RemeshPolicy* remesh_policy() const { return m_policy ? &*m_policy : nullptr; }
  /// Two-way runs: the scheme's parameters.
  const CouplingParams* coupling() const { return m_stepper ? &m_stepper->params() : nullptr; }

 private:
  /// The policy's mesh around the bodies at `positions`, timed as the remesh phase, observed.
  mesh::TetMesh build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases);
  FsiStepReport step_one_way(double h, PhaseTimes& phases);
  /// The grid fluid's surfaces around the bodies at `positions`.
  std::vector<mesh::SolidSurface> grid_surfaces(const std::vector<MatX3>& positions) const;
  FsiStepReport step_two_way(double h, PhaseTimes& phases);

  solid::SolidWorld m_world;
  std::optional<fluid::FluidSimulation> m_fluid;
  std::optional<fluid::GridFluid> m_grid;
  GridPressureForces m_grid_forces = GridPressureForces::Consistent;
  GridForceCache m_grid_cache;  ///< the J of the grid the last two-way step committed
  std::optional<RemeshPolicy> m_policy;
  std::optional<CoupledStepper> m_stepper;
  MeshObserver m_observer;
  bool m_started = false;
};

}  // namespace tetfsi::coupling
