#pragma once
/// @file contact.hpp
/// Contact between bodies and self-contact, with a positive gap d̂ and Coulomb friction,
/// inside the bodies' implicit step [Chentanez06, Eq. (4)] (the solid-only world's joint
/// solve, the simultaneous coupled solve's solid block, time splitting's solid solve).
///
/// Primitives: every surface point against every surface triangle, every surface edge against
/// every other (of another body, or of the same body when `self`: pairs that share a vertex
/// or lie closer than max(d̂, 1.5 × the body's thinnest extent) in the rest shape are
/// neighbours through the material, such as a sheet's two faces, not contacts).
/// Broad phase: a bounding-volume hierarchy of the primitives' swept boxes
/// (contact_geometry.hpp); continuous collision detection along the step's straight paths.
///
/// The constraint. For a pair with nodes i, weights c_i (point–triangle: 1, −w₀, −w₁, −w₂;
/// edge–edge: 1 − s, s, −(1 − t), −t) and a unit normal n from the second primitive towards
/// the first, the gap after the step by Eq. (5) must be at least d̂:
///   g(uⁿ⁺¹) = nᵀ Σ c_i (xⁿ_i + h/2 (uⁿ_i + uⁿ⁺¹_i)) − d̂ ≥ 0.
/// n and c are taken at the configuration the solve predicted when the pair first violated it
/// (the start of the step's ballistic prediction, or a solve), n oriented to the side the pair
/// was on at tⁿ: a pair found crossed (continuous detection) is pushed back to its side.
/// An active pair acts by a penalty force f_i = −k g c_i n, k = κ m̄ / h² with m̄ the pair's
/// effective mass (1/m̄ = Σ c_i²/m_i over its free nodes): in A uⁿ⁺¹ = b it adds
/// (h/2) k (c ⊗ n)(c ⊗ n)ᵀ to A (coupling the two bodies' blocks) and −k g₀ (c ⊗ n) to b, so
/// for a body whose inertia dominates its stiffness at this step the gap closes to within
/// about 2/κ of the penetration the step would otherwise make (κ = 10⁴ by default). (Scaling
/// k by the bodies' stiffness as well was measured to make impacts less stable, not more.) The set
/// is a primal–dual active set as the floors' (floor_contact.hpp): after each solve a pair whose
/// force λ = −k g would pull (adhesion) is released, at most twice per step, and a pair the solve
/// moves below d̂ (or across) is added, until neither happens.
///
/// Friction: Coulomb by the normal force of the previous solve, as the lagged smoothed
/// friction of Incremental Potential Contact [Li20, Eqs. (13)–(16)]: a tangential force
/// −μ λ f₁(|v_t|)/|v_t| v_t on the relative tangential velocity v_t = (I − n nᵀ) Σ c_i uⁿ⁺¹_i,
/// f₁(y) = 2y/ε − y²/ε² below ε = 1 mm/s (sticking as a stiff viscosity), 1 above (sliding
/// at μ λ), in the same solve, iterated with λ until it moves by less than 1 %.
///
/// After Eq. (5), land(): an active pair's separating normal velocity becomes at most e × its
/// approach speed (the trapezoidal rule would otherwise send it back at its approach speed, as
/// on a floor), by impulses weighted by the nodes' masses.
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/timer.hpp"
#include "core/types.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

/// The scene's contact between bodies (`contact` section).
struct ContactParams {
  bool enabled = false;
  double gap = 0.0;          ///< d̂ (m): the distance surfaces keep; > 0
  double friction = 0.0;     ///< Coulomb μ ≥ 0
  double restitution = 0.0;  ///< e in [0, 1]: separating speed ≤ e × approach speed
  bool self = true;          ///< self-contact of each body's surface
  double stiffness = 1e4;    ///< κ: the penalty relative to the pair's inertia, k = κ m̄/h²
};

