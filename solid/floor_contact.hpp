#pragma once
/// @file floor_contact.hpp
/// Unilateral floor contact with Coulomb friction inside a body's implicit step, for floors
/// (axis-aligned Plane obstacles): an active set of velocity constraints on A uⁿ⁺¹ = b + f
/// [Chentanez06, Eq. (4)], with f the other forces of the solve (the fluid's, in a coupled
/// step).
///
/// A node in contact has the normal velocity that puts it on the floor by Eq. (5),
/// u_n = −2 gapⁿ/h − uⁿ_n, so positions and enclosed volumes stay exact through impacts. The
/// floor's force on it is the constraint's multiplier, the residual of its row,
///   λ = n · (A u − b − f),
/// and the contact is unilateral: after a solve, a node whose λ < 0 (the floor would pull it
/// down: adhesion) is released, and a free node that Eq. (5) puts below the floor is added;
/// the step is solved again until neither happens (a primal–dual active set; the complementarity
/// gapⁿ⁺¹ ≥ 0, λ ≥ 0, gapⁿ⁺¹ λ = 0 then holds at every floor node).
///
/// Friction is Coulomb by the normal force: a node sticks (its tangential uⁿ⁺¹ = 0) while the
/// tangential force that holds it is at most μ λ̄, and slides otherwise under the force
/// μ λ̄ against its tangential velocity, both inside the same solve. λ̄ = λ − m u_n/h is the
/// floor's net normal force of the step once the node has landed (land(): its normal velocity
/// after the step is e × its approach speed, 0 without restitution — the trapezoidal rule would
/// otherwise send it back up at its approach speed).
#include <cstdint>
#include <functional>
#include <vector>

#include "core/timer.hpp"
#include "core/types.hpp"
#include "solid/integrator.hpp"
#include "solid/obstacles.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

/// A node on a floor during one step.
struct FloorContact {
  Index node = -1;
  int axis = 0;  ///< the floor's normal is sign · e_axis
  double sign = 1.0;
  double gap = 0.0;       ///< signed distance above the floor at tⁿ (m)
  double incoming = 0.0;  ///< normal velocity at tⁿ (< 0: approaching)
  const Obstacle* obstacle = nullptr;
  double force = 0.0;            ///< λ, the floor's normal force of the last solve (N)
  bool slip = false;             ///< sliding (friction force below), else sticking
  Vec3 friction = Vec3::Zero();  ///< sliding: the friction force on the node (N)
  int switches = 0;              ///< stick/slip changes this step (2: at the cone's edge)
};

/// What the active set did in one step.
struct FloorContactReport {
  int rounds = 0;         ///< solves of the step
  Index released = 0;     ///< nodes released (adhesive λ), summed over rounds
  Index added = 0;        ///< nodes added after a solve (Eq. (5) below the floor)
  bool converged = true;  ///< the set settled within max_rounds
};

/// One body's floor contacts in one step (see the file comment). Use:
///   FloorContacts c(body, obstacles, gravity, h);
///   do { c.constrain(sys, A, b, fixed, prescribed); solve; } while (c.update(u, f));
///   advance_trapezoidal(body, u, h); c.land(body);
class FloorContacts {
 public:
  /// The starting set: every node whose ballistic prediction xⁿ + h uⁿ + ½ h² g is below a
  /// floor (one floor per node, the first that applies; pinned DOFs excluded).
  FloorContacts(const SolidBody& body, const std::vector<Obstacle>& obstacles, const Vec3& gravity,
                double h);

  bool empty() const { return m_contacts.empty(); }
  Index size() const { return static_cast<Index>(m_contacts.size()); }
  const std::vector<FloorContact>& contacts() const { return m_contacts; }
  const FloorContactReport& report() const { return m_report; }

  /// The body's system with the contacts in it: A and b (the trapezoidal system, pins already
  /// eliminated) get the contact DOFs eliminated at their prescribed velocities and the
  /// sliding nodes' friction forces; fixed and prescribed (3n) mark and hold them. `sys` is
  /// kept by reference for update(): it must outlive the step's solves.
  void constrain(const TrapezoidalSystem& sys, SparseMatrix& A, VecX& b,
                 std::vector<std::uint8_t>& fixed, VecX& prescribed);

  /// After a solve with velocities u (3n, contact DOFs at their prescribed values) and the
  /// other forces f (3n, or null: none): the floor forces, stick/slip, releases and additions.
  /// @return true if the set changed (solve again) and max_rounds is not reached.
  bool update(const VecX& u, const VecX* f);

  /// After Eq. (5): the contact nodes' normal velocity becomes e × their approach speed
  /// (away from the floor; 0 for e = 0), their tangential velocity that of the solve; then
  /// the other obstacles (resolve_collisions). Returns the nodes in contact, each once.
  Index land(SolidBody& body) const;

  /// Solves per step at most; the last one only adds nodes below the floor (none is left
  /// there), and an unsettled set is kept with a warning (report().converged false).
  static constexpr int max_rounds = 12;

 private:
  bool add_penetrating(const VecX& u);
  const SolidBody& m_body;
  const std::vector<Obstacle>& m_obstacles;
  double m_h;
  const TrapezoidalSystem* m_sys = nullptr;
  std::vector<FloorContact> m_contacts;
  /// per node: releases and re-additions this step (odd: released)
  std::vector<std::uint8_t> m_released;
  FloorContactReport m_report;
};

/// Solves A u = b (u: the starting guess in, the solution out).
using BodySolve = std::function<void(const SparseMatrix& A, const VecX& b, VecX& u)>;

/// One body's linearised trapezoidal step A uⁿ⁺¹ = b [Chentanez06, Eqs. (4)–(5)] (`sys`, with
/// any held forces already in b) with its floor contacts, each round solved by `solve`, then
/// Eq. (5), land(), and the remaining obstacles by resolve_collisions. u: uⁿ in (the guess),
/// uⁿ⁺¹ out (Eq. (5), landing and obstacles timed as phase "update"). Returns the nodes in
/// contact; `rep`, if given, the set's work.
Index step_with_floor_contacts(SolidBody& body, const TrapezoidalSystem& sys,
                               const std::vector<Obstacle>& obstacles, const Vec3& gravity,
                               double h, const BodySolve& solve, VecX& u, PhaseTimes& times,
                               FloorContactReport* rep = nullptr);

}  // namespace tetfsi::solid
