#pragma once
/// @file grid_fluid.hpp
/// The grid fluid of a simulation (sim_fluid.hpp): fluid::GridFluid on the MAC grid, its
/// cells classified around the bodies' surfaces every step, GridCoupledFluid for the coupling
/// schemes, and the pressure-force matrices of the grid it last committed (GridForceCache),
/// which the forces on the bodies (the output's, time splitting's first step) read instead of
/// rebuilding them.
#include <memory>
#include <string>
#include <vector>

#include "coupling/grid_coupled.hpp"
#include "coupling/sim_fluid.hpp"
#include "fluid/grid/simulation.hpp"

namespace tetfsi::coupling {

class GridSimFluid final : public SimFluid {
 public:
  /// @param policy the bodies' surfaces, names and the fluid box (must outlive this)
  GridSimFluid(const fluid::FluidParams& params, const GridSetup& grid, const RemeshPolicy& policy);

  const char* kind() const override { return "grid"; }
  bool started() const override { return m_started; }
  void start(const solid::SolidWorld& world, PhaseTimes& phases) override;
  void rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) override;
  FluidStepAlone step_alone(const solid::SolidWorld& world, double h, PhaseTimes& phases,
                            PhaseTimes& fluid_phases) override;
  std::unique_ptr<CoupledFluid> coupled(std::vector<BodyInterface> bodies,
                                        PhaseTimes& phases) override;
  double time() const override { return m_grid.time(); }
  Index cells() const override;
  bool builds_meshes() const override { return false; }
  void set_mesh_observer(MeshObserver) override {}
  std::vector<VecX> body_forces(const solid::SolidWorld& world) const override;
  fluid::FluidFrame frame(const solid::SolidWorld& world) const override;
  std::string start_summary(double seconds) const override;
  /// The grid's records under prefix + "grid/", then the force cache's under
  /// prefix + "grid/cache/".
  void save_state(CheckpointWriter& w, const std::string& prefix) const override;
  void load_state(const CheckpointReader& r, const std::string& prefix) override;

  /// The grid fluid itself (tests, benchmarks).
  fluid::GridFluid& grid() { return m_grid; }
  const fluid::GridFluid& grid() const { return m_grid; }
  /// The pressure forces' form of the scene (fluid.grid.pressure_forces).
  GridPressureForces forces_form() const { return m_forces; }

 private:
  fluid::GridFluid m_grid;
  GridPressureForces m_forces;
  const RemeshPolicy& m_policy;
  GridForceCache m_cache;  ///< the J of the grid the last step committed
  bool m_started = false;
};

/// The grid fluid behind `f` (tests, benchmarks), nullptr if `f` is another discretisation.
inline fluid::GridFluid* grid_fluid(SimFluid* f) {
  auto* g = dynamic_cast<GridSimFluid*>(f);
  return g ? &g->grid() : nullptr;
}
inline const fluid::GridFluid* grid_fluid(const SimFluid* f) {
  auto* g = dynamic_cast<const GridSimFluid*>(f);
  return g ? &g->grid() : nullptr;
}

}  // namespace tetfsi::coupling