/// @throws InputError naming `where` and the key: gap ≤ 0 or not finite, or larger than the
///   smallest extent of a body's rest shape (its thinnest side); friction < 0; restitution
///   outside [0, 1]; stiffness < 10 (the gap would close by more than a fifth).
void validate(const ContactParams& p, const std::vector<SolidBody>& bodies,
              const std::string& where);

/// The default d̂ where the scene gives none: a fifth of `size` (the fluid's surface cell
/// size, or a solid-only scene's median surface edge), at most a third of the thinnest body.
double default_contact_gap(const std::vector<SolidBody>& bodies, double size);
/// The median length of the bodies' surface edges (m).
double median_surface_edge(const std::vector<SolidBody>& bodies);

/// One contact constraint of a step (file comment).
struct ContactPair {
  bool edge_edge = false;
  std::array<Index, 2> body{};  ///< the two primitives' bodies
  std::array<Index, 2> prim{};  ///< point (surface node) / edge, then triangle / edge
  int nodes = 0;                ///< 4 (both kinds)
  std::array<Index, 4> node{};  ///< node i of body node_body[i]
  std::array<Index, 4> node_body{};
  std::array<double, 4> c{};  ///< weights c_i
  Vec3 n = Vec3::UnitZ();     ///< unit normal, second primitive → first
  double g0 = 0.0;            ///< nᵀ Σ c_i (xⁿ_i + h/2 uⁿ_i) − d̂ (m)
  double k = 0.0;             ///< penalty (N/m)
  double lambda0 = 0.0;       ///< augmented-Lagrangian offset: λ = λ₀ − k g (N)
  double force = 0.0;         ///< λ of the last solve (N)
  double eta = 0.0;           ///< friction viscosity μ λ f₁(|v_t|)/|v_t| (N s/m)
  double approach = 0.0;      ///< −nᵀ Σ c_i uⁿ_i: > 0 approaching (m/s)
  bool crossed = false;       ///< found across the other primitive (CCD)
};

/// What the contacts did in one step.
struct ContactReport {
  int rounds = 0;          ///< solves of the step with the contacts in them
  Index active = 0;        ///< pairs in the set at the end
  Index added = 0;         ///< pairs added after a solve
  Index released = 0;      ///< pairs released (adhesive)
  Index crossings = 0;     ///< pairs found crossed by the continuous detection
  bool converged = true;   ///< the set settled within max_rounds
  double force = 0.0;      ///< Σ λ over the set at the end (N)
  double max_force = 0.0;  ///< max λ (N)
  /// The smallest distance between surface primitives after the step (different bodies, and
  /// a body's own non-neighbouring primitives), capped at 4 d̂ (m).
  double min_gap = 0.0;
};

/// Where a body's DOFs are in the stacked system of the free bodies' velocities.
struct BodyDofs {
  Index dof0 = -1;  ///< first stacked DOF of a free body; −1: not free (its uⁿ⁺¹ known)
  /// free: per DOF, 1 where uⁿ⁺¹ is prescribed (pins, floor contacts); null: none
  const std::vector<std::uint8_t>* fixed = nullptr;
  /// free: the prescribed values (3n; null: 0); not free: the body's whole uⁿ⁺¹ (3n)
  const VecX* known = nullptr;
};

/// The contacts' part of the stacked system: A uⁿ⁺¹ = b over the free DOFs.
struct ContactSystem {
  SparseMatrix A;  ///< ns × ns (symmetric, positive semi-definite)
  VecX b;          ///< ns
  bool empty() const { return A.nonZeros() == 0; }
};

/// The contacts of one step between `bodies` (see the file comment). Use:
///   BodyContacts c(bodies, params, gravity, h);  // before kinematic bodies are moved
///   do { ... c.system(dofs, ns) ...; solve; } while (c.update(u));
///   advance_trapezoidal(...) for every body; c.land(bodies); c.measure(bodies);
class BodyContacts {
 public:
  /// Captures xⁿ, uⁿ of every body and the starting set from each free body's ballistic
  /// prediction xⁿ + h uⁿ + ½ h² g (kinematic bodies: xⁿ + h uⁿ).
  BodyContacts(const std::vector<SolidBody>& bodies, const ContactParams& params,
               const Vec3& gravity, double h);
  ~BodyContacts();
  BodyContacts(const BodyContacts&) = delete;
  BodyContacts& operator=(const BodyContacts&) = delete;

