#pragma once
/// @file run_stats.hpp
/// The figures of a run with a fluid, kept once from the simulation's reports
/// (coupling::FsiSimulation): the stats.csv columns of the last step (FluidStepStats,
/// CoupledStepStats) and the summaries over the run (FluidSummary, CouplingSummary).
#include <optional>
#include <string>

#include "coupling/simulation.hpp"
#include "io/output.hpp"

namespace tetfsi::app {

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
  long long iterations = 0;    ///< of the coupled solves, summed
  double max_residual = 0.0;   ///< worst relative residual of any coupled solve
  int unconverged_solves = 0;  ///< coupled solves that reported converged = false
  /// Steps whose coupled solve stopped at its round-off floor above coupling.rel_tol
  /// (CoupledReport::solves_at_floor), and the largest such floor.
  int steps_at_floor = 0;
  double max_floor = 0.0;
  double max_interface_power = 0.0;  ///< max over steps of |pᵀ Jᵀ u| (W)
  /// max over steps of |pᵀ Jᵀ u − pᵀ V D1 H u| (W): 0 but for round-off unless the grid's
  /// paper J
  double max_interface_imbalance = 0.0;
  Index max_enclosed_regions = 0;  ///< most enclosed regions in one step
  double max_volume_drift = 0.0;   ///< max over steps and regions of |after − target| / target
  double enclosed_volume = 0.0;    ///< Σ of the enclosed regions' volume after the last step (m³)
  /// Steps whose mesh had to be built around the bodies at tⁿ because the predicted surfaces
  /// x* = x + h u could not be meshed (e.g. a body predicted out of the box).
  int unpredicted_meshes = 0;
  long long solid_iterations = 0;  ///< splitting: the bodies' own solves, summed
  double total_energy = 0.0;  ///< fluid kinetic + solid kinetic + elastic after the last step (J)
};

/// Keeps the figures of a fluid run. Install `mesh_observer()` on the simulation before its
/// first mesh, then call `record` after every step.
class RunRecorder {
 public:
  explicit RunRecorder(const coupling::FsiSimulation& sim);

  /// The simulation's mesh observer: the mesh columns, the quality summary (timed as the
  /// output phase) and the summary's remesh bookkeeping.
  coupling::MeshObserver mesh_observer();
  /// The fluid (and, two-way, the coupling) figures of the step `sim` has just taken.
  void record(const coupling::FsiStepReport& r, const coupling::FsiSimulation& sim);

  const FluidStepStats& stats() const { return m_stats; }
  const FluidSummary& summary() const { return m_summary; }
  /// Two-way runs: the coupling figures of the last step (unset before it) and over the run.
  const std::optional<CoupledStepStats>& coupled_stats() const { return m_coupled_stats; }
  const std::optional<CouplingSummary>& coupling_summary() const { return m_coupling_summary; }

  /// Every figure kept across steps, as records under "run/recorder/" (a checkpoint), and back
  /// into a recorder of the same kind of run (`tetfsi resume`).
  /// @throws CheckpointError naming the record if one is missing or of another type.
  void save_state(CheckpointWriter& w) const;
  void load_state(const CheckpointReader& r);

 private:
  void record_mesh(const mesh::TetMesh& m, const mesh::RemeshReport& report, double seconds,
                   PhaseTimes& phases);
  void record_fluid_step(const fluid::FluidStepReport& r, double seconds, double time);
  void record_coupled_step(const coupling::CoupledStepReport& rep, double time);

  FluidStepStats m_stats;
  FluidSummary m_summary;
  std::optional<CoupledStepStats> m_coupled_stats;
  std::optional<CouplingSummary> m_coupling_summary;
};

}  // namespace tetfsi::app
