#pragma once
/// @file stvk.hpp
/// Constant-Green-strain linear tets with an isotropic St. Venant–Kirchhoff law
/// [OBrienHodgins99], [Chentanez06, §3.2].
///
/// Per tet with rest edge matrix Dm = [X1−X0, X2−X0, X3−X0] and deformed Ds likewise:
///   F = Ds Dm⁻¹,  E = ½(FᵀF − I)  (Green strain),  S = λ tr(E) I + 2μ E  (2nd Piola–Kirchhoff),
///   W = V0 (μ E:E + ½ λ (tr E)²)  (elastic energy).
/// The elastic force of [Chentanez06, Eq. (3)] is K(d) = ∂W/∂x (the internal force, on the
/// left-hand side of M a + C u + K(d) = f), and K' = ∂K/∂d is its Jacobian (symmetric).
#include <vector>

#include "core/enum_names.hpp"
#include "core/types.hpp"
#include "solid/material.hpp"

namespace tetfsi::solid {

/// Which Jacobian K' the integrators use (scene key solid.tangent).
enum class Tangent {
  Exact,     ///< ∂²W/∂x², indefinite where an element is strongly compressed
  Definite,  ///< the initial-stress part keeps only S's tensile principal stresses: K' ⪰ 0
};
inline constexpr EnumNames<Tangent, 2> k_tangent_names{
    "tangent", {{{Tangent::Exact, "exact"}, {Tangent::Definite, "definite"}}}};

/// Per-tet output fields (#T each).
struct TetFields {
  VecX green_strain_norm;  ///< Frobenius norm of E (dimensionless)
  VecX von_mises_stress;   ///< von Mises stress of the Cauchy stress σ = F S Fᵀ / J (Pa)
  VecX volume_ratio;       ///< J = det F = V / V0
};

class StvkElasticity {
 public:
  /// @param rest rest positions X (#V × 3, m)
  /// @param tets positively oriented tets (#T × 4)
  StvkElasticity(const MatX3& rest, const MatX4i& tets, const Material& material);

  Index num_nodes() const { return m_num_nodes; }
  Index num_tets() const { return static_cast<Index>(m_tets.rows()); }
  /// Rest volume of each tet (#T, m³).
  const VecX& rest_volumes() const { return m_rest_volume; }

  /// Elastic energy W(x) (J) at deformed positions x (#V × 3).
  double energy(const MatX3& x) const;
  /// K(d) = ∂W/∂x (3#V, interleaved, N).
  VecX forces(const MatX3& x) const;
  /// K'(d) = ∂²W/∂x² (3#V × 3#V, symmetric, N/m).
  SparseMatrix jacobian(const MatX3& x) const;
  /// Forces and Jacobian in one pass (shares F, E, S per tet).
  void forces_and_jacobian(const MatX3& x, VecX& forces, SparseMatrix& jacobian) const;
  /// Strain, stress and volume-ratio fields at x.
  TetFields tet_fields(const MatX3& x) const;

  /// The Jacobian jacobian() and forces_and_jacobian() return (Exact by default). Definite
  /// replaces S by S₊ = Q max(Λ, 0) Qᵀ in the initial-stress term g_aᵀ S g_b I of K'_e: the
  /// material term is ⪰ 0, so K' is too, and the step's matrix M/h + C + (h/2) K' stays SPD
  /// however hard an element is compressed. Only the matrix changes, not the forces: a
  /// linearised step's equilibrium is the same, Newton converges linearly instead.
  void set_tangent(Tangent t) { m_tangent = t; }
  Tangent tangent() const { return m_tangent; }

 private:
  Index m_num_nodes;
  MatX4i m_tets;
  LameParameters m_lame;
  Tangent m_tangent = Tangent::Exact;
  std::vector<Mat3> m_dm_inv;  ///< Dm⁻¹ per tet
  VecX m_rest_volume;          ///< V0 per tet
  /// Sparsity pattern of K' (3#V × 3#V, values zero), built once in the constructor.
  SparseMatrix m_pattern;
  /// #T · 144: index into m_pattern's value array of local entry (12 i + j) of tet t, so each
  /// Jacobian evaluation only fills values (no triplet sort).
  std::vector<Index> m_slot;
};

}  // namespace tetfsi::solid
