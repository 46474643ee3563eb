#pragma once
/// @file simulation.hpp
/// The fluid on the dynamic tet mesh, one step at a time (docs/dev/architecture.md, one time step,
/// steps 3–6 without the coupling): transfer = semi-Lagrangian advection from the old mesh onto the
/// new one, forces and sources, boundary conditions, pressure projection [Chentanez06, Eqs.
/// (1)–(2)], [KFCO06]. Solids are kinematic here: their surface velocities are given (one-way); the
/// simultaneous coupling (coupling/) replaces the projection by the coupled solve.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/linear_solver.hpp"
#include "core/timer.hpp"
#include "core/types.hpp"
#include "fluid/frame.hpp"
#include "fluid/params.hpp"
#include "fluid/step.hpp"
#include "fluid/tet/reconstruct.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// The fluid state on one TetMesh.
struct FluidState {
  VecX u;            ///< #F normal velocity along n_f (m/s)
  VecX p;            ///< #T pressure at the circumcentres (Pa; total, incl. ρ g·x for liquids)
  VecX density;      ///< #T smoke density (kg/m³)
  VecX temperature;  ///< #T temperature (K)
  /// Zero velocity and pressure, no smoke, ambient temperature.
  static FluidState at_rest(const mesh::TetMesh& m, double ambient_temperature);
};

/// The fluid's part of a step up to its pressure (docs/dev/architecture.md, one time step, steps
/// 3–4) on the new mesh: the intermediate velocity v* with every prescribed boundary velocity set,
/// ready for a projection — FluidSimulation's own, or the simultaneous coupled solve [Chentanez06,
/// Eq. (7)], which replaces the Solid faces of deformable bodies by H uⁿ⁺¹.
struct FluidPrediction {
  mesh::TetMesh mesh;
  double h = 0.0;
  VecX u_star;       ///< #F v*: Wall 0, Inflow −speed, Solid faces n_f · Σ w_a v_a (`solids`)
  VecX density;      ///< #T smoke density after transfer, decay and sources
  VecX temperature;  ///< #T
  VecX rho;          ///< #T fluid density per cell (cell_fluid_density)
  VecX p_open;       ///< #F dynamic pressure prescribed on Open faces (Pa), 0 elsewhere
  Index traces_clamped = 0;
};

/// The fluid density of every cell (#T, kg/m³): `enclosed_density` in regions bounded only by
/// Solid faces when it is set, `density` elsewhere.
VecX cell_fluid_density(const mesh::TetMesh& m, const FluidParams& p);

/// A function "desired edge length at x" for mesh::Sizing::refine (≤ 0: no request).
using RefineField = std::function<double(const Vec3&)>;

class FluidSimulation {
 public:
  explicit FluidSimulation(FluidParams params);
  ~FluidSimulation();
  FluidSimulation(FluidSimulation&&) noexcept;
  FluidSimulation& operator=(FluidSimulation&&) noexcept;

  /// Start on `mesh` with the fluid at rest (sources applied, hydrostatic pressure for
  /// liquids).
  void initialize(mesh::TetMesh mesh);

  /// One step of length h onto `new_mesh` (built around the solids at t + h):
  ///  1. transfer: every new face centre and cell centroid traced back through the old
  ///     velocity field (RK2, clamped at walls and solids) [KFCO06, §4];
  ///  2. forces (buoyancy, vorticity confinement), decay, sources, boundary values (inflow,
  ///     Solid faces n_f · Σ_a w_a v_a from `solids`, walls 0);
  ///  3. projection: solve the pressure Poisson equation and subtract (h/ρ) G p.
  /// Phases "transfer", "forces", "assembly", "solve" are added to `phases`.
  /// @param solids one entry per body index of the mesh's Solid faces (may be empty if the
  ///   mesh has none)
  /// @throws SolverError if the pressure solve fails or the state becomes non-finite;
  ///   the simulation then keeps its previous mesh and state.
  FluidStepReport step(mesh::TetMesh new_mesh, double h,
                       const std::vector<SolidSurfaceMotion>& solids, PhaseTimes& phases);

  /// Steps 1–2 of `step` only (transfer, forces, sources, boundary values), for a projection
  /// done elsewhere (coupling/). Phases "transfer" and "forces". The simulation is unchanged.
  FluidPrediction predict(mesh::TetMesh new_mesh, double h,
                          const std::vector<SolidSurfaceMotion>& solids, PhaseTimes& phases) const;
  /// End a step from `pred` with the projected face velocities u (#F) and the dynamic
  /// pressure p_dyn (#T, Pa; the hydrostatic part ρ g·x is added here): the new mesh and
  /// state, time += h. Fills the report's diagnostics (energy, fluxes, CFL, smoke mass); the
  /// solve fields (converged, iterations, residual, divergence) are the caller's.
  /// @throws SolverError if u or p_dyn is not finite (the simulation is then unchanged).
  FluidStepReport commit(FluidPrediction pred, VecX u, VecX p_dyn);

  /// Replace the state on the current mesh (e.g. an initial velocity field; tests).
  /// @throws InputError if a size does not match the mesh or a value is not finite.
  /// The state the next step reads as records under `prefix` (core/checkpoint.hpp): the mesh
  /// (mesh::save_mesh), u, p, smoke, temperature and the time. The parameters come from the
  /// scene; the pressure solver is made afresh (it carries nothing from step to step).
  void save_state(CheckpointWriter& w, const std::string& prefix) const;
  /// Restore save_state's records (instead of initialize).
  /// @throws CheckpointError naming the record if the fields do not fit the mesh.
  void load_state(const CheckpointReader& r, const std::string& prefix);

  void set_state(FluidState s);

  const mesh::TetMesh& mesh() const;
  const FluidState& state() const;
  const FluidParams& params() const;
  /// The reconstructed velocity of the current state (params().reconstruction); it refers
  /// to the current mesh, so it is valid until the next step. Build it once when several of
  /// its fields are needed (a frame).
  VelocityField velocity_field() const;
  /// Reconstructed velocity at the cell centroids (#T × 3) and at the vertices (#V × 3).
  MatX3 cell_velocities() const;
  MatX3 vertex_velocities() const;
  /// |curl u| per cell (#T, 1/s).
  VecX vorticity_magnitude() const;
  /// The refinement the fluid asks the next remesh for (params().refine), or an empty
  /// function when refinement is off. It samples the current state on a voxel grid, so it
  /// stays valid after later steps (it does not reference the simulation).
  RefineField refinement_field() const;
  /// Time (s) since initialize.
  double time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// The fields of the fluid's current state on its mesh, for a frame (fluid/frame.hpp): one
/// velocity reconstruction for the vorticity and the cell and vertex velocities.
MeshFrameFields mesh_frame_fields(const FluidSimulation& sim);

}  // namespace tetfsi::fluid
