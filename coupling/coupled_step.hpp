#pragma once
/// @file coupled_step.hpp
/// One two-way coupled step of the fluid and the solid bodies (DESIGN.md §2), by either
/// scheme of the paper:
///
///  - **simultaneous** [Chentanez06, §3.3]: every deformable body's linearised trapezoidal
///    system (Eq. (4)) is assembled at dⁿ; the fluid mesh is rebuilt around the predicted
///    surfaces x* = X + dⁿ + h uⁿ (kinematic bodies at tⁿ⁺¹); the fluid is advected onto it
///    and accelerated to v*; then uⁿ⁺¹ and pⁿ⁺¹ come from one solve (coupled_system.hpp),
///    the face velocities from Eq. (8), dⁿ⁺¹ from Eq. (5), then floor/obstacle collisions;
///  - **splitting** (the paper's baseline, §4, Fig. 6): each body takes its trapezoidal step
///    with the fluid's nodal forces of the previous step held fixed, then the fluid mesh is
///    rebuilt around the bodies at tⁿ⁺¹ and the fluid projected with the bodies' velocities
///    held fixed. Nothing stabilises it: with a light structure in a heavy fluid it diverges
///    (the added-mass instability), which is what it is there to show. Closed regions get
///    the usual non-physical fix (their net flux is removed, fluid::project()).
///
///  - **bfgs**, **modified_newton**, **newton** [BatheSonnad80]: the fully nonlinear
///    trapezoidal rule of every deformable body (solid/nonlinear_trapezoid.hpp) with the
///    fluid's nodal forces in its out-of-balance force, iterated to equilibrium
///    (core/equilibrium.hpp, tolerances from SolidWorld::equilibrium). The mesh is built
///    around x* as for simultaneous; each residual evaluation projects the fluid on it with
///    the bodies' Solid faces moving at the iterate's velocities (a fluid-only solve) and
///    returns the pressure forces. bfgs and modified_newton start from the seed's Eq. (15):
///    the bodies' own (h/4) K̂ = M/h + C/2 + (h/4) K', no fluid in it — the fluid's added
///    mass is learnt by the BFGS updates (modified Newton never learns it: with more added
///    mass than body mass it cannot converge). newton re-forms the bodies' tangent every
///    iteration and solves for the increment with the fluid in the matrix (the coupled
///    system of coupled_system.hpp on the increment), so it is the simultaneous scheme
///    iterated on the solid's nonlinearity. The fluid-only solution is affine in the face
///    velocities: a point in the affine span of solved points (every line-search trial) is
///    combined from them instead of solved, so BFGS costs one fluid solve per iteration.
///    Fluid regions sealed by a deformable body (no Open face) are rejected: a fluid-only
///    projection cannot give them a volume.
///
/// Kinematic bodies follow their motion in every scheme and are prescribed in the solve.
#include <functional>
#include <string>
#include <vector>

#include "core/equilibrium.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"
#include "fluid/simulation.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

enum class Scheme { Simultaneous, Splitting, Bfgs, ModifiedNewton, Newton };
/// "simultaneous" | "splitting" | "bfgs" | "modified_newton" | "newton".
/// @throws InputError naming the value and the valid ones.
Scheme parse_scheme(const std::string& name);
const char* to_string(Scheme s);
/// bfgs, modified_newton, newton: the schemes that iterate to equilibrium.
bool is_iterated(Scheme s);

struct CouplingParams {
  Scheme scheme = Scheme::Simultaneous;
  CoupledOptions solve;
};

/// A body's boundary as the fluid mesh sees it: its boundary triangles in a compact
/// numbering of the nodes they use (mesh::SolidSurface's vertex numbering).
struct BodySurface {
  VecXi nodes;       ///< body node of each compact surface vertex
  MatX3i triangles;  ///< boundary triangles in compact numbering
};
BodySurface body_surface(const solid::SolidBody& body);

/// Builds the fluid mesh around the bodies' surfaces at the given node positions (one
/// #n × 3 matrix per body, every node of the body). @throws MeshError.
using MeshBuilder = std::function<mesh::TetMesh(const std::vector<MatX3>& positions)>;

struct CoupledStepReport {
  Scheme scheme = Scheme::Simultaneous;
  CoupledReport solve;  ///< the coupled (or, splitting, the fluid-only) solve
  fluid::FluidStepReport fluid;
  int solid_iterations = 0;    ///< splitting: the bodies' own solves
  /// Iterated schemes: the equilibrium iteration (iterations = the seed's Table I count).
  EquilibriumReport equilibrium;
  int fluid_solves = 0;  ///< iterated schemes: fluid solves (residual evaluations + newton's)
  Index contacts = 0;          ///< nodes in contact with obstacles after the step
  bool predicted_mesh = true;  ///< simultaneous: the mesh was built around x* (else around xⁿ)
  double solid_kinetic_energy = 0.0, elastic_energy = 0.0;  ///< after the step (J)
  /// fluid kinetic + solid kinetic + elastic (J), after the step
  double total_energy() const {
    return fluid.kinetic_energy + solid_kinetic_energy + elastic_energy;
  }
};

class CoupledStepper {
 public:
  CoupledStepper(CouplingParams params, const solid::SolidWorld& world);

  /// Advance the world and the fluid by h together. The fluid must be initialised on a mesh
  /// of the bodies at tⁿ (of their surfaces, body_surface numbering). Phases: remesh (the
  /// builder's), transfer, forces, coupled_assembly, coupled_solve, solid (splitting: the
  /// bodies' solves), update.
  /// @throws SolverError if a solve fails or the state becomes non-finite; MeshError from
  ///   the builder. The world and the fluid are then left at tⁿ.
  CoupledStepReport step(solid::SolidWorld& world, fluid::FluidSimulation& fluid,
                         const MeshBuilder& build, double h, PhaseTimes& phases);

  const CouplingParams& params() const { return m_params; }
  const std::vector<BodySurface>& surfaces() const { return m_surfaces; }
  /// Enclosed volumes' targets (coupled_system.hpp), kept across steps.
  const VolumeTargets& volume_targets() const { return m_targets; }

 private:
  CouplingParams m_params;
  std::vector<BodySurface> m_surfaces;
  VolumeTargets m_targets;
  std::vector<VecX> m_held_force;  ///< splitting: the fluid's nodal forces of the last step
  bool m_have_force = false;
  EquilibriumHistory m_history;  ///< iterated schemes: Eq. (12)'s largest force, kept matrix

  /// The iterated schemes' part of step(): returns the fluid solution at the converged
  /// velocities and advances the bodies. @throws SolverError if the iteration fails.
  CoupledSolution step_iterated(solid::SolidWorld& world, fluid::FluidPrediction& pred,
                                const fluid::FluidParams& params,
                                const std::vector<BodyInterface>& ifaces, double h,
                                PhaseTimes& phases, CoupledStepReport& rep);
};

}  // namespace tetfsi::coupling
