/// Tests of solid/kinematic.cpp and the kinematic path of SolidWorld::step: exact rotations,
/// rigidity at any time, velocity = d/dt position, and a world with a kinematic and a
/// deformable body stepped together.
#include <doctest/doctest.h>

#include <cmath>

#include "core/error.hpp"
#include "solid/kinematic.hpp"
#include "solid/world.hpp"
#include "solid_test_utils.hpp"
#include "tests/test_util.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

namespace {

/// A motion with every part non-trivial: translation, an oblique axis, an off-origin centre.
KinematicMotion tumbling() {
  KinematicMotion k;
  k.linear_velocity = Vec3(0.3, -0.2, 0.5);
  k.angular_velocity = Vec3(1.0, 2.0, -0.5);  // rad/s
  k.center = Vec3(0.4, -1.0, 2.0);
  return k;
}

/// Rest positions of a few points spread around the centre.
MatX3 sample_points() {
  MatX3 X(6, 3);
  X << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1.5, -2, 0.3, -0.7, 0.2, 3.1;
  return X;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("KinematicMotion: a quarter turn about z lands exactly, through the centre") {
    KinematicMotion k;
    k.angular_velocity = Vec3(0, 0, M_PI / 2);  // 90° per second
    k.center = Vec3(1, 1, 0);
    const double t = 1.0;
    // (2, 1, 0) is 1 m along +x from the centre: a quarter turn takes it to +y of the centre.
    CHECK((k.position(Vec3(2, 1, 0), t) - Vec3(1, 2, 0)).norm() < 1e-12);
    CHECK((k.position(Vec3(1, 1, 5), t) - Vec3(1, 1, 5)).norm() < 1e-12);  // on the axis
    CHECK((k.position(Vec3(1, 3, -1), t) - Vec3(-1, 1, -1)).norm() < 1e-12);
    // With a translation on top, the centre moves with v t.
    k.linear_velocity = Vec3(0.5, 0, 2);
    CHECK((k.position(Vec3(2, 1, 0), t) - Vec3(1.5, 2, 2)).norm() < 1e-12);
    // R(t) is orthonormal with det 1; R(0) = I; ω = 0 gives pure translation.
    const Mat3 R = tumbling().rotation(0.7);
    CHECK((R.transpose() * R - Mat3::Identity()).norm() < 1e-14);
    CHECK(R.determinant() == doctest::Approx(1.0).epsilon(1e-14));
    CHECK((tumbling().rotation(0.0) - Mat3::Identity()).norm() == 0.0);
    KinematicMotion slide;
    slide.linear_velocity = Vec3(1, 2, 3);
    CHECK((slide.position(Vec3(1, 1, 1), 2.0) - Vec3(3, 5, 7)).norm() < 1e-15);
    CHECK((slide.velocity(Vec3(1, 1, 1), 2.0) - Vec3(1, 2, 3)).norm() == 0.0);
  }

  TEST_CASE("KinematicMotion: distances between nodes are preserved at every time") {
    const KinematicMotion k = tumbling();
    const MatX3 X = sample_points();
    for (int step = 0; step <= 400; ++step) {
      const double t = 0.137 * step;  // up to ~55 s: many turns, no drift (closed form)
      const MatX3 x = k.position(X, t);
      for (Index i = 0; i < X.rows(); ++i) {
        // The MatX3 overload agrees with the one-node one.
        CHECK((x.row(i).transpose() - k.position(Vec3(X.row(i).transpose()), t)).norm() < 1e-14);
        for (Index j = i + 1; j < X.rows(); ++j) {
          const double rest = (X.row(i) - X.row(j)).norm();
          CHECK(std::abs((x.row(i) - x.row(j)).norm() - rest) <= 1e-12 * rest);
        }
      }
      // The centre travels with v t.
      CHECK((k.position(k.center, t) - (k.center + k.linear_velocity * t)).norm() < 1e-12);
    }
  }

  TEST_CASE("KinematicMotion: velocity is the time derivative of the position") {
    const KinematicMotion k = tumbling();
    const MatX3 X = sample_points();
    const double dt = 1e-5;
    for (double t : {0.0, 0.3, 1.7, 12.5}) {
      const MatX3 u = k.velocity(X, t);
      const MatX3 fd = (k.position(X, t + dt) - k.position(X, t - dt)) / (2 * dt);
      for (Index i = 0; i < X.rows(); ++i) {
        CAPTURE(t);
        CAPTURE(i);
        const Vec3 ui = u.row(i).transpose();
        CHECK((ui - fd.row(i).transpose()).norm() <= 1e-6 * ui.norm());
        CHECK((ui - k.velocity(Vec3(X.row(i).transpose()), t)).norm() < 1e-14);
        // u = v + ω × (x − c − v t).
        const Vec3 x = k.position(Vec3(X.row(i).transpose()), t);
        const Vec3 expected =
            k.linear_velocity + k.angular_velocity.cross(x - k.center - k.linear_velocity * t);
        CHECK((ui - expected).norm() < 1e-12);
      }
    }
  }

  TEST_CASE("SolidWorld: a kinematic body follows its path exactly next to a deformable one") {
    SolidWorld w;
    w.gravity = Vec3(0, 0, -9.81);
    w.linear_solver = SolverKind::Umfpack;
    const Material mat = make_material(1000.0, 1e5, 0.3, 0.0, 0.0);
    w.bodies.push_back(
        make_box_body("falling", Vec3(0, 0, 0), Vec3(1, 1, 0.2), Vec3i(2, 2, 1), mat));
    w.bodies.push_back(
        make_box_body("paddle", Vec3(3, 0, 0), Vec3(4, 0.2, 1), Vec3i(2, 1, 2), mat));
    KinematicMotion k;
    k.linear_velocity = Vec3(0.1, 0, 0.2);
    k.angular_velocity = Vec3(0, 0, 2.0);
    k.center = w.bodies[1].rest_positions().colwise().mean().transpose();
    w.bodies[1].kinematic = k;
    w.set_kinematic_states();
    CHECK(w.bodies[1].displacement.isZero(0.0));
    CHECK((w.bodies[1].velocity - k.velocity(w.bodies[1].rest_positions(), 0.0)).norm() == 0.0);
    CHECK(w.bodies[1].is_kinematic());
    CHECK_FALSE(w.bodies[0].is_kinematic());

    const double h = 0.01;
    const int n = 25;
    PhaseTimes times;
    for (int i = 0; i < n; ++i) {
      const SolidStepReport rep = w.step(h, times);
      CHECK(rep.converged);
    }
    CHECK(w.time == doctest::Approx(n * h).epsilon(1e-14));
    // The kinematic body is on its path at t = n h, to round-off.
    const SolidBody& p = w.bodies[1];
    const MatX3& X = p.rest_positions();
    CHECK((p.positions() - k.position(X, w.time)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((p.velocity - k.velocity(X, w.time)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(p.elastic_energy() == doctest::Approx(0.0).epsilon(1e-12));  // rigid: no strain
    // The deformable body fell under gravity (free fall: z̄ = −g t²/2 to first order in h).
    const SolidBody& f = w.bodies[0];
    const double zbar = f.displacement.col(2).mean();
    CHECK(zbar < 0.0);
    CHECK(zbar == doctest::Approx(-0.5 * 9.81 * w.time * w.time).epsilon(0.1));
  }

  TEST_CASE("SolidWorld: a kinematic body with pins or loads is an input error naming it") {
    const Material mat = make_material(1000.0, 1e5, 0.3);
    PhaseTimes times;
    {
      SolidWorld w;
      w.bodies.push_back(
          make_box_body("paddle", Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1), mat));
      w.bodies[0].kinematic = KinematicMotion{};
      w.bodies[0].pin_node(0);
      const std::string m = test::message_of<InputError>([&] { w.step(0.01, times); });
      CHECK(m.find("body 'paddle' is kinematic: it cannot have pins") != std::string::npos);
      CHECK(w.time == 0.0);
    }
    {
      SolidWorld w;
      w.bodies.push_back(
          make_box_body("paddle", Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1), mat));
      w.bodies[0].kinematic = KinematicMotion{};
      w.bodies[0].applied_force(3, 2) = 1.0;
      const std::string m = test::message_of<InputError>([&] { w.step(0.01, times); });
      CHECK(m.find("body 'paddle' is kinematic: it cannot have loads") != std::string::npos);
    }
  }
}  // TEST_SUITE
