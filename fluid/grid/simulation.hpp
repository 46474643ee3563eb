#pragma once
/// @file grid/simulation.hpp
/// The fluid on the MAC grid, one step at a time, with the same seam as the tet fluid
/// (tet/simulation.hpp): predict (advection, forces, sources, boundary values → v*), a projection
/// (its own, or a coupled solve), commit. Solids are given by their surfaces at t + h and
/// their surface velocities (one-way here).
///
/// Physics as on the tet mesh (FluidParams): smoke density and temperature, Boussinesq
/// buoyancy [Fedkiw01, Eq. (8)] averaged from the cells to each face, decay, volume sources,
/// Inflow patches (speed, and the cells next to them take the patch's smoke and
/// temperature), Open patches' pressures, and liquids' hydrostatic split p = p_dyn + ρ g·x.
/// Vorticity confinement [Fedkiw01, Eq. (11)] on the cell-centred velocity (central
/// differences, one-sided next to solids). Regions sealed by Solid faces take
/// `enclosed_density` (grid_cell_density).
#include <functional>
#include <memory>
#include <vector>

#include "core/linear_solver.hpp"
#include "core/timer.hpp"
#include "fluid/frame.hpp"
#include "fluid/grid/grid.hpp"
#include "fluid/grid/liquid.hpp"
#include "fluid/params.hpp"
#include "fluid/step.hpp"

namespace tetfsi::fluid {

struct GridState {
  VecX u;                     ///< #F face velocities along +e_a (m/s)
  VecX p;                     ///< #C total pressure at cell centres (Pa; 0 in solid cells)
  VecX density;               ///< #C smoke density (kg/m³)
  VecX temperature;           ///< #C (K)
  LiquidParticles particles;  ///< a liquid with a free surface (empty without)
};

/// The grid's part of a step up to its pressure: v* with every prescribed face set.
struct GridPrediction {
  GridCells cells;
  double h = 0.0;
  VecX u_star;
  VecX density, temperature;
  VecX p_open;  ///< #F dynamic pressure on Open faces (Pa)
  VecX rho;     ///< #C fluid density per cell (grid_cell_density)
  Index traces_clamped = 0;
  LiquidParticles particles;  ///< a free surface: the particles moved to t + h
  VecX u_old;                 ///< a free surface: #F the particles' velocity on the faces
  std::vector<std::uint8_t> particle_faces;  ///< a free surface: #F, 1 where particles reached
  Index particles_added = 0, particles_removed = 0;  ///< a free surface: by sources, Open faces
  double liquid_moved = 0;  ///< a free surface: the volume hold_liquid_volume took (m³)
  double liquid_advect_s = 0, liquid_surface_s = 0, liquid_p2g_s = 0;  ///< FluidStepReport's
};

/// Velocity at the cell centres (#C × 3): the mean of each axis' two faces.
MatX3 cell_velocities(const GridCells& gc, const VecX& u);
/// The fluid density of every cell (#C, kg/m³): `enclosed_density` in regions bounded only by
/// Solid faces when it is set, `density` elsewhere.
VecX grid_cell_density(const GridCells& gc, const FluidParams& p);
/// curl u per cell (#C × 3, 1/s; 0 in solid cells) of the cell-centred velocity uc: central
/// differences, one-sided next to solid cells and the box.
MatX3 grid_vorticity(const GridCells& gc, const MatX3& uc);

class GridFluid {
 public:
  /// @throws InputError for an invalid parameter (naming it) or an option the grid lacks.
  GridFluid(FluidParams params, GridSpec grid, mesh::FluidDomain domain);

