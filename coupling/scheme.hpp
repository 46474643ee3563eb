#pragma once
/// @file scheme.hpp
/// A coupling scheme: one two-way step of the fluid and the solid bodies
/// (docs/dev/architecture.md). Every scheme is a part behind the same interface, in its own file:
///
///  - **simultaneous** (scheme_simultaneous.cpp) [Chentanez06, §3.3]: every deformable body's
///    linearised trapezoidal system (Eq. (4)) is assembled at dⁿ; the fluid mesh is rebuilt
///    around the predicted surfaces x* = X + dⁿ + h uⁿ (kinematic bodies at tⁿ⁺¹); the fluid
///    is advected onto it and accelerated to v*; then uⁿ⁺¹ and pⁿ⁺¹ come from one solve
///    (coupled_system.hpp), the face velocities from Eq. (8), dⁿ⁺¹ from Eq. (5), then
///    obstacle collisions; floors are unilateral velocity constraints of the solve, solved
///    again until their active set settles (solid/floor_contact.hpp);
///  - **splitting** (scheme_splitting.cpp; the paper's baseline, §4, Fig. 6): each body takes
///    its trapezoidal step with the fluid's nodal forces of the previous step held fixed, then
///    the fluid mesh is rebuilt around the bodies at tⁿ⁺¹ and the fluid projected with the
///    bodies' velocities held fixed. Nothing stabilises it: with a light structure in a heavy
///    fluid it diverges (the added-mass instability), which is what it is there to show.
///  - **bfgs**, **modified_newton**, **newton** (scheme_iterated.cpp) [BatheSonnad80]: the
///    fully nonlinear trapezoidal rule of every deformable body with the fluid's nodal forces
///    in its out-of-balance force, iterated to equilibrium (core/equilibrium.hpp); see that
///    file.
///
/// The fluid is seen through its seam (fluid_seam.hpp): predict around given body positions,
/// the step's coupled solve and H, commit — the tet fluid and the grid fluid alike.
/// Kinematic bodies follow their motion in every scheme and are prescribed in the solve.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/enum_names.hpp"
#include "core/equilibrium.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"
#include "coupling/fluid_seam.hpp"
#include "fluid/tet/simulation.hpp"
#include "mesh/remesh.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

enum class Scheme { Simultaneous, Splitting, Bfgs, ModifiedNewton, Newton };
inline constexpr EnumNames<Scheme, 5> k_scheme_names{"coupling scheme",
                                                     {{{Scheme::Simultaneous, "simultaneous"},
                                                       {Scheme::Splitting, "splitting"},
                                                       {Scheme::Bfgs, "bfgs"},
                                                       {Scheme::ModifiedNewton, "modified_newton"},
                                                       {Scheme::Newton, "newton"}}}};
/// "simultaneous" | "splitting" | "bfgs" | "modified_newton" | "newton" (k_scheme_names).
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

/// The bodies' surfaces at `positions` (one #n × 3 per body, every node) as the fluid sees
/// them: compact vertices, mesh::SolidSurface::body = the body's index.
/// @throws MeshError naming the body (names[b]) and the node if a body is not strictly inside
///   the fluid box.
std::vector<mesh::SolidSurface> place_surfaces(const mesh::FluidDomain& domain,
                                               const std::vector<BodySurface>& surfaces,
                                               const std::vector<std::string>& names,
                                               const std::vector<MatX3>& positions);