  bool empty() const { return m_pairs.empty(); }
  const std::vector<ContactPair>& pairs() const { return m_pairs; }
  const ContactReport& report() const { return m_report; }

  /// The set's penalty and friction terms on the stacked free DOFs (ns of them).
  ContactSystem system(const std::vector<BodyDofs>& dofs, Index ns) const;

  /// After a solve with every body's uⁿ⁺¹ (3n; kinematic bodies' known velocities, empty
  /// for bodies without contact): forces, friction, releases, additions.
  /// @return true if the set changed (solve again) and max_rounds is not reached.
  bool update(const std::vector<VecX>& u);

  /// After Eq. (5): separating normal velocities of active pairs at most e × approach.
  void land(std::vector<SolidBody>& bodies) const;
  /// The report's min_gap from the bodies' positions after the step.
  void measure(const std::vector<SolidBody>& bodies);

  static constexpr int max_rounds = 12;

 private:
  struct Surface;
  std::vector<MatX3> ends(const std::vector<VecX>& u) const;
  /// Adds every candidate pair violated at positions `x1` (ends of straight paths from xⁿ).
  bool add_violated(const std::vector<MatX3>& x1);
  /// The pair's constraint `cp` if it is violated at x1 (g1 < 0: its gap there minus d̂).
  bool try_pair(bool ee, Index ba, Index pa, Index bb, Index pb, const std::vector<MatX3>& x1,
                ContactPair& cp, double& g1) const;
  /// Is point p0[0] behind triangle p0[1..3] of body bb at the start of the step, under it and
  /// less than half the body's thickness deep?
  bool inside_at_start(Index bb, const std::array<Vec3, 4>& p0) const;
  /// The rest of pair `cp` (n and c set) and g1, its gap at p1 minus d̂; false if g1 ≥ 0.
  bool fill_pair(bool ee, std::array<Index, 2> body, std::array<Index, 2> prim,
                 const std::array<Index, 4>& node, const std::array<Index, 4>& node_body,
                 const std::array<Vec3, 4>& p0, const std::array<Vec3, 4>& p1, ContactPair& cp,
                 double& g1) const;
  double pair_distance(bool ee, Index ba, Index pa, Index bb, Index pb,
                       const std::vector<MatX3>& x) const;
  bool excluded(bool ee, Index ba, Index pa, Index bb, Index pb) const;
  using Visit = std::function<void(bool ee, Index ba, Index pa, Index bb, Index pb)>;
  /// Every candidate pair whose boxes around the paths x0 → x1, inflated by `pad`, overlap.
  void candidates(const std::vector<MatX3>& x0, const std::vector<MatX3>& x1, double pad,
                  const Visit& visit) const;

  const std::vector<SolidBody>& m_bodies;
  ContactParams m_params;
  double m_h;
  std::vector<MatX3> m_x0, m_u0;
  std::vector<Surface> m_surf;
  std::vector<double> m_self_reach;  ///< per body: excluded() below this rest distance
  std::vector<double> m_depth;  ///< per body: how deep a point inside it counts (inside_at_start)
  std::vector<ContactPair> m_pairs;
  std::map<std::array<Index, 5>, int> m_released;  ///< per pair key: releases this step
  ContactReport m_report;
};

/// The block-diagonal matrix of the blocks A[b] at rows and columns dof0[b] (dof0: #A + 1
/// offsets; a block of an empty range is skipped).
SparseMatrix stack_blocks(const std::vector<SparseMatrix>& A, const std::vector<Index>& dof0);

}  // namespace tetfsi::solid