  /// Start at rest around the bodies' surfaces (sources applied, hydrostatic pressure).
  void initialize(std::vector<mesh::SolidSurface> surfaces);
  /// Advect onto the grid classified around `surfaces` (at t + h), add forces and sources,
  /// set Wall 0, Inflow ±speed, Solid faces from `motions` (one per surface, its vertex
  /// velocities; empty: 0). Phases "transfer", "forces".
  GridPrediction predict(std::vector<mesh::SolidSurface> surfaces,
                         const std::vector<SolidSurfaceMotion>& motions, double h,
                         PhaseTimes& phases) const;
  /// Project pred.u_star (phases "assembly", "solve"): the face velocities and p_dyn (#C).
  std::pair<VecX, VecX> project(const GridPrediction& pred, FluidStepReport& rep,
                                PhaseTimes& phases);
  /// End the step: state, time += h; fills the report's diagnostics.
  /// @throws SolverError if u or p_dyn is not finite (the fluid is then unchanged).
  FluidStepReport commit(GridPrediction pred, VecX u, VecX p_dyn, FluidStepReport rep = {});
  /// predict, project, commit; `alongside(cells)`, if given, runs beside the projection
  /// (run_alongside: the pressure solver is serial) on the step's classified grid, which
  /// commit then makes cells().
  FluidStepReport step(std::vector<mesh::SolidSurface> surfaces,
                       const std::vector<SolidSurfaceMotion>& motions, double h, PhaseTimes& phases,
                       const std::function<void(const GridCells&)>& alongside = {});

  /// The state the next step reads as records under `prefix` (core/checkpoint.hpp): the
  /// bodies' surfaces the grid is classified around (classify_grid rebuilds the rest from
  /// them), u, p, smoke, temperature and the time.
  void save_state(CheckpointWriter& w, const std::string& prefix) const;
  /// Restore save_state's records (instead of initialize).
  /// @throws CheckpointError naming the record if the fields do not fit the grid.
  void load_state(const CheckpointReader& r, const std::string& prefix);

  /// A liquid with a free surface (FluidParams::liquid; grid/liquid.hpp).
  bool has_liquid() const;
  /// Replace the state (tests: an initial velocity). @throws InputError on a size mismatch.
  void set_state(GridState s);
  const GridState& state() const { return m_state; }
  const GridCells& cells() const { return m_cells; }
  const FluidParams& params() const { return m_params; }
  double time() const { return m_time; }
  /// Velocity at the cell centres (#C × 3, the mean of each axis' two faces).
  MatX3 cell_velocities() const;

 private:
  FluidParams m_params;
  GridSpec m_grid;
  mesh::FluidDomain m_domain;
  GridCells m_cells;
  GridState m_state;
  /// The liquid's part of predict after the classification: particles moved and emitted,
  /// the free surface, v* from the particles (phase "transfer").
  void predict_liquid(GridPrediction& pred, double h) const;
  /// Forces, sources and boundary values (phase "forces").
  GridPrediction predict_forces(GridPrediction pred, const std::vector<SolidSurfaceMotion>& motions,
                                PhaseTimes& phases) const;
  /// Rings of faces to extrapolate a velocity u into: past the farthest a particle moves in h.
  int extrapolation_layers(const VecX& u, double h) const;
  /// m³ that n liquid particles carry (each its seeding share of a cell).
  double particle_volume(Index n) const;

  std::unique_ptr<LinearSolver> m_solver;
  Vec3 m_liquid_gravity = Vec3::Zero();  ///< a free surface: gravity on the velocity
  LiquidSurfaceParams m_surface;         ///< a free surface: how φ is read from the particles
  double m_liquid_expected = 0.0;  ///< m³: the volume the particles carry (see liquid_volume_drift)
  double m_time = 0.0;
  bool m_initialized = false;
};

/// The cell fields of the fluid's current state for a frame (fluid/frame.hpp): the grid's
/// geometry, pressure, smoke, temperature, divergence, velocity and vorticity at the cell
/// centres, the solid cells and the liquid's φ (the bodies' surface arrays are left empty).
GridFrameFields grid_frame_fields(const GridFluid& g);

}  // namespace tetfsi::fluid
