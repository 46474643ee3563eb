#pragma once
/// @file nonlinear_trapezoid.hpp
/// The fully nonlinear implicit trapezoidal rule of [BatheSonnad80, Eqs. (1)–(7)] for one
/// body, iterated to dynamic equilibrium by full Newton, modified Newton or BFGS
/// (core/equilibrium.hpp), beside the linearised rule of integrator.hpp.
///
/// With Eqs. (3)–(5), U = d, U̇ = u, the rule reads M Ü¹ + C u¹ + K(d¹) = f_e and
///   d¹ = dⁿ + h/2 (uⁿ + u¹),   Ü¹ = 2 (u¹ − uⁿ)/h − Üⁿ.
/// Taking M Üⁿ = f_e − C uⁿ − K(dⁿ) (equilibrium at tⁿ, which the previous step met to RTOL;
/// evaluated afresh so that a step after a collision or a change of load starts
/// consistently), the out-of-balance force of Eq. (6) is 2 g(u¹) with
///
///   g(u¹) = ½ (f_s(dⁿ, uⁿ) + f_s(d¹, u¹)) − M (u¹ − uⁿ)/h,   f_s(d, u) = f_e − C u − K(d),
///
/// i.e. the trapezoidal rule on the solid's own forces, in velocity form. The unknown is u¹
/// (ΔU = h/2 Δu¹; the convergence tests are ratios, so the scale does not matter), and
///
///   −∂g/∂u¹ = M/h + C/2 + (h/4) K'(d¹) = (h/4) K̂,   K̂ = K' + (2/h) C + (4/h²) M   [Eq. (7)].
///
/// C = αM + βK'(dⁿ) (Rayleigh, at the start of the step). Fixed DOFs keep u¹ = 0: their g
/// is 0 and their rows and columns of the matrix are eliminated (diagonal m/h). The iteration
/// starts, as in the seed, from U⁽⁰⁾ = ᵗU, i.e. d¹ = dⁿ, u¹ = −uⁿ. On a linear system the
/// rule is Newmark's average acceleration (γ = ½, β = ¼): it conserves ½uᵀMu + ½dᵀKd.
///
/// The coupled iteration (coupling/coupled_step) adds the fluid's nodal forces to g.
#include <string>

#include "core/enum_names.hpp"
#include "core/equilibrium.hpp"
#include "core/types.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

/// solid.integrator: "linearized" (integrator.hpp) | "newton" | "modified_newton" | "bfgs".
enum class Integrator { Linearized, Newton, ModifiedNewton, Bfgs };
inline constexpr EnumNames<Integrator, 4> k_integrator_names{
    "solid integrator",
    {{{Integrator::Linearized, "linearized"},
      {Integrator::Newton, "newton"},
      {Integrator::ModifiedNewton, "modified_newton"},
      {Integrator::Bfgs, "bfgs"}}}};
/// @throws InputError naming the value and the valid ones.
Integrator parse_integrator(const std::string& name);
const char* to_string(Integrator i);
/// The iteration of a nonlinear integrator. @pre i != Linearized
IterationMethod iteration_method(Integrator i);

class TrapezoidalEquilibrium {
 public:
  /// @param body at tⁿ (its d, u); @param f_e external forces (3#V, N), constant over the step
  TrapezoidalEquilibrium(const SolidBody& body, double h, const VecX& f_e);

  Index size() const { return m_mass.size() * 3; }
  double h() const { return m_h; }
  /// g(u¹) (3#V, N), zero on fixed DOFs.
  VecX residual(const VecX& u1) const;
  /// (h/4) K̂ at u¹: M/h + C/2 + (h/4) K'(d¹), fixed DOFs eliminated. Symmetric.
  SparseMatrix tangent(const VecX& u1) const;
  /// d¹ = dⁿ + h/2 (uⁿ + u¹) (3#V, interleaved).
  VecX displacement(const VecX& u1) const;
  /// The seed's starting iterate: u¹ = −uⁿ (d¹ = dⁿ), 0 on fixed DOFs.
  VecX start() const;

 private:
  MatX3 positions(const VecX& u1) const;  ///< X + d¹ (#V × 3)

  const SolidBody& m_body;
  double m_h;
  VecX m_mass;       ///< lumped mass per node
  VecX m_d0, m_u0;   ///< dⁿ, uⁿ
  VecX m_fs0;        ///< f_s(dⁿ, uⁿ)
  VecX m_fe;         ///< f_e
  SparseMatrix m_C;  ///< β K'(dⁿ) (the αM part is applied from m_mass); empty if β = 0
};

/// A factorization of (a copy of) A, CHOLMOD or UMFPACK if not positive definite, as an
/// inverse.
FactoredMatrix factor_inverse(const SparseMatrix& A);

/// Advance one deformable body by h with the nonlinear rule: iterate from start() by
/// `opt.method`, then set d, u (and leave them at tⁿ if it did not converge).
/// @return the iteration's report (converged or not).
EquilibriumReport step_nonlinear(SolidBody& body, double h, const VecX& f_e,
                                 const EquilibriumOptions& opt, EquilibriumHistory& history);

}  // namespace tetfsi::solid
