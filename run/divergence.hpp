#pragma once
/// The run's divergence check: a step whose bodies hold far more energy than gravity, the
/// loads and the fluid can have supplied, or whose fluid moves far faster than anything in the
/// scene can drive it, has diverged (an unstable integrator or coupling at too large a step),
/// even though every value is still finite. run_dynamic stops the run there.

#include <optional>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/types.hpp"

namespace tetfsi::solid {
class SolidWorld;
}
namespace tetfsi::coupling {
struct FsiStepReport;
}

namespace tetfsi::app {

struct Scene;

/// What a scene can drive: the fluid's speed scale and the buoyancy of immersed bodies.
struct DivergenceScales {
  /// Fluid scenes: max(inflow speeds, sqrt(2 a L)) with a = |g| + |g_fluid| + the largest
  /// buoyancy acceleration the sources and patches can cause, L the fluid box's diagonal
  /// (m/s); 0 without a fluid.
  double fluid_speed = 0.0;
  double fluid_density = 0.0;  ///< the densest fluid (kg/m³) around or inside the bodies
  Vec3 gravity = Vec3::Zero();
};

DivergenceScales divergence_scales(const Scene& scene);

/// Tracks the energy budget of the free bodies from the start of a run:
///   E_kin + E_el ≤ E_kin,0 + E_el,0 + max(0, V_g,0 − V_g) + W_loads⁺ + W_fluid⁺ + W_buoy,
/// W_loads⁺ the positive work of the scene's loads per step (f · Δd), W_fluid⁺ the positive
/// work of the fluid's dynamic pressure (two-way: the coupled solve's pᵀJᵀuⁿ⁺¹ h), W_buoy
/// the most the displaced fluid's weight can do (ρ_f V |g| |Δz|). A consistent integrator
/// keeps the energy below the budget (the implicit ones dissipate); a step beyond
/// `factor` × budget + floor (floor = 1e-4 Σ E V, the strain energy of about 1 % strain)
/// has diverged. The fluid: its largest face speed beyond `factor`² × the largest of the
/// scene's speed scale, the bodies' peak node speed so far and √(2 budget / their mass).
class DivergenceGuard {
 public:
  static constexpr double kFactor = 10.0;

  DivergenceGuard(const solid::SolidWorld& world, const DivergenceScales& scales);
  /// Call before each step (saves the displacements the loads' work is measured from).
  void before_step(const solid::SolidWorld& world);
  /// Call after each step: the one-line reason it diverged, or nothing.
  std::optional<std::string> after_step(const solid::SolidWorld& world,
                                        const coupling::FsiStepReport& rep);

  double budget() const;  ///< the current budget (J)

  /// What the guard carries between steps (the start's energies and centroids, the work and
  /// the peak speed so far), as records under "run/guard/", and back into a guard built for
  /// the same world (`tetfsi resume`: the budget is the whole run's, not the resumed part's).
  /// @throws CheckpointError naming the record if one is missing or does not fit the world.
  void save_state(CheckpointWriter& w) const;
  void load_state(const CheckpointReader& r);

 private:
  double mechanical_energy(const solid::SolidWorld& world) const;
  double gravity_potential(const solid::SolidWorld& world) const;
  double buoyancy_work(const solid::SolidWorld& world) const;
  std::optional<std::string> check_fluid(const coupling::FsiStepReport& rep) const;

  DivergenceScales m_scales;
  double m_energy0 = 0.0, m_potential0 = 0.0, m_floor = 0.0;
  double m_work = 0.0;     ///< W_loads⁺ + W_fluid⁺ so far
  double m_release = 0.0;  ///< max(0, V_g,0 − V_g) of the last step
  double m_buoyancy = 0.0;
  double m_body_speed = 0.0;      ///< the bodies' largest node speed so far (the fluid keeps it)
  double m_mass = 0.0;            ///< of the deforming bodies
  std::vector<Vec3> m_centroid0;  ///< mass centroids at the start
  std::vector<MatX3> m_before;    ///< displacements before the step
};

}  // namespace tetfsi::app
