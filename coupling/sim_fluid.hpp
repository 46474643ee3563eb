#pragma once
/// @file sim_fluid.hpp
/// The fluid of a simulation behind one interface, whatever its discretisation: FsiSimulation
/// (simulation.hpp) holds one SimFluid (or none: a solid-only run) and never asks which
/// discretisation it is. A SimFluid starts around the bodies, steps alone around them
/// (one-way runs), hands the coupling schemes its CoupledFluid for a step (two-way runs,
/// fluid_seam.hpp), saves and restores its state, and gives what the output and the stats
/// read: its time, cell count, forces on the bodies and a frame (fluid/frame.hpp) as plain
/// data. Two implementations:
///  - TetSimFluid (tet_fluid.hpp): fluid::FluidSimulation on a tet mesh rebuilt around the
///    bodies every step by the RemeshPolicy, refined where the fluid asks;
///  - GridSimFluid (grid_fluid.hpp): fluid::GridFluid on the MAC grid, its cells classified
///    around the bodies' surfaces every step; it keeps the pressure-force matrices of the grid
///    it last committed (GridForceCache) for the forces of that grid.
/// docs/dev/fluid_interface.md says what a third discretisation implements.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/timer.hpp"
#include "core/types.hpp"
#include "coupling/fluid_seam.hpp"
#include "coupling/grid_coupled.hpp"
#include "coupling/scheme.hpp"
#include "fluid/frame.hpp"
#include "fluid/params.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

/// How the fluid mesh is rebuilt every step: around every body's boundary triangles
/// (body_surface) at given node positions, refined where the fluid asks for it
/// (fluid::FluidSimulation::refinement_field), inside the fluid box. Every discretisation
/// reads its bodies' surfaces, names and box here; only the tet fluid builds meshes.
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
  /// The bodies' surfaces at `positions` in the fluid box (place_surfaces).
  std::vector<mesh::SolidSurface> place(const std::vector<MatX3>& positions) const;

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

/// Called after every mesh a fluid built successfully, with the remesh's wall seconds and
/// the phases of the step (a caller's diagnostics, e.g. the mesh quality).
using MeshObserver = std::function<void(const mesh::TetMesh&, const mesh::RemeshReport&,
                                        double seconds, PhaseTimes& phases)>;

/// One step the fluid took alone (one-way runs).
struct FluidStepAlone {
  fluid::FluidStepReport report;
  double seconds = 0.0;  ///< wall seconds of the fluid's part after the remesh
};

/// The node positions of every body (X + d), in body order.
std::vector<MatX3> body_positions(const solid::SolidWorld& world);

class SimFluid {
 public:
  virtual ~SimFluid() = default;

  /// The discretisation's name in a checkpoint's "sim/kind" ("tet", "grid").
  virtual const char* kind() const = 0;
  /// start (or rebuild_at_rest, load_state) succeeded.
  virtual bool started() const = 0;
  /// Start at rest around the bodies as they are (t = 0). Phase remesh where the fluid builds
  /// a mesh. @throws MeshError, InputError (naming the bodies) if it cannot be placed there.
  virtual void start(const solid::SolidWorld& world, PhaseTimes& phases) = 0;
  /// Rebuild around the bodies as they are and restart at rest (static runs).
  virtual void rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) = 0;
  /// One-way: the bodies have stepped; step the fluid by h around them, their surfaces moving
  /// at their velocities. Phase remesh into `phases`, the fluid's own ("transfer", "forces",
  /// "assembly", "solve") into `fluid_phases`. @throws MeshError, SolverError (the fluid then
  /// keeps its last state).
  virtual FluidStepAlone step_alone(const solid::SolidWorld& world, double h, PhaseTimes& phases,
                                    PhaseTimes& fluid_phases) = 0;
  /// Two-way: the fluid as the coupling scheme steps it for one step (fluid_seam.hpp), with
  /// the bodies numbered as `bodies` (body_interfaces). It refers to this fluid; the remesh
  /// phases it times go into `phases`, which must outlive it.
  virtual std::unique_ptr<CoupledFluid> coupled(std::vector<BodyInterface> bodies,
                                                PhaseTimes& phases) = 0;

  /// The fluid's time (s) since start.
  virtual double time() const = 0;
  /// The fluid cells of the current state (the tets of the mesh; the grid's fluid cells).
  virtual Index cells() const = 0;
  /// Whether the fluid builds a tet mesh every step (shown to the mesh observer; the stats'
  /// mesh columns stay empty otherwise).
  virtual bool builds_meshes() const = 0;
  /// The observer of every mesh the fluid builds (none if it builds none).
  virtual void set_mesh_observer(MeshObserver observer) = 0;
  /// The fluid's nodal forces on each body (3n, N) of its current state (started only).
  virtual std::vector<VecX> body_forces(const solid::SolidWorld& world) const = 0;
  /// The current state as a frame (an empty one before start succeeded).
  virtual fluid::FluidFrame frame(const solid::SolidWorld& world) const = 0;
  /// What start built, in one line for `tetfsi validate` (`seconds`: how long it took).
  virtual std::string start_summary(double seconds) const = 0;

  /// Everything the next step reads, as records under `prefix` (core/checkpoint.hpp; started
  /// fluids only). A fluid of the same setup given them by load_state steps on bit for bit.
  virtual void save_state(CheckpointWriter& w, const std::string& prefix) const = 0;
  /// Restore save_state's records into a fluid just built (instead of start).
  /// @throws CheckpointError naming the record if they do not fit.
  virtual void load_state(const CheckpointReader& r, const std::string& prefix) = 0;
};

/// The fluid of `setup` (tet or grid) around the bodies of `policy`, which must outlive it.
std::unique_ptr<SimFluid> make_sim_fluid(const FluidSetup& setup, const RemeshPolicy& policy);

}  // namespace tetfsi::coupling
