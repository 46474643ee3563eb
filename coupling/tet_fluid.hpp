#pragma once
/// @file tet_fluid.hpp
/// The tet fluid behind the coupling schemes' seam (fluid_seam.hpp): the mesh rebuilt around
/// the bodies by a MeshBuilder, fluid::FluidSimulation's predict and commit, the interface
/// operators of the step's mesh and solve_coupled.
#include <functional>
#include <memory>
#include <vector>

#include "coupling/fluid_seam.hpp"
#include "fluid/interface.hpp"
#include "fluid/simulation.hpp"
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
  /// @param bodies how each body's surface is numbered (body_interfaces); `fluid` and
  ///   `build` must outlive this
  TetCoupledFluid(fluid::FluidSimulation& fluid, const MeshBuilder& build,
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
  const MeshBuilder& m_build;
  std::vector<BodyInterface> m_bodies;
};

}  // namespace tetfsi::coupling
