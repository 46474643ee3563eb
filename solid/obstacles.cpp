#include "solid/obstacles.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.hpp"

namespace tetfsi::solid {

namespace {

/// Penetration test of point x against one obstacle. Returns true if x is inside or on the
/// surface, with `depth` ≥ 0 the distance to the closest surface point and `n` the outward
/// unit normal there (pointing to the free side).
bool penetration(const Obstacle& o, const Vec3& x, double& depth, Vec3& n) {
  if (o.kind == Obstacle::Kind::Plane) {
    const double s = (x - o.point).dot(o.normal);
    if (s > 0.0) return false;
    depth = -s;
    n = o.normal;
    return true;
  }
  // Box: inside if strictly between lo and hi in every axis; leave through the nearest face.
  for (int k = 0; k < 3; ++k)
    if (!(x[k] > o.lo[k] && x[k] < o.hi[k])) return false;
  depth = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double to_lo = x[k] - o.lo[k];
    const double to_hi = o.hi[k] - x[k];
    if (to_lo < depth) {
      depth = to_lo;
      n = -Vec3::Unit(k);
    }
    if (to_hi < depth) {
      depth = to_hi;
      n = Vec3::Unit(k);
    }
  }
  return true;
}

}  // namespace

Index resolve_collisions(SolidBody& body, const std::vector<Obstacle>& obstacles) {
  if (obstacles.empty()) return 0;
  for (const Obstacle& o : obstacles) {
    TETFSI_REQUIRE(InputError, o.restitution >= 0.0 && o.restitution <= 1.0,
                   "obstacle '{}': restitution {} must be in [0, 1]", o.name, o.restitution);
    TETFSI_REQUIRE(InputError, o.friction >= 0.0, "obstacle '{}': friction {} must be >= 0", o.name,
                   o.friction);
    if (o.kind == Obstacle::Kind::Plane)
      TETFSI_REQUIRE(InputError, std::abs(o.normal.norm() - 1.0) < 1e-9,
                     "obstacle '{}': plane normal must have unit length (got {})", o.name,
                     o.normal.norm());
    else
      TETFSI_REQUIRE(InputError, (o.lo.array() < o.hi.array()).all(),
                     "obstacle '{}': box needs lo < hi in every axis", o.name);
  }
  const MatX3& X = body.rest_positions();
  Index contacts = 0;
  for (Index i = 0; i < body.num_nodes(); ++i) {
    if (body.is_fixed(3 * i) || body.is_fixed(3 * i + 1) || body.is_fixed(3 * i + 2)) continue;
    bool in_contact = false;
    for (const Obstacle& o : obstacles) {
      Vec3 x = X.row(i).transpose() + body.displacement.row(i).transpose();
      double depth = 0.0;
      Vec3 n = Vec3::Zero();
      if (!penetration(o, x, depth, n)) continue;
      in_contact = true;
      // Project to the closest surface point.
      body.displacement.row(i) += depth * n.transpose();
      Vec3 u = body.velocity.row(i).transpose();
      const double un = u.dot(n);
      if (un < 0.0) {
        // Restitution on the approaching normal velocity: u_n ← −e u_n.
        const double dun = -(1.0 + o.restitution) * un;  // > 0
        Vec3 ut = u - un * n;
        const double ut_norm = ut.norm();
        // Coulomb friction: |Δu_t| ≤ μ |Δu_n|, stopping but never reversing.
        if (ut_norm > 0.0) ut *= std::max(0.0, 1.0 - o.friction * dun / ut_norm);
        u = ut - o.restitution * un * n;
      }
      body.velocity.row(i) = u.transpose();
    }
    if (in_contact) ++contacts;
  }
  return contacts;
}

}  // namespace tetfsi::solid
