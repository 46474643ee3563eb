#pragma once
/// @file tet_fluid.hpp
/// The tet fluid behind the coupling schemes' seam (fluid_seam.hpp): the mesh rebuilt around
/// the bodies by a MeshBuilder, fluid::FluidSimulation's predict and commit, the interface
/// operators of the step's mesh and solve_coupled; and the tet fluid of a simulation
/// (TetSimFluid, sim_fluid.hpp).
#include <functional>
#include <memory>
#include <vector>

#include "coupling/fluid_seam.hpp"
#include "coupling/sim_fluid.hpp"
#include "fluid/tet/interface.hpp"
#include "fluid/tet/simulation.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::coupling {

/// Builds the fluid mesh around the bodies' surfaces at the given node positions (one
/// #n × 3 matrix per body, every node of the body). @throws MeshError.
using MeshBuilder = std::function<mesh::TetMesh(const std::vector<MatX3>& positions)>;

/// The tet fluid's prediction of a step: fluid::FluidPrediction on the step's mesh and the
/// interface operators of that mesh.
class TetPrediction final : public PredictedFluid {
 public:
  /// @param positions the bodies' node positions the mesh was built around (the interface
  ///   half cells' normals, half_cells.hpp)
  TetPrediction(fluid::FluidPrediction pred, const fluid::FluidParams& params,
                const std::vector<BodyInterface>& bodies, const std::vector<MatX3>& positions);

  const VecX& u_star() const override { return m_pred.u_star; }
  CoupledSolution solve(const std::vector<CoupledBody>& bodies, const CoupledOptions& opt,
                        const SolveVariant& variant = {}) const override;
  void apply_H(const std::vector<VecX>& u, VecX& u_face) const override {
    m_ops.apply_H(u, u_face);
  }
  void refuse_sealed_regions(const solid::SolidWorld& world, const char* scheme) const override;

  const fluid::FluidPrediction& prediction() const { return m_pred; }
  fluid::FluidPrediction& prediction() { return m_pred; }

 private:
  fluid::FluidPrediction m_pred;
  const fluid::FluidParams& m_params;
  const InterfaceOperators m_ops;
  const VecX m_half_cells;  ///< #F δ_eff of the Solid faces (CoupledInput::half_cell_lengths)
};

class TetCoupledFluid final : public CoupledFluid {
 public:
  /// @param bodies how each body's surface is numbered (body_interfaces); `fluid` must
  ///   outlive this
  TetCoupledFluid(fluid::FluidSimulation& fluid, MeshBuilder build,
                  std::vector<BodyInterface> bodies);

  const fluid::FluidParams& params() const override { return m_fluid.params(); }
  std::unique_ptr<PredictedFluid> predict(const std::vector<MatX3>& positions,
                                          const std::vector<fluid::SolidSurfaceMotion>& motions,
                                          double h, PhaseTimes& phases) override;
  fluid::FluidStepReport commit(std::unique_ptr<PredictedFluid> pred,
                                CoupledSolution& sol) override;
  std::vector<VecX> current_forces(const std::vector<BodyInterface>& bodies) const override;

 private:
  fluid::FluidSimulation& m_fluid;
  MeshBuilder m_build;
  std::vector<BodyInterface> m_bodies;
};

class TetSimFluid final : public SimFluid {
 public:
  /// @param policy builds the meshes around the bodies (must outlive this)
  TetSimFluid(const fluid::FluidParams& params, const RemeshPolicy& policy);

  const char* kind() const override { return "tet"; }
  bool started() const override { return m_started; }
  void start(const solid::SolidWorld& world, PhaseTimes& phases) override;
  void rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) override;
  FluidStepAlone step_alone(const solid::SolidWorld& world, double h, PhaseTimes& phases,
                            PhaseTimes& fluid_phases) override;
  std::unique_ptr<CoupledFluid> coupled(std::vector<BodyInterface> bodies,
                                        PhaseTimes& phases) override;
  double time() const override { return m_fluid.time(); }
  Index cells() const override { return m_fluid.mesh().num_tets(); }
  bool builds_meshes() const override { return true; }
  void set_mesh_observer(MeshObserver observer) override { m_observer = std::move(observer); }
  std::vector<VecX> body_forces(const solid::SolidWorld& world) const override;
  fluid::FluidFrame frame(const solid::SolidWorld& world) const override;
  std::string start_summary(double seconds) const override;
  /// The fluid's records under prefix + "fluid/".
  void save_state(CheckpointWriter& w, const std::string& prefix) const override;
  void load_state(const CheckpointReader& r, const std::string& prefix) override;

  /// The tet fluid itself (tests, benchmarks).
  fluid::FluidSimulation& simulation() { return m_fluid; }
  const fluid::FluidSimulation& simulation() const { return m_fluid; }

 private:
  /// The policy's mesh around the bodies at `positions` (refined as the fluid asks once it
  /// has started), timed as the remesh phase, observed.
  mesh::TetMesh build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases);

  fluid::FluidSimulation m_fluid;
  const RemeshPolicy& m_policy;
  MeshObserver m_observer;
  bool m_started = false;
};

/// The tet fluid behind `f` (tests, benchmarks), nullptr if `f` is another discretisation.
inline fluid::FluidSimulation* tet_fluid(SimFluid* f) {
  auto* t = dynamic_cast<TetSimFluid*>(f);
  return t ? &t->simulation() : nullptr;
}
inline const fluid::FluidSimulation* tet_fluid(const SimFluid* f) {
  auto* t = dynamic_cast<const TetSimFluid*>(f);
  return t ? &t->simulation() : nullptr;
}

}  // namespace tetfsi::coupling
