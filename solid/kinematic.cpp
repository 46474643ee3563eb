#include "solid/kinematic.hpp"

#include <cmath>

#include <Eigen/Geometry>

namespace tetfsi::solid {

Mat3 KinematicMotion::rotation(double t) const {
  const double rate = angular_velocity.norm();
  if (rate == 0.0) return Mat3::Identity();
  const Vec3 a = angular_velocity / rate;
  Mat3 K;
  K << 0.0, -a.z(), a.y(),  //
      a.z(), 0.0, -a.x(),   //
      -a.y(), a.x(), 0.0;
  const double theta = rate * t;
  // Rodrigues' rotation formula.
  return Mat3::Identity() + std::sin(theta) * K + (1.0 - std::cos(theta)) * (K * K);
}

Vec3 KinematicMotion::position(const Vec3& X, double t) const {
  return center + linear_velocity * t + rotation(t) * (X - center);
}

Vec3 KinematicMotion::velocity(const Vec3& X, double t) const {
  return linear_velocity + angular_velocity.cross(rotation(t) * (X - center));
}

MatX3 KinematicMotion::position(const MatX3& X, double t) const {
  const Mat3 R = rotation(t);
  const Vec3 shift = center + linear_velocity * t;
  MatX3 x(X.rows(), 3);
  for (Index i = 0; i < X.rows(); ++i)
    x.row(i) = (shift + R * (X.row(i).transpose() - center)).transpose();
  return x;
}

MatX3 KinematicMotion::velocity(const MatX3& X, double t) const {
  const Mat3 R = rotation(t);
  MatX3 u(X.rows(), 3);
  for (Index i = 0; i < X.rows(); ++i)
    u.row(i) =
        (linear_velocity + angular_velocity.cross(R * (X.row(i).transpose() - center))).transpose();
  return u;
}

}  // namespace tetfsi::solid
