#include "solid/pose.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/SVD>

namespace tetfsi::solid {

Vec3 up_direction(const Vec3& gravity) {
  const double g = gravity.norm();
  if (!(g > 0.0)) return Vec3::UnitZ();
  return -gravity / g;
}

double rotation_angle_deg(const Mat3& R) {
  const Vec3 vee(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));  // 2 sin θ · axis
  return std::atan2(vee.norm(), R.trace() - 1.0) * 180.0 / std::numbers::pi;
}

namespace {

/// Σ m_i y_i / Σ m_i over the rows of `y` (#V × 3).
Vec3 mass_centroid(const VecX& m, const MatX3& y) {
  return (y.transpose() * m) / m.sum();
}

}  // namespace

Mat3 body_rotation(const SolidBody& body) {
  const VecX& m = body.lumped_mass();
  const MatX3& X = body.rest_positions();
  const MatX3 x = body.positions();
  const Vec3 c = mass_centroid(m, x);
  const Vec3 C = mass_centroid(m, X);
  Mat3 A = Mat3::Zero();
  for (Index i = 0; i < body.num_nodes(); ++i)
    A += m[i] * (x.row(i).transpose() - c) * (X.row(i).transpose() - C).transpose();
  const Eigen::JacobiSVD<Mat3> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3& V = svd.matrixV();
  // A reflection: flip the direction of the smallest singular value (JacobiSVD sorts them in
  // decreasing order), the rotation nearest to A.
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) *= -1.0;
  return U * V.transpose();
}

BodyPose body_pose(const SolidBody& body, const Vec3& up) {
  BodyPose p;
  if (body.num_nodes() == 0) return p;
  const MatX3 x = body.positions();
  const VecX heights = x * up;
  p.lowest = heights.minCoeff();
  p.centroid_height = mass_centroid(body.lumped_mass(), x).dot(up);
  p.rotation_deg = rotation_angle_deg(body_rotation(body));
  return p;
}

}  // namespace tetfsi::solid
