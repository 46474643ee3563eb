#include "solid/floor_contact.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/dof_elimination.hpp"
#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::solid {

namespace {

/// The axis of an axis-aligned plane (−1 for another obstacle).
int floor_axis(const Obstacle& o) {
  if (o.kind != Obstacle::Kind::Plane) return -1;
  for (int a = 0; a < 3; ++a)
    if (std::abs(std::abs(o.normal[a]) - 1.0) < 1e-12) return a;
  return -1;
}

/// Node i against obstacle o, if o is a floor and the node's normal DOF is free: its gap,
/// approach speed and starting friction state — sliding if it already moves along the floor
/// (its force set once a solve gives its normal force), else sticking.
std::optional<FloorContact> floor_contact(const SolidBody& body, const MatX3& x, Index i,
                                          const Obstacle& o) {
  const int axis = floor_axis(o);
  if (axis < 0 || body.is_fixed(3 * i + axis)) return std::nullopt;
  FloorContact c;
  c.node = i;
  c.axis = axis;
  c.sign = o.normal[axis] > 0 ? 1.0 : -1.0;
  c.gap = c.sign * (x(i, axis) - o.point[axis]);
  c.incoming = c.sign * body.velocity(i, axis);
  c.obstacle = &o;
  Vec3 ut = body.velocity.row(i).transpose();
  ut[axis] = 0.0;
  c.slip = o.friction == 0.0 || ut.norm() > 0.0;
  return c;
}

/// Row i of the symmetric A times u.
double row_dot(const SparseMatrix& A, Index i, const VecX& u) {
  double s = 0.0;
  for (SparseMatrix::InnerIterator it(A, i); it; ++it) s += it.value() * u[it.row()];
  return s;
}

constexpr double k_gap_tol = 1e-12;  ///< m: Eq. (5) below the floor by more adds the node
/// Solves within which a sliding node's friction force is iterated to 1 % of μ λ̄; later
/// solves keep it (its normal force can swing from solve to solve when friction loads a body
/// unevenly: a tilted block landing on a corner).
constexpr int k_friction_rounds = 4;
/// Releases of one node per step; re-added after the last, it stays for the step (λ may
/// then be slightly adhesive: measured −0.02 N on a tilted block of 20 N after one release).
constexpr int k_releases = 2;

}  // namespace

FloorContacts::FloorContacts(const SolidBody& body, const std::vector<Obstacle>& obstacles,
                             const Vec3& gravity, double h)
    : m_body(body), m_obstacles(obstacles), m_h(h), m_released(body.num_nodes(), 0) {
  const MatX3 x = body.positions();
  for (Index i = 0; i < body.num_nodes(); ++i) {
    for (const Obstacle& o : obstacles) {
      const std::optional<FloorContact> c = floor_contact(body, x, i, o);
      if (!c) continue;
      const double pred = c->gap + h * c->incoming + 0.5 * h * h * c->sign * gravity[c->axis];
      if (pred >= 0.0) continue;
      m_contacts.push_back(*c);
      break;
    }
  }
}

void FloorContacts::constrain(const TrapezoidalSystem& sys, SparseMatrix& A, VecX& b,
                              std::vector<std::uint8_t>& fixed, VecX& prescribed) {
  m_sys = &sys;
  A = sys.A;
  b = sys.b;
  fixed = m_body.fixed_dofs();
  prescribed = VecX::Zero(m_body.num_dofs());
  std::vector<std::uint8_t> mask(m_body.num_dofs(), 0);
  for (const FloorContact& c : m_contacts) {
    const Index dof = 3 * c.node + c.axis;
    // on the floor after the step by Eq. (5): gapⁿ⁺¹ = gapⁿ + h/2 (uⁿ_n + uⁿ⁺¹_n) = 0
    prescribed[dof] = c.sign * (-2.0 * c.gap / m_h - c.incoming);
    mask[dof] = 1;
    for (int t = 0; t < 3; ++t) {
      if (t == c.axis || fixed[3 * c.node + t]) continue;
      if (c.slip)
        b[3 * c.node + t] += c.friction[t];
      else
        mask[3 * c.node + t] = 1;  // sticking: tangential uⁿ⁺¹ = 0
    }
  }
  for (size_t i = 0; i < mask.size(); ++i) fixed[i] = fixed[i] || mask[i];
  if (m_contacts.empty()) return;
  const VecX& mass = m_body.lumped_mass();
  eliminate_dofs(
      A, mask, [&](Index i) { return mass[i / 3] / m_h; }, &b, &prescribed);
}

namespace {

/// Coulomb's law for one contact after a solve (see the file comment): sticking → sliding
/// when the holding force `rt` exceeds `limit` = μ λ̄, sliding → sticking when the friction
/// force would drive the node (uₜ · f > 0); a sliding node's force re-aimed against uₜ at the
/// new limit. A node that has switched twice in a step is at the cone's edge with uₜ ≈ 0: it
/// slides from then on with its force's direction kept (the switching would not end).
/// @return true if the solve must be repeated (a switch, or the force moved by > 1 %).
bool update_friction(FloorContact& c, double limit, const Vec3& u_node, const Vec3& rt) {
  Vec3 ut = u_node;
  ut[c.axis] = 0.0;
  if (!c.slip) {
    if (!(rt.norm() > limit * (1.0 + 1e-9) && rt.norm() > 0.0)) return false;
    c.slip = true;  // cannot hold it: it slides, the friction at its limit
    c.friction = limit * rt / rt.norm();
    ++c.switches;
    return true;
  }
  if (c.obstacle->friction == 0.0) return false;
  Vec3 f = c.friction;
  if (c.switches < 2 && (ut.dot(c.friction) > 0.0 || ut.norm() == 0.0)) {
    c.slip = false;  // friction would drive it: it sticks
    ++c.switches;
    return true;
  }
  // The new normal force, averaged with the force applied (the normal forces depend on the
  // friction: alone, a tilted block's nodes swing between two values from round to round).
  const double applied = c.friction.norm();
  const double mag = applied > 0.0 ? 0.5 * (applied + limit) : limit;
  if (c.switches < 2 && ut.norm() > 0.0)
    f = -mag * ut / ut.norm();  // against the sliding
  else if (applied > 0.0)
    f = mag * c.friction / applied;  // at the edge: its direction kept
  const bool moved = (f - c.friction).norm() > 1e-2 * std::max(limit, applied);
  c.friction = f;
  return moved;
}

}  // namespace

