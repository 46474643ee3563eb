#pragma once
/// @file fluid_seam.hpp
/// The fluid as every coupling scheme sees it, whatever its discretisation
/// (docs/dev/architecture.md): a CoupledFluid predicts the step around the bodies at given
/// positions (the tet fluid rebuilds its mesh there, the grid fluid reclassifies its cells), the
/// PredictedFluid of the step solves the coupled system [Chentanez06, Eq. (7)] with the bodies' Eq.
/// (4) and applies H, and the CoupledFluid commits the solution. Two implementations:
///  - TetCoupledFluid (tet_fluid.cpp): fluid::FluidSimulation on the dynamic tet mesh,
///    fluid::InterfaceOperators, solve_coupled (coupled_system.hpp);
///  - GridCoupledFluid (grid_coupled.hpp): fluid::GridFluid on the MAC grid,
///    fluid::GridInterface, solve_grid_coupled.
#include <memory>
#include <string>
#include <vector>

#include "core/timer.hpp"
#include "core/types.hpp"
#include "coupling/coupled_system.hpp"
#include "fluid/params.hpp"
#include "fluid/tet/simulation.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

/// Variations of one step's solve the schemes need.
struct SolveVariant {
  /// Replaces the prediction's v* (the iterated schemes' Solid faces at n·(H x)).
  const VecX* u_star = nullptr;
  /// v* = 0, no open pressure, no gravity: the coupled system on an increment (newton).
  bool homogeneous = false;
  /// The enclosed regions' targets (null: no volume correction).
  VolumeTargets* targets = nullptr;
};

/// The fluid's prediction of one step (v* on the step's mesh or grid) with its interface
/// operators.
class PredictedFluid {
 public:
  virtual ~PredictedFluid() = default;
  /// v* (#F), every prescribed face set (Solid faces at the bodies' surface velocities at tⁿ).
  virtual const VecX& u_star() const = 0;
  /// The coupled solve with `bodies` (one per body; a body that is not free keeps its faces'
  /// v*). @throws SolverError, InputError as solve_coupled.
  virtual CoupledSolution solve(const std::vector<CoupledBody>& bodies, const CoupledOptions& opt,
                                const SolveVariant& variant = {}) const = 0;
  /// u_face[f] = (H u)_f on the Solid faces of every body b whose u[b] is not empty.
  virtual void apply_H(const std::vector<VecX>& u, VecX& u_face) const = 0;
  /// @throws InputError naming the body and `scheme` if a fluid region without an Open face
  ///   is bounded by a deformable body (a fluid-only projection cannot keep its volume).
  virtual void refuse_sealed_regions(const solid::SolidWorld& world, const char* scheme) const = 0;
};

class CoupledFluid {
 public:
  virtual ~CoupledFluid() = default;
  virtual const fluid::FluidParams& params() const = 0;
  /// Predict the step onto the fluid around the bodies at `positions` (one #n × 3 per body,
  /// every node), the Solid faces at `motions` (the bodies' surface velocities). Phases
  /// remesh (tet), transfer, forces. @throws MeshError if the bodies cannot be placed there.
  virtual std::unique_ptr<PredictedFluid> predict(
      const std::vector<MatX3>& positions, const std::vector<fluid::SolidSurfaceMotion>& motions,
      double h, PhaseTimes& phases) = 0;
  /// End the step from `pred` with the solution's face velocities and dynamic pressure.
  virtual fluid::FluidStepReport commit(std::unique_ptr<PredictedFluid> pred,
                                        CoupledSolution& sol) = 0;
  /// The fluid's nodal forces on every body (3n each) of its current pressure: time
  /// splitting's forces for its first step.
  virtual std::vector<VecX> current_forces(const std::vector<BodyInterface>& bodies) const = 0;
};

}  // namespace tetfsi::coupling
