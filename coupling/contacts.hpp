#pragma once
/// @file contacts.hpp
/// Floor contacts as velocity constraints of the simultaneous solve: a node whose predicted
/// position xⁿ + h uⁿ + ½ h² g is below an axis-aligned plane gets the normal velocity that
/// puts it on the plane by Eq. (5), u_n = −2 gapⁿ/h − uⁿ_n. Its position stays exact — the
/// enclosed volume then sees exactly what the solve saw, where projecting nodes out after the
/// step would change it by the penetration — and its velocity is stopped after the step.
#include <cstdint>
#include <vector>

#include "core/types.hpp"
#include "solid/obstacles.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::coupling {

/// A node held on a floor (an axis-aligned Plane obstacle) during a coupled step.
struct Contact {
  Index node = -1;
  int axis = 0;
  double sign = 1.0;      ///< the plane's normal is sign · e_axis
  double incoming = 0.0;  ///< normal velocity at tⁿ (< 0: approaching)
  const solid::Obstacle* obstacle = nullptr;
};

/// The body's floor contacts of this step: sets fixed[dof] = 1 and prescribed[dof] (3n each)
/// for the normal DOF of each contact node (one plane per node, the first that applies).
std::vector<Contact> floor_contacts(const solid::SolidBody& body,
                                    const std::vector<solid::Obstacle>& obstacles,
                                    const Vec3& gravity, double h, VecX& prescribed,
                                    std::vector<std::uint8_t>& fixed);

/// After the step: the contact nodes stop on the floor (normal velocity 0) and lose
/// tangential speed by Coulomb friction. No per-node restitution: a node sent back up while
/// its neighbours still come down crushes the elements between them (measured: a
/// liquid-filled shell inverted elements within 3 steps of touching the floor at e = 0.3);
/// the body rebounds by its own elasticity.
void land_contacts(solid::SolidBody& body, const std::vector<Contact>& contacts,
                   const Vec3& gravity, double h);

}  // namespace tetfsi::coupling
