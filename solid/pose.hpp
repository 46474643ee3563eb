#pragma once
/// @file pose.hpp
/// Where a body is and how far it has turned, in three numbers per body (the `<body>_lowest`,
/// `<body>_centroid_height` and `<body>_rotation_deg` columns of stats.csv): enough to see
/// contact with a floor and tipping without opening frames.
///
/// With lumped masses m_i, current positions x_i = X_i + d_i and rest positions X_i:
///
///   lowest          = min_i x_i · up                                              (m)
///   centroid_height = c · up,  c = Σ m_i x_i / Σ m_i                              (m)
///   A = Σ m_i (x_i − c)(X_i − C)ᵀ,  C = Σ m_i X_i / Σ m_i,  A = R S  (polar decomposition)
///   rotation_deg    = the angle of R, 0..180                                      (degrees)
///
/// R is the rotation closest to A in the Frobenius norm (the best-fit rigid rotation of the
/// body from rest, as in shape matching): R = U Vᵀ from A = U Σ Vᵀ (Eigen's JacobiSVD), with
/// the column of U of the smallest singular value negated if det(U Vᵀ) < 0, so det R = +1.
/// A rigid motion x = Q X + t gives R = Q (A = Q Σ m (X − C)(X − C)ᵀ, the second factor
/// symmetric positive definite); a uniform scaling x = s X + t (s > 0) gives R = I.
#include <cmath>

#include "core/types.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {

/// The pose figures of one body (pose.hpp's formulas). NaN for a body without nodes.
struct BodyPose {
  double lowest = NAN;           ///< min over the nodes of x · up (m)
  double centroid_height = NAN;  ///< the mass centroid · up (m)
  double rotation_deg = NAN;     ///< angle of the rotation from rest (degrees, 0..180)
};

/// The unit vector against gravity, −g/|g|; +z when g = 0 (a scene without gravity).
/// @param gravity m/s²
Vec3 up_direction(const Vec3& gravity);

/// The angle of a rotation matrix in degrees (0..180): θ with tr R = 1 + 2 cos θ and
/// |vee(R − Rᵀ)| = 2 sin θ. Computed as atan2(|vee(R − Rᵀ)|, tr R − 1), which equals
/// acos(clamp((tr R − 1)/2, −1, 1)) for a rotation but keeps full precision near 0 and 180°
/// (acos near 1 turns round-off ε into √(2ε) ≈ 1e-6°).
/// @param R a rotation (orthogonal, det +1)
double rotation_angle_deg(const Mat3& R);

/// R of the polar decomposition A = R S of A = Σ m_i (x_i − c)(X_i − C)ᵀ (see the file's
/// comment): the body's best-fit rotation from rest.
Mat3 body_rotation(const SolidBody& body);

/// The body's lowest point, centroid height and rotation from rest (pose.hpp's formulas),
/// for its current state X + d. Kinematic bodies are measured the same way.
/// @param up unit vector pointing up (up_direction(world.gravity))
BodyPose body_pose(const SolidBody& body, const Vec3& up);

}  // namespace tetfsi::solid
