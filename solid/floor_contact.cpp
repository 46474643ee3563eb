#include "solid/floor_contact.hpp"

#include <algorithm>
#include <cmath>

#include "core/dof_elimination.hpp"
#include "core/error.hpp"

namespace tetfsi::solid {

namespace {

/// The axis of an axis-aligned plane (−1 for another obstacle).
int floor_axis(const Obstacle& o) {
  if (o.kind != Obstacle::Kind::Plane) return -1;
  for (int a = 0; a < 3; ++a)
    if (std::abs(std::abs(o.normal[a]) - 1.0) < 1e-12) return a;
  return -1;
}

/// Row i of the symmetric A times u.
double row_dot(const SparseMatrix& A, Index i, const VecX& u) {
  double s = 0.0;
  for (SparseMatrix::InnerIterator it(A, i); it; ++it) s += it.value() * u[it.row()];
  return s;
}

constexpr double k_gap_tol = 1e-12;  ///< m: Eq. (5) below the floor by more adds the node

}  // namespace

FloorContacts::FloorContacts(const SolidBody& body, const std::vector<Obstacle>& obstacles,
                             const Vec3& gravity, double h)
    : m_body(body), m_obstacles(obstacles), m_h(h), m_released(body.num_nodes(), 0) {
  const MatX3 x = body.positions();
  for (Index i = 0; i < body.num_nodes(); ++i) {
    for (const Obstacle& o : obstacles) {
      const int axis = floor_axis(o);
      if (axis < 0 || body.is_fixed(3 * i + axis)) continue;
      FloorContact c;
      c.node = i;
      c.axis = axis;
      c.sign = o.normal[axis] > 0 ? 1.0 : -1.0;
      c.gap = c.sign * (x(i, axis) - o.point[axis]);
      c.incoming = c.sign * body.velocity(i, axis);
      c.obstacle = &o;
      // a node already sliding starts sliding (its friction force set by the first solve's
      // normal force), else sticking
      Vec3 ut = body.velocity.row(i).transpose();
      ut[axis] = 0.0;
      c.slip = o.friction == 0.0 || ut.norm() > 0.0;
      const double pred = c.gap + h * c.incoming + 0.5 * h * h * c.sign * gravity[axis];
      if (pred >= 0.0) continue;
      m_contacts.push_back(c);
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

bool FloorContacts::update(const VecX& u, const VecX* f) {
  TETFSI_CHECK(m_sys, "FloorContacts::update before constrain");
  ++m_report.rounds;
  const VecX& mass = m_body.lumped_mass();
  auto residual = [&](Index dof) {  // the constraint's force on the DOF: A u − b − f
    return row_dot(m_sys->A, dof, u) - m_sys->b[dof] - (f ? (*f)[dof] : 0.0);
  };
  bool changed = false;
  std::vector<FloorContact> kept;
  for (FloorContact c : m_contacts) {
    const Index n = c.node;
    c.force = c.sign * residual(3 * n + c.axis);
    if (c.force < 0.0 && m_released[n] == 0) {  // adhesive: let it go
      m_released[n] = 1;
      ++m_report.released;
      changed = true;
      continue;
    }
    // the floor's net normal force once the node has landed (its u_n then 0)
    const double un = c.sign * u[3 * n + c.axis];
    const double net = std::max(0.0, c.force - mass[n] * un / m_h);
    const double limit = c.obstacle->friction * net;
    Vec3 ut = u.segment<3>(3 * n);
    ut[c.axis] = 0.0;
    if (!c.slip) {
      Vec3 rt = Vec3::Zero();
      for (int t = 0; t < 3; ++t)
        if (t != c.axis && !m_body.is_fixed(3 * n + t)) rt[t] = residual(3 * n + t);
      if (rt.norm() > limit * (1.0 + 1e-9) && rt.norm() > 0.0) {  // cannot hold it: slide
        c.slip = true;
        c.friction = limit * rt / rt.norm();
        changed = true;
      }
    } else if (c.obstacle->friction > 0.0) {
      if (ut.dot(c.friction) > 0.0 || ut.norm() == 0.0) {  // friction would drive it: it sticks
        c.slip = false;
        changed = true;
      } else if (ut.norm() > 0.0) {
        // against the sliding, at the new normal force: solved again until it holds to 1 %
        const Vec3 f = -limit * ut / ut.norm();
        if ((f - c.friction).norm() > 1e-2 * std::max(f.norm(), c.friction.norm())) changed = true;
        c.friction = f;
      }
    }
    kept.push_back(c);
  }
  m_contacts = std::move(kept);
  changed = add_penetrating(u) || changed;
  if (changed && m_report.rounds >= max_rounds) {
    m_report.converged = false;
    return false;
  }
  return changed;
}

bool FloorContacts::add_penetrating(const VecX& u) {
  std::vector<std::uint8_t> in(m_body.num_nodes(), 0);
  for (const FloorContact& c : m_contacts) in[c.node] = 1;
  const MatX3 x = m_body.positions();
  bool added = false;
  for (Index i = 0; i < m_body.num_nodes(); ++i) {
    if (in[i] || m_released[i] == 2) continue;
    for (const Obstacle& o : m_obstacles) {
      const int axis = floor_axis(o);
      if (axis < 0 || m_body.is_fixed(3 * i + axis)) continue;
      FloorContact c;
      c.node = i;
      c.axis = axis;
      c.sign = o.normal[axis] > 0 ? 1.0 : -1.0;
      c.gap = c.sign * (x(i, axis) - o.point[axis]);
      c.incoming = c.sign * m_body.velocity(i, axis);
      c.obstacle = &o;
      c.slip = o.friction == 0.0;
      const double after = c.gap + 0.5 * m_h * (c.incoming + c.sign * u[3 * i + axis]);
      if (after >= -k_gap_tol) continue;
      if (m_released[i] == 1) m_released[i] = 2;  // back in: it stays for this step
      m_contacts.push_back(c);
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
    body.velocity(c.node, c.axis) =
        c.sign * c.obstacle->restitution * std::max(0.0, -c.incoming);
    if ((x.row(c.node).transpose() - c.obstacle->point).dot(c.obstacle->normal) > 0.0)
      ++on_floor;
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