struct CoupledStepReport {
  Scheme scheme = Scheme::Simultaneous;
  CoupledReport solve;  ///< the coupled (or, splitting, the fluid-only) solve
  fluid::FluidStepReport fluid;
  int solid_iterations = 0;  ///< splitting: the bodies' own solves
  /// Iterated schemes: the equilibrium iteration (iterations = the seed's Table I count).
  EquilibriumReport equilibrium;
  int fluid_solves = 0;  ///< iterated schemes: fluid solves (residual evaluations + newton's)
  Index contacts = 0;    ///< nodes in contact with obstacles after the step
  /// Floors' active set (solid/floor_contact.hpp): the most solves of one body's (splitting)
  /// or of the coupled system (simultaneous) in the step; 1 if the set held at once.
  int contact_rounds = 0;
  bool contacts_settled = true;  ///< the active set settled within its max_rounds
  /// Contact between bodies (solid::SolidWorld::contact enabled): the step's set and figures.
  std::optional<solid::ContactReport> body_contact;
  bool predicted_mesh = true;  ///< the mesh was built around x* (else around xⁿ)
  double solid_kinetic_energy = 0.0, elastic_energy = 0.0;  ///< after the step (J)
  /// Σ_b f_fluid,b · (dⁿ⁺¹ − dⁿ): the work of the fluid's forces of the solution on the free
  /// bodies over the step (J; the divergence check's budget, run/divergence.hpp)
  double fluid_work = 0.0;
  /// fluid kinetic + solid kinetic + elastic (J), after the step
  double total_energy() const {
    return fluid.kinetic_energy + solid_kinetic_energy + elastic_energy;
  }
};

/// What a scheme steps. The fluid must be around the bodies at tⁿ (their surfaces,
/// body_surface numbering).
struct StepContext {
  solid::SolidWorld& world;
  CoupledFluid& fluid;
  const std::vector<BodySurface>& surfaces;  ///< per body
  double h = 0.0;
  PhaseTimes& phases;
};

class CouplingScheme {
 public:
  virtual ~CouplingScheme() = default;
  virtual Scheme kind() const = 0;
  /// Advance the bodies to tⁿ⁺¹ and predict the fluid (pred); return the fluid's solution
  /// (face velocities, dynamic pressure) for CoupledFluid::commit. Fills rep's
  /// scheme-specific figures. The caller (CoupledStepper) restores the world on an exception
  /// and commits the fluid.
  /// @throws SolverError, MeshError.
  virtual CoupledSolution advance(StepContext& ctx, std::unique_ptr<PredictedFluid>& pred,
                                  CoupledStepReport& rep) = 0;
  /// What the scheme carries from step to step, as checkpoint records under `prefix`
  /// (simultaneous: the enclosed regions' target volumes; splitting: the held fluid forces;
  /// iterated: the equilibrium history with the kept matrix and BFGS updates).
  virtual void save_state(CheckpointWriter& w, const std::string& prefix) const = 0;
  /// @throws CheckpointError naming the record if it does not fit.
  virtual void load_state(const CheckpointReader& r, const std::string& prefix) = 0;
};

/// The scheme of `params.scheme`.
std::unique_ptr<CouplingScheme> make_scheme(const CouplingParams& params);

// ---- shared by the schemes (scheme.cpp) ----------------------------------------------------

/// Each body's nodes at X + disp(b).
std::vector<MatX3> node_positions(const solid::SolidWorld& world,
                                  const std::function<MatX3(Index)>& disp);
/// The bodies' surface velocities at tⁿ (the fluid's boundary values before the solve).
std::vector<fluid::SolidSurfaceMotion> surface_motion(const solid::SolidWorld& world,
                                                      const std::vector<BodySurface>& surfaces);
/// How the mesh's Solid faces refer to each body (fluid::InterfaceOperators' input).
std::vector<BodyInterface> body_interfaces(const solid::SolidWorld& world,
                                           const std::vector<BodySurface>& surfaces);
/// The fluid predicted around x* = X + dⁿ + h uⁿ (kinematic bodies at tⁿ⁺¹: call after
/// moving them), or around xⁿ if that fails (a body predicted out of the box;
/// rep.predicted_mesh = false); the Solid faces at the bodies' velocities at tⁿ.
std::unique_ptr<PredictedFluid> predict_around_predicted(StepContext& ctx, CoupledStepReport& rep);
/// The fluid predicted around the bodies as they are (time splitting, after the bodies' step).
std::unique_ptr<PredictedFluid> predict_around_current(StepContext& ctx);
/// The solve's assembly and solve seconds into the phases coupled_assembly, coupled_solve.
void add_solve_phases(PhaseTimes& phases, const CoupledReport& r);
/// @throws SolverError naming the body if its state is not finite.
void check_finite(const solid::SolidBody& body, double h);

}  // namespace tetfsi::coupling
