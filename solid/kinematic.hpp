#pragma once
/// @file kinematic.hpp
/// Prescribed rigid motion of a body that the scene moves instead of the FEM (scene key
/// `bodies[i].kinematic`): a constant translation velocity plus a constant rotation about an
/// axis through a centre that travels with the body.
///
///   x(t) = c + v t + R(t) (X − c),   R(t) = rotation by |ω| t about ω / |ω|   (Rodrigues)
///   u(t) = v + ω × (x(t) − c − v t) = v + ω × R(t) (X − c)
///
/// Evaluated in closed form at every t (no accumulation over steps, so no drift): the
/// distances between nodes are those of the rest configuration to round-off at any time.
#include "core/types.hpp"

namespace tetfsi::solid {

struct KinematicMotion {
  Vec3 linear_velocity = Vec3::Zero();   ///< v (m/s)
  Vec3 angular_velocity = Vec3::Zero();  ///< ω (rad/s): axis ω/|ω|, rate |ω|
  Vec3 center = Vec3::Zero();            ///< c (m): a point on the rotation axis at t = 0

  /// R(t) = I + sin θ K + (1 − cos θ) K², θ = |ω| t, K = [ω/|ω|]×  (identity for ω = 0).
  Mat3 rotation(double t) const;

  /// x(t) of the material point with rest position X (m). @param t time (s)
  Vec3 position(const Vec3& X, double t) const;
  /// u(t) of the material point with rest position X (m/s).
  Vec3 velocity(const Vec3& X, double t) const;

  /// x(t) of every node. @param X rest positions (n × 3, m) @return n × 3 (m)
  MatX3 position(const MatX3& X, double t) const;
  /// u(t) of every node. @param X rest positions (n × 3, m) @return n × 3 (m/s)
  MatX3 velocity(const MatX3& X, double t) const;
};

}  // namespace tetfsi::solid
