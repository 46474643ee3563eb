/// Tests of solid/pose.cpp: a body moved rigidly by a known rotation and translation gives
/// that angle and the lowest point and centroid height computed by hand; at rest 0°; near
/// 180°; a uniform scaling 0°; kinematic bodies measured the same way.
#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

#include "solid/pose.hpp"
#include "solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The box [0, 1] × [0, 2] × [0, 3], 2 × 2 × 3 cells: its lumped-mass centroid is the box's
/// centre (0.5, 1, 1.5) (each tet puts a quarter of its mass on each node).
SolidBody make_pose_box() {
  return make_box_body("box", Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3i(2, 2, 3),
                       make_material(1000.0, 1e5, 0.3));
}

const Vec3 kCentre(0.5, 1.0, 1.5);

/// d such that x = Q (X − centre) + centre + t for every node.
void move_rigidly(SolidBody& b, const Mat3& Q, const Vec3& t) {
  for (Index i = 0; i < b.num_nodes(); ++i) {
    const Vec3 X = b.rest_positions().row(i).transpose();
    b.displacement.row(i) = (Q * (X - kCentre) + kCentre + t - X).transpose();
  }
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("body_pose at rest: 0 degrees, the lowest point and centroid of the rest shape") {
    const SolidBody b = make_pose_box();
    const BodyPose z = body_pose(b, up_direction(Vec3(0, 0, -9.81)));
    CHECK(std::abs(z.rotation_deg) <= 1e-12);
    CHECK(std::abs(z.lowest - 0.0) <= 1e-12);
    CHECK(std::abs(z.centroid_height - 1.5) <= 1e-12);
    // Gravity along −y: up is +y.
    const BodyPose y = body_pose(b, up_direction(Vec3(0, -2.0, 0)));
    CHECK(std::abs(y.lowest - 0.0) <= 1e-12);
    CHECK(std::abs(y.centroid_height - 1.0) <= 1e-12);
    CHECK(std::abs(y.rotation_deg) <= 1e-12);
  }

  TEST_CASE("up_direction: against gravity, +z without gravity") {
    CHECK((up_direction(Vec3(0, 0, -9.81)) - Vec3(0, 0, 1)).norm() == 0.0);
    CHECK((up_direction(Vec3(3, 0, 4)) - Vec3(-0.6, 0, -0.8)).norm() <= 1e-15);
    CHECK((up_direction(Vec3::Zero()) - Vec3(0, 0, 1)).norm() == 0.0);
  }

  TEST_CASE("body_pose of a body turned by 30 degrees about x and translated: as by hand") {
    SolidBody b = make_pose_box();
    const Vec3 t(0.3, -0.2, 0.7);
    move_rigidly(b, rotation(Vec3::UnitX(), 30.0 * kDeg), t);
    const BodyPose p = body_pose(b, Vec3::UnitZ());
    CHECK(std::abs(p.rotation_deg - 30.0) <= 1e-9);
    // The centroid moves by t only; the lowest corner is (y, z) = (−1, −1.5) from the centre,
    // at height y sin 30° + z cos 30° = −0.5 − 0.75 √3 below it.
    CHECK(std::abs(p.centroid_height - (1.5 + 0.7)) <= 1e-12);
    CHECK(std::abs(p.lowest - (1.5 + 0.7 - 0.5 - 0.75 * std::sqrt(3.0))) <= 1e-12);
    CHECK(p.lowest <= p.centroid_height);
    // The rotation itself is recovered, not only its angle.
    CHECK((body_rotation(b) - rotation(Vec3::UnitX(), 30.0 * kDeg)).norm() <= 1e-12);
  }

  TEST_CASE("body_pose near 180 degrees: 170 degrees about an oblique axis") {
    SolidBody b = make_pose_box();
    const Mat3 Q = rotation(Vec3(1.0, -2.0, 0.5), 170.0 * kDeg);
    move_rigidly(b, Q, Vec3(-1.0, 2.0, 0.25));
    const BodyPose p = body_pose(b, Vec3::UnitZ());
    CHECK(std::abs(p.rotation_deg - 170.0) <= 1e-9);
    CHECK(std::abs(p.centroid_height - 1.75) <= 1e-12);
    CHECK((body_rotation(b) - Q).norm() <= 1e-12);
    // 180 degrees exactly, and the angle of a matrix given directly.
    CHECK(std::abs(rotation_angle_deg(rotation(Vec3(0, 1, 1), std::numbers::pi)) - 180.0) <= 1e-12);
    CHECK(std::abs(rotation_angle_deg(rotation(Vec3(0, 1, 1), 1e-7)) - 1e-7 / kDeg) <= 1e-15);
  }

  TEST_CASE("body_pose of a uniformly stretched body: no rotation") {
    SolidBody b = make_pose_box();
    for (Index i = 0; i < b.num_nodes(); ++i) {
      const Vec3 X = b.rest_positions().row(i).transpose();
      b.displacement.row(i) = (1.25 * X + Vec3(0.1, 0.2, -0.3) - X).transpose();
    }
    const BodyPose p = body_pose(b, Vec3::UnitZ());
    CHECK(std::abs(p.rotation_deg) <= 1e-12);
    CHECK(std::abs(p.lowest - (-0.3)) <= 1e-12);
    CHECK(std::abs(p.centroid_height - (1.25 * 1.5 - 0.3)) <= 1e-12);
  }

  TEST_CASE("body_pose of a kinematic body: the angle its motion has turned it by") {
    SolidBody b = make_pose_box();
    KinematicMotion k;
    k.angular_velocity = Vec3(0.0, 0.5, 0.0);  // rad/s about y
    k.center = kCentre;
    k.linear_velocity = Vec3(0.0, 0.0, -0.1);
    b.kinematic = k;
    b.set_kinematic_state(2.0);  // 1 rad, 0.2 m down
    const BodyPose p = body_pose(b, Vec3::UnitZ());
    CHECK(std::abs(p.rotation_deg - 1.0 / kDeg) <= 1e-9);
    CHECK(std::abs(p.centroid_height - 1.3) <= 1e-12);
  }
}
