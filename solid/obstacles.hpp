#pragma once
/// @file obstacles.hpp
/// Static obstacles (half-spaces and boxes) that keep solid nodes outside, with
/// restitution and Coulomb friction.
#include <string>
#include <vector>

#include "core/types.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

struct Obstacle {
  enum class Kind { Plane, Box };
  Kind kind = Kind::Plane;
  std::string name;
  // Plane: the solid side is {x : (x − point) · normal ≥ 0}; nodes must stay there.
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  ///< unit normal pointing into the free side
  // Box: axis-aligned [lo, hi]; nodes must stay outside it.
  Vec3 lo = Vec3::Zero();
  Vec3 hi = Vec3::Zero();
  double restitution = 0.0;  ///< e in [0, 1]: outgoing normal speed = e × incoming
  double friction = 0.0;     ///< Coulomb μ ≥ 0: |Δu_t| ≤ μ |Δu_n|
};

/// After a step: every node found inside an obstacle (not fixed) is moved to the closest
/// point of its surface (displacement changed), the normal velocity component, if
/// approaching, becomes −e times itself, and the tangential component is reduced by at most
/// μ times the normal velocity change (stopping, not reversing).
/// Restitution and friction act per node: for a multi-node body the macroscopic rebound
/// follows from momentum sharing (a tet landing on a face with e = 1 keeps (3e − 1)/4 of its
/// speed). Projection stores about ½ k (v h)² of elastic energy per contact, i.e. a fraction
/// (ωh)² of the impact energy: harmless when the body's modes are resolved (ωh < 1), but a
/// stiff body with ωh ≫ 1 can be launched by it — reduce h or soften the body.
/// @return the number of nodes in contact.
Index resolve_collisions(SolidBody& body, const std::vector<Obstacle>& obstacles);

}  // namespace tetfsi::solid
