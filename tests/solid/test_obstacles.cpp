/// Tests of solid/obstacles.cpp: the contact law (projection, restitution, Coulomb friction)
/// on planes and boxes, and bodies dropped and slid on a floor through SolidWorld.
#include <doctest/doctest.h>

#include <cmath>

#include "core/error.hpp"
#include "solid/obstacles.hpp"
#include "solid/world.hpp"
#include "solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;
using namespace tetfsi::solid::testing;

namespace {

SolidBody unit_tet() {
  mesh::VolumeMesh tet;
  tet.vertices.resize(4, 3);
  tet.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  tet.tets.resize(1, 4);
  tet.tets << 0, 1, 2, 3;
  return SolidBody("tet", tet, make_material(1000.0, 1e5, 0.3));
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("contact law: projection with restitution and Coulomb friction on a plane") {
    struct Case {
      double e, mu;
      Vec3 expected;  // velocity after contact of a node arriving with (1, 0, −2) m/s
    };
    // Δu_n = (1 + e)·2; the tangential speed 1 is reduced by min(1, μ Δu_n).
    for (const Case& c : {Case{0.0, 0.0, Vec3(1, 0, 0)}, Case{1.0, 0.0, Vec3(1, 0, 2)},
                          Case{0.0, 0.25, Vec3(0.5, 0, 0)}, Case{0.5, 0.2, Vec3(0.4, 0, 1)},
                          Case{0.0, 1.0, Vec3(0, 0, 0)}}) {
      SolidBody b = unit_tet();
      b.velocity.rowwise() = Vec3(1.0, 0.0, -2.0).transpose();
      const Index contacts = resolve_collisions(b, {floor_plane(0.2, c.e, c.mu)});
      CHECK(contacts == 3);  // nodes 0, 1, 2 lie at z = 0 < 0.2
      for (Index i = 0; i < 3; ++i) {
        CHECK(b.positions()(i, 2) == doctest::Approx(0.2).epsilon(1e-15));
        CHECK((b.velocity.row(i).transpose() - c.expected).norm() <= 1e-15);
      }
      CHECK(b.displacement.row(3).norm() == 0.0);  // node 3 (z = 1) is untouched
      CHECK((b.velocity.row(3).transpose() - Vec3(1, 0, -2)).norm() == 0.0);
    }
    // A receding node is projected but keeps its velocity; a pinned node is left alone.
    SolidBody b = unit_tet();
    b.velocity.rowwise() = Vec3(1.0, 0.0, 3.0).transpose();
    b.pin_node(0);
    CHECK(resolve_collisions(b, {floor_plane(0.2, 0.5, 0.5)}) == 2);
    CHECK(b.displacement.row(0).norm() == 0.0);
    CHECK((b.velocity.row(1).transpose() - Vec3(1, 0, 3)).norm() == 0.0);
    CHECK(b.positions()(1, 2) == doctest::Approx(0.2).epsilon(1e-15));
    // Bad parameters are input errors naming the obstacle.
    Obstacle bad = floor_plane(0.0, 1.5, 0.0);
    CHECK_THROWS_AS(resolve_collisions(b, {bad}), InputError);
  }

  TEST_CASE("contact law: a node inside a box leaves through the nearest face") {
    SolidBody b = unit_tet();
    b.velocity.rowwise() = Vec3(0.0, 0.0, -1.0).transpose();
    Obstacle box;
    box.kind = Obstacle::Kind::Box;
    box.name = "table";
    box.lo = Vec3(-1.0, -1.0, -1.0);
    box.hi = Vec3(2.0, 2.0, 0.1);
    box.restitution = 0.0;
    CHECK(resolve_collisions(b, {box}) == 3);
    for (Index i = 0; i < 3; ++i) {
      CHECK(b.positions()(i, 2) == doctest::Approx(0.1).epsilon(1e-15));
      CHECK(b.velocity.row(i).norm() == 0.0);
    }
    CHECK(b.positions()(3, 2) == 1.0);
  }

  TEST_CASE("a box dropped on a plane stops at the plane") {
    SolidWorld world;
    world.gravity = Vec3(0, 0, -9.81);
    world.obstacles.push_back(floor_plane(0.0, 0.0, 0.5));
    world.bodies.push_back(make_box_body("box", Vec3(0, 0, 0.05), Vec3(0.1, 0.1, 0.15),
                                         Vec3i(2, 2, 2),
                                         make_material(1000.0, 1e5, 0.3, 0.0, 1e-2)));
    const SolidBody& b = world.bodies[0];
    PhaseTimes times;
    const double h = 1e-3;
    double lowest = 1.0;
    SolidStepReport rep;
    for (int n = 0; n < 1000; ++n) {
      rep = world.step(h, times);
      lowest = std::min(lowest, b.positions().col(2).minCoeff());
    }
    // The bottom face rests on the plane: 9 nodes in contact, none below it, nearly at rest.
    MESSAGE("dropped box: lowest node z over the run " << lowest << " m, final COM speed "
                                                       << com_velocity(b).norm() << " m/s");
    CHECK(lowest >= -1e-12);
    CHECK(rep.contacts == 9);
    CHECK(com_velocity(b).norm() < 1e-3);
    CHECK(com(b).z() == doctest::Approx(0.05).epsilon(0.01));  // sag under own weight is tiny
  }

  TEST_CASE("restitution 1 vs 0 on a single falling tet: the momentum balance of the contact law") {
    // Restitution acts per node. A single tet falls face down: its three base nodes (3/4 of
    // the mass) hit the floor together at speed v and leave with e·v while the apex still
    // moves at −v. With its internal mode critically damped (β = 2/ω, ω ≈ 2e3 rad/s) the tet
    // then moves as one "point" that conserves momentum: the centre of mass leaves at
    // v' = (3e − 1) v / 4, so e = 1 rebounds to (1/2)² = 1/4 of the drop height and e = 0 not
    // at all (it settles). The step resolves the internal mode (ωh ≈ 0.02): projection then
    // injects only O((ωh)²) of energy (a stiff, unresolved tet would be launched by it).
    auto rebound = [](double e) {
      mesh::VolumeMesh tet;
      tet.vertices.resize(4, 3);
      tet.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
      tet.vertices *= 0.02;
      tet.vertices.col(2).array() += 0.2;  // base 0.2 m above the floor
      tet.tets.resize(1, 4);
      tet.tets << 0, 1, 2, 3;
      SolidWorld world;
      world.gravity = Vec3(0, 0, -9.81);
      world.obstacles.push_back(floor_plane(0.0, e, 0.0));
      world.bodies.emplace_back("pebble", tet, make_material(1000.0, 1e6, 0.3, 0.0, 1e-3));
      const SolidBody& b = world.bodies[0];
      PhaseTimes times;
      const double h = 1e-5;
      const double z0 = com(b).z(), rest_height = z0 - 0.2;
      bool hit = false;
      double v_impact = 0.0, z_max_after = -1.0;
      for (int n = 0; n < 35000; ++n) {  // 0.35 s: fall 0.2 s, rebound to the top ≈ 0.1 s
        const double v_before = com_velocity(b).z();
        const SolidStepReport rep = world.step(h, times);
        if (!hit && rep.contacts > 0) v_impact = -v_before;
        hit = hit || rep.contacts > 0;
        if (hit) z_max_after = std::max(z_max_after, com(b).z());
      }
      MESSAGE("e = " << e << ": impact speed " << v_impact << " m/s (free fall "
                     << std::sqrt(2 * 9.81 * 0.2) << ")");
      return (z_max_after - rest_height) / (z0 - rest_height);  // rebound / drop height
    };
    const double r1 = rebound(1.0), r0 = rebound(0.0);
    MESSAGE("rebound height / drop height: e = 1: " << r1 << " (rigid prediction 0.25), e = 0: "
                                                    << r0 << " (prediction 0)");
    CHECK(r1 == doctest::Approx(0.25).epsilon(0.05));
    CHECK(r0 < 0.01);
  }

  TEST_CASE("Coulomb friction stops a sliding box after about v0^2 / (2 mu g)") {
    auto slide = [](double mu, double& stop_time) {
      SolidWorld world;
      world.gravity = Vec3(0, 0, -9.81);
      world.obstacles.push_back(floor_plane(0.0, 0.0, mu));
      world.bodies.push_back(make_box_body("slider", Vec3(0, 0, 0), Vec3(0.1, 0.1, 0.05),
                                           Vec3i(2, 2, 1),
                                           make_material(1000.0, 1e6, 0.3, 0.0, 1e-3)));
      SolidBody& b = world.bodies[0];
      b.velocity.col(0).setConstant(1.0);  // v0 = 1 m/s along x
      PhaseTimes times;
      const double h = 1e-3;
      stop_time = -1.0;
      for (int n = 0; n < 400; ++n) {
        world.step(h, times);
        if (stop_time < 0.0 && com_velocity(b).x() < 1e-3) stop_time = (n + 1) * h;
      }
      return com(b).x() - 0.05;
    };
    double t_stop = 0.0, t_none = 0.0;
    const double mu = 0.5, g = 9.81;
    const double dist = slide(mu, t_stop);
    const double free_dist = slide(0.0, t_none);
    // Rigid block on a rough floor: stops after t = v0/(μg), s = v0²/(2μg).
    MESSAGE("friction mu = 0.5: slid "
            << dist << " m (rigid " << 1.0 / (2 * mu * g) << " m), stopped after " << t_stop
            << " s (rigid " << 1.0 / (mu * g) << " s); mu = 0 slid " << free_dist << " m");
    CHECK(t_stop > 0.0);
    CHECK(dist == doctest::Approx(1.0 / (2 * mu * g)).epsilon(0.1));
    CHECK(t_stop == doctest::Approx(1.0 / (mu * g)).epsilon(0.1));
    CHECK(free_dist == doctest::Approx(0.4).epsilon(0.01));  // v0 · 0.4 s, frictionless
  }

}  // TEST_SUITE