bool FloorContacts::update(const VecX& u, const VecX* f) {
  TETFSI_CHECK(m_sys, "FloorContacts::update before constrain");
  ++m_report.rounds;
  const VecX& mass = m_body.lumped_mass();
  auto residual = [&](Index dof) {  // the constraint's force on the DOF: A u − b − f
    return row_dot(m_sys->A, dof, u) - m_sys->b[dof] - (f ? (*f)[dof] : 0.0);
  };
  // The last solve before the cap only adds nodes below the floor: the step then ends with
  // none there (a projection would move a node by up to a step's travel and can invert the
  // elements above it), at worst with an adhesive force or an unsettled friction state.
  const bool closing = m_report.rounds >= max_rounds - 1;
  bool changed = false;
  std::vector<FloorContact> kept;
  for (FloorContact c : m_contacts) {
    const Index n = c.node;
    c.force = c.sign * residual(3 * n + c.axis);
    // adhesive: let it go (twice per step at most: the active set then ends)
    if (c.force < 0.0 && m_released[n] < 2 * k_releases) {
      changed = true;
      if (!closing) {
        ++m_released[n];
        ++m_report.released;
        continue;
      }
    }
    // the floor's net normal force once the node has landed (its u_n then 0)
    const double un = c.sign * u[3 * n + c.axis];
    const double net = std::max(0.0, c.force - mass[n] * un / m_h);
    Vec3 rt = Vec3::Zero();  // sticking: the tangential force that holds it
    if (!c.slip)
      for (int t = 0; t < 3; ++t)
        if (t != c.axis && !m_body.is_fixed(3 * n + t)) rt[t] = residual(3 * n + t);
    // a change of state always solves again; the force's own convergence for a few solves
    FloorContact next = c;
    const bool redo = update_friction(next, c.obstacle->friction * net, u.segment<3>(3 * n), rt);
    if (redo && (next.slip != c.slip || m_report.rounds < k_friction_rounds)) changed = true;
    if (!closing) c = next;
    kept.push_back(c);
  }
  m_contacts = std::move(kept);
  const bool added = add_penetrating(u);
  if (!closing) return changed || added;
  if (added && m_report.rounds < max_rounds) return true;  // the closing solve
  if (changed || added) {
    m_report.converged = false;
    logger().warn(
        "body '{}': its floor contacts did not settle in {} solves ({} released, {} added); the "
        "last set is kept{}",
        m_body.name(), m_report.rounds, m_report.released, m_report.added,
        added ? " and nodes left below a floor are projected onto it" : "");
  }
  return false;
}

bool FloorContacts::add_penetrating(const VecX& u) {
  std::vector<std::uint8_t> in(m_body.num_nodes(), 0);
  for (const FloorContact& c : m_contacts) in[c.node] = 1;
  const MatX3 x = m_body.positions();
  bool added = false;
  for (Index i = 0; i < m_body.num_nodes(); ++i) {
    if (in[i]) continue;
    for (const Obstacle& o : m_obstacles) {
      std::optional<FloorContact> c = floor_contact(m_body, x, i, o);
      if (!c) continue;
      c->slip = o.friction == 0.0;  // found by a solve: it starts sticking
      const double after = c->gap + 0.5 * m_h * (c->incoming + c->sign * u[3 * i + c->axis]);
      if (after >= -k_gap_tol) continue;
      if (m_released[i] % 2 == 1) ++m_released[i];  // back in
      m_contacts.push_back(*c);
      ++m_report.added;
      added = true;
      break;
    }
  }
  return added;
}

Index FloorContacts::land(SolidBody& body) const {
  Index on_floor = 0;  // contact nodes Eq. (5) left just above their floor (round-off)
  const MatX3 x = body.positions();
  for (const FloorContact& c : m_contacts) {
    body.velocity(c.node, c.axis) = c.sign * c.obstacle->restitution * std::max(0.0, -c.incoming);
    if ((x.row(c.node).transpose() - c.obstacle->point).dot(c.obstacle->normal) > 0.0) ++on_floor;
  }
  return on_floor + resolve_collisions(body, m_obstacles);
}

Index step_with_floor_contacts(SolidBody& body, const TrapezoidalSystem& sys,
                               const std::vector<Obstacle>& obstacles, const Vec3& gravity,
                               double h, const BodySolve& solve, VecX& u, PhaseTimes& times,
                               FloorContactReport* rep) {
  FloorContacts contacts(body, obstacles, gravity, h);
  SparseMatrix A;
  VecX b, prescribed;
  std::vector<std::uint8_t> fixed;
  do {
    contacts.constrain(sys, A, b, fixed, prescribed);
    solve(A, b, u);
  } while (contacts.update(u, nullptr));
  if (rep) *rep = contacts.report();
  ScopedTimer timer(times, "update");
  advance_trapezoidal(body, u, h);
  return contacts.land(body);
}

}  // namespace tetfsi::solid
