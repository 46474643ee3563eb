#include "coupling/contacts.hpp"

#include <algorithm>
#include <cmath>

namespace tetfsi::coupling {

std::vector<Contact> floor_contacts(const solid::SolidBody& body,
                                    const std::vector<solid::Obstacle>& obstacles,
                                    const Vec3& gravity, double h, VecX& prescribed,
                                    std::vector<std::uint8_t>& fixed) {
  std::vector<Contact> out;
  const MatX3 x = body.positions();
  for (Index i = 0; i < body.num_nodes(); ++i) {
    for (const solid::Obstacle& o : obstacles) {
      if (o.kind != solid::Obstacle::Kind::Plane) continue;
      int axis = -1;
      for (int a = 0; a < 3; ++a)
        if (std::abs(std::abs(o.normal[a]) - 1.0) < 1e-12) axis = a;
      if (axis < 0) continue;
      const double sign = o.normal[axis] > 0 ? 1.0 : -1.0;
      const Index dof = 3 * i + axis;
      if (fixed[dof]) continue;
      const double gap = sign * (x(i, axis) - o.point[axis]);
      const double un = sign * body.velocity(i, axis);
      const double pred = gap + h * un + 0.5 * h * h * sign * gravity[axis];
      if (pred >= 0.0) continue;
      Contact c;
      c.node = i;
      c.axis = axis;
      c.sign = sign;
      c.incoming = un;
      c.obstacle = &o;
      fixed[dof] = 1;
      prescribed[dof] = sign * (-2.0 * gap / h - un);  // lands on the plane by Eq. (5)
      out.push_back(c);
      break;
    }
  }
  return out;
}

void land_contacts(solid::SolidBody& body, const std::vector<Contact>& contacts,
                   const Vec3& gravity, double h) {
  for (const Contact& c : contacts) {
    const double mu = c.obstacle->friction;
    Vec3 u = body.velocity.row(c.node).transpose();
    // the normal speed the floor takes away this step: the approach, and what gravity would
    // have added (a resting node's weight, for Coulomb friction)
    const double dun = std::abs(c.sign * u[c.axis]) + std::max(0.0, -c.incoming) +
                       h * std::max(0.0, -c.sign * gravity[c.axis]);
    u[c.axis] = 0.0;
    const double tn = u.norm();
    if (tn > 0) u *= std::max(0.0, 1.0 - mu * dun / tn);
    body.velocity.row(c.node) = u.transpose();
  }
}

}  // namespace tetfsi::coupling
