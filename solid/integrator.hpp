#pragma once
/// @file integrator.hpp
/// The linearised implicit trapezoidal rule of [Chentanez06, Eqs. (4)–(5), (9)–(18)].
#include "core/enum_names.hpp"
#include "core/types.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

/// A u^{n+1} = b for one body (the fluid-free form of [Chentanez06, Eq. (4)]).
/// The coupling later adds −J p to this very system.
///
///   A = M/h + C + (h/2) K',   C = αM + βK',
///   b = M uⁿ/h − (h/2) K' uⁿ − K(dⁿ) + f_e,
/// with K, K' evaluated at dⁿ and M the lumped mass (diagonal, 3#V).
/// Fixed DOFs are eliminated symmetrically: their rows and columns of A are zero except a
/// diagonal entry m_i/h, and b is zero there, so u stays 0 on them and A stays symmetric.
///
/// Energy behaviour (measured in tests/solid/test_integrator.cpp): on a linear system
/// Eqs. (4)–(5) read M(uⁿ⁺¹ − uⁿ)/h = −K dⁿ⁺¹, i.e. Newmark with γ = 1 (the paper's β = 1/2,
/// γ = 1 of Eqs. (10)–(11)). Hence E = ½uᵀMu + ½dᵀKd obeys
///   Eⁿ⁺¹ − Eⁿ = −½ (dⁿ⁺¹ − dⁿ)ᵀ K (dⁿ⁺¹ − dⁿ) ≤ 0:
/// unconditionally stable, never gains energy, but dissipates at first order in h — a
/// numerical damping ratio ≈ ωh/4 per mode (|λ| = (1 + (ωh)²/2)^(−1/2) per step), added to
/// the Rayleigh ζ = α/(2ω) + βω/2. Unresolved modes (ωh ≫ 1) are damped out within a step.
///
/// `Trapezoid::Midpoint` is the opt-in alternative: K evaluated at the midpoint
/// (dⁿ + dⁿ⁺¹)/2 instead of at dⁿ⁺¹, i.e. K' weighted h/4 instead of h/2 in A and b
/// (Newmark γ = 1/2, β = 1/4, "average acceleration"). On a linear undamped system it
/// conserves E exactly (docs/dev/validation_plan.md "Solid": no amplitude decay); it does not damp
/// unresolved modes. Both keep the form A uⁿ⁺¹ − J pⁿ⁺¹ = b the coupling needs.
enum class Trapezoid {
  Paper,     ///< [Chentanez06, Eqs. (4), (15)–(18)]: K(dⁿ⁺¹) linearised, weight h/2
  Midpoint,  ///< K((dⁿ + dⁿ⁺¹)/2) linearised, weight h/4: energy-conserving on linear systems
};

inline constexpr EnumNames<Trapezoid, 2> k_trapezoid_names{
    "trapezoid variant", {{{Trapezoid::Paper, "paper"}, {Trapezoid::Midpoint, "midpoint"}}}};
/// "paper" / "midpoint" (scene key solid.trapezoid). @throws InputError naming the value.
Trapezoid parse_trapezoid(const std::string& name);
const char* to_string(Trapezoid t);

struct TrapezoidalSystem {
  SparseMatrix A;  ///< 3#V × 3#V, symmetric
  VecX b;          ///< 3#V
};

/// Assemble A and b at the body's current state.
/// @param f_e external forces (3#V, N), e.g. body.external_forces(gravity)
TrapezoidalSystem assemble_trapezoidal(const SolidBody& body, double h, const VecX& f_e,
                                       Trapezoid variant = Trapezoid::Paper);

/// dⁿ⁺¹ = dⁿ + h/2 (uⁿ + uⁿ⁺¹), then u ← uⁿ⁺¹ [Chentanez06, Eq. (5)].
/// @param u_new 3#V velocities (fixed DOFs must be 0)
void advance_trapezoidal(SolidBody& body, const VecX& u_new, double h);

/// x += h/2 (uⁿ + uⁿ⁺¹), elementwise (flat, 3n): Eq. (5)'s one site [Chentanez06, Eq. (5)],
/// for displacements (advance_trapezoidal) and for positions (the coupled solve's enclosed
/// volumes).
void trapezoidal_displace(Eigen::Ref<VecX> x, const VecX& u_old, const VecX& u_new, double h);

}  // namespace tetfsi::solid
