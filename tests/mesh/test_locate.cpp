/// Tests of mesh/locate.cpp: PointLocator on random points with good, bad and no hints, on
/// vertices and faces, outside the mesh and in a hole, from two threads.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include "mesh/generate.hpp"
#include "mesh/locate.hpp"
#include "mesh/tet_mesh.hpp"

using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

/// make_box of [0, 1]³ with interior vertices jittered by up to `amount` × cell size (fixed
/// seed): the outer boundary stays the unit cube, tets are irregular.
TetMesh jittered_unit_box(int n, double amount, unsigned seed = 11) {
  VolumeMesh v = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(n, n, n));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount / n, amount / n);
  for (Index i = 0; i < v.num_vertices(); ++i) {
    for (int a = 0; a < 3; ++a) {
      const double x = v.vertices(i, a);
      if (x > 1e-9 && x < 1 - 1e-9) v.vertices(i, a) = x + u(rng);
    }
  }
  return build_tet_mesh(v.vertices, v.tets);
}

Vec3 point_of(const TetMesh& m, const Location& l) {
  Vec3 x = Vec3::Zero();
  for (int k = 0; k < 4; ++k) x += l.bary(k) * Vec3(m.vertices.row(m.tets(l.tet, k)));
  return x;
}

/// Barycentric coordinates of p in tet t by an independent route: solve the 3 × 3 system.
Vec4 solve_bary(const TetMesh& m, Index t, const Vec3& p) {
  const Vec3 a = m.vertices.row(m.tets(t, 0));
  Mat3 E;
  for (int k = 0; k < 3; ++k) E.col(k) = Vec3(m.vertices.row(m.tets(t, k + 1))) - a;
  const Vec3 l = E.fullPivLu().solve(p - a);
  return Vec4(1 - l.sum(), l(0), l(1), l(2));
}

/// The located tet really contains p: the returned and the independently solved barycentric
/// coordinates are ≥ −1e-10, sum to 1 and reconstruct p to 1e-12 (unit-size mesh).
void check_inside(const TetMesh& m, const Location& l, const Vec3& p) {
  REQUIRE(l.tet >= 0);
  CHECK(l.inside);
  CHECK(l.distance == 0.0);
  CHECK(l.bary.minCoeff() >= -1e-10);
  CHECK(std::abs(l.bary.sum() - 1.0) <= 1e-12);
  CHECK((point_of(m, l) - p).norm() <= 1e-12);
  CHECK(solve_bary(m, l.tet, p).minCoeff() >= -1e-10);
}

/// Distance from p to triangle (a, b, c) by a route independent of the locator's: the plane
/// projection if it falls inside the triangle, else the nearest of the three edges.
double distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a).normalized();
  const Vec3 q = p - n.dot(p - a) * n;
  const auto side = [&](const Vec3& u, const Vec3& v) { return n.dot((v - u).cross(q - u)); };
  if (side(a, b) >= 0 && side(b, c) >= 0 && side(c, a) >= 0) return (p - q).norm();
  const auto seg = [&](const Vec3& u, const Vec3& v) {
    const double s = std::clamp((p - u).dot(v - u) / (v - u).squaredNorm(), 0.0, 1.0);
    return (p - (u + s * (v - u))).norm();
  };
  return std::min({seg(a, b), seg(b, c), seg(c, a)});
}

/// Distance from p to the union of all tets (0 inside one, 1e-10 tolerance), by brute force.
double brute_force_distance(const TetMesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (Index t = 0; t < m.num_tets(); ++t) {
    if (solve_bary(m, t, p).minCoeff() >= -1e-10) return 0.0;
    const auto x = [&](int k) { return Vec3(m.vertices.row(m.tets(t, k))); };
    best = std::min(
        {best, distance_to_triangle(p, x(1), x(2), x(3)), distance_to_triangle(p, x(0), x(2), x(3)),
         distance_to_triangle(p, x(0), x(1), x(3)), distance_to_triangle(p, x(0), x(1), x(2))});
  }
  return best;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("PointLocator: random points in a jittered box with no hint and bad hints") {
    const TetMesh m = jittered_unit_box(10, 0.15);
    const PointLocator loc(m);
    std::mt19937 rng(2024);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Index far_tet = m.num_tets() - 1;  // the opposite corner of the box from tet 0
    for (int i = 0; i < 10000; ++i) {
      const Vec3 p(u(rng), u(rng), u(rng));
      check_inside(m, loc.locate(p), p);
      check_inside(m, loc.locate(p, 0), p);
      check_inside(m, loc.locate(p, far_tet), p);
      check_inside(m, loc.locate(p, m.num_tets() + 5), p);  // out of range: as no hint
    }
    const auto st = loc.stats();
    CHECK(st.outside == 0);
    CHECK(st.walks + st.fallbacks >= 40000);
  }

  TEST_CASE("PointLocator: good hints in a slightly moved mesh") {
    // The semi-Lagrangian use: face centroids of a mesh, moved a little, located in the old
    // mesh starting from the tet the face belongs to.
    const TetMesh m = jittered_unit_box(12, 0.15);
    const PointLocator loc(m);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-0.3 / 12, 0.3 / 12);
    long long checked = 0;
    for (Index f = 0; f < m.num_faces(); ++f) {
      Vec3 p = Vec3(m.face_centroids.row(f)) + Vec3(u(rng), u(rng), u(rng));
      p = p.cwiseMax(0.0).cwiseMin(1.0);
      const Location l = loc.locate(p, m.face_tets(f, 0));
      check_inside(m, l, p);
      ++checked;
    }
    const auto st = loc.stats();
    CHECK(checked == m.num_faces());
    CHECK(st.fallbacks == 0);  // a convex mesh: every walk arrives
    CHECK(st.walks == checked);
    // Short walks from good hints: a few steps on average.
    CHECK(static_cast<double>(st.walk_steps) / static_cast<double>(st.walks) < 3.0);
  }

  TEST_CASE("PointLocator: points exactly on vertices edges and faces") {
    const TetMesh m = jittered_unit_box(5, 0.15);
    const PointLocator loc(m);
    for (Index v = 0; v < m.num_vertices(); ++v) {
      const Vec3 p = m.vertices.row(v);
      check_inside(m, loc.locate(p), p);
      check_inside(m, loc.locate(p, static_cast<Index>(v % m.num_tets())), p);
    }
    for (Index f = 0; f < m.num_faces(); ++f) {
      const Vec3 p = m.face_centroids.row(f);
      check_inside(m, loc.locate(p), p);
      const Vec3 e =
          0.5 * (Vec3(m.vertices.row(m.faces(f, 0))) + Vec3(m.vertices.row(m.faces(f, 1))));
      check_inside(m, loc.locate(e, m.face_tets(f, 0)), e);
    }
    CHECK(loc.stats().outside == 0);
  }

  TEST_CASE("PointLocator: points outside the box get the nearest tet and distance") {
    const TetMesh m = jittered_unit_box(6, 0.15);
    const PointLocator loc(m);
    struct Case {
      Vec3 p, nearest;
    };
    // Axis-aligned cases with exact answers: the nearest point of the unit cube is the clamp.
    const std::vector<Case> cases = {{Vec3(1.5, 0.5, 0.5), Vec3(1.0, 0.5, 0.5)},
                                     {Vec3(-0.25, 0.3, 0.7), Vec3(0.0, 0.3, 0.7)},
                                     {Vec3(0.2, 0.4, -2.0), Vec3(0.2, 0.4, 0.0)},
                                     {Vec3(-1, -1, -1), Vec3(0, 0, 0)},
                                     {Vec3(2.0, 0.5, 3.0), Vec3(1.0, 0.5, 1.0)},
                                     {Vec3(100.0, 0.3, 0.2), Vec3(1.0, 0.3, 0.2)},
                                     {Vec3(0.5, 1.0 + 1e-6, 0.5), Vec3(0.5, 1.0, 0.5)}};
    for (const Case& c : cases) {
      CAPTURE(c.p.transpose());
      for (const Index hint : {Index{-1}, Index{0}, m.num_tets() / 2}) {
        const Location l = loc.locate(c.p, hint);
        REQUIRE(l.tet >= 0);
        CHECK_FALSE(l.inside);
        const double d = (c.p - c.nearest).norm();
        CHECK(std::abs(l.distance - d) <= 1e-12 * std::max(1.0, d));
        // Barycentrics of the nearest point: clamped, summing to 1, reconstructing it.
        CHECK(l.bary.minCoeff() >= 0.0);
        CHECK(l.bary.maxCoeff() <= 1.0);
        CHECK(std::abs(l.bary.sum() - 1.0) <= 1e-12);
        CHECK((point_of(m, l) - c.nearest).norm() <= 1e-12 * std::max(1.0, d));
      }
    }
    CHECK(loc.stats().outside == 3 * static_cast<long long>(cases.size()));
    // Just inside the tolerance: a point 1e-14 outside a wall face counts as inside.
    const Location l = loc.locate(Vec3(0.5, 1.0 + 1e-14, 0.5));
    CHECK(l.inside);
  }

  TEST_CASE("PointLocator: a mesh with a hole") {
    // [0, 1]³ in 6³ cubes without the central 2³ block: the hole is [1/3, 2/3]³.
    const VolumeMesh box = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(6, 6, 6));
    std::vector<Index> keep;
    for (Index t = 0; t < box.num_tets(); ++t) {
      const Index cube = t / 6;  // make_box writes 6 tets per cube, cubes in i-fastest order
      const int i = cube % 6, j = (cube / 6) % 6, k = cube / 36;
      if (!(i >= 2 && i <= 3 && j >= 2 && j <= 3 && k >= 2 && k <= 3)) keep.push_back(t);
    }
    MatX4i tets(static_cast<Index>(keep.size()), 4);
    for (std::size_t r = 0; r < keep.size(); ++r)
      tets.row(static_cast<Index>(r)) = box.tets.row(keep[r]);
    const TetMesh m = build_tet_mesh(box.vertices, tets);
    CHECK(std::abs(total_volume(m) - (1.0 - 1.0 / 27.0)) <= 1e-12);
    const PointLocator loc(m);
    std::mt19937 rng(99);
    std::uniform_real_distribution<double> u(1.0 / 3.0 + 1e-3, 2.0 / 3.0 - 1e-3);
    for (int i = 0; i < 2000; ++i) {
      const Vec3 p(u(rng), u(rng), u(rng));
      // Distance from inside the cubic hole to its walls: through the nearest face.
      double d = 1.0;
      for (int a = 0; a < 3; ++a) d = std::min({d, p(a) - 1.0 / 3.0, 2.0 / 3.0 - p(a)});
      for (const Index hint : {Index{-1}, Index{0}, m.num_tets() / 2}) {
        const Location l = loc.locate(p, hint);
        REQUIRE(l.tet >= 0);
        CHECK_FALSE(l.inside);
        CHECK(std::abs(l.distance - d) <= 1e-12);
        CHECK(std::abs((point_of(m, l) - p).norm() - d) <= 1e-12);
      }
    }
    // Points of the solid part around the hole are found, whatever the hint.
    std::uniform_real_distribution<double> w(0.0, 1.0);
    int found = 0;
    for (int i = 0; i < 5000; ++i) {
      const Vec3 p(w(rng), w(rng), w(rng));
      if ((p.array() > 1.0 / 3.0).all() && (p.array() < 2.0 / 3.0).all()) continue;
      check_inside(m, loc.locate(p, static_cast<Index>(i % m.num_tets())), p);
      ++found;
    }
    CHECK(found > 4000);
  }

  TEST_CASE("PointLocator: nearest tet agrees with brute force on a swiss-cheese mesh") {
    // A jittered box with 40 % of its cubes removed at random: many holes and tunnels, a
    // non-convex outside, walks that leave the mesh all the time. The locator's answer must
    // match a brute-force search over every tet: inside where some tet contains the point,
    // else the same distance (1e-12).
    VolumeMesh box = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(7, 7, 7));
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> j(-0.1 / 7, 0.1 / 7);
    for (Index i = 0; i < box.num_vertices(); ++i) {
      for (int a = 0; a < 3; ++a) box.vertices(i, a) += j(rng);  // boundary too: nothing is flat
    }
    std::bernoulli_distribution drop(0.4);
    std::vector<Index> keep;
    for (Index cube = 0; cube < box.num_tets() / 6; ++cube) {
      if (drop(rng)) continue;
      for (Index t = 6 * cube; t < 6 * cube + 6; ++t) keep.push_back(t);
    }
    MatX4i tets(static_cast<Index>(keep.size()), 4);
    for (std::size_t r = 0; r < keep.size(); ++r) {
      tets.row(static_cast<Index>(r)) = box.tets.row(keep[r]);
    }
    const TetMesh m = build_tet_mesh(box.vertices, tets);
    const PointLocator loc(m);
    std::uniform_real_distribution<double> u(-0.4, 1.4);
    int inside = 0, outside = 0;
    for (int i = 0; i < 1500; ++i) {
      const Vec3 p(u(rng), u(rng), u(rng));
      const double d = brute_force_distance(m, p);
      const Location l = loc.locate(p, static_cast<Index>((i * 7919) % m.num_tets()));
      REQUIRE(l.tet >= 0);
      CHECK(l.inside == (d == 0.0));
      if (d == 0.0) {
        check_inside(m, l, p);
        ++inside;
      } else {
        CHECK(std::abs(l.distance - d) <= 1e-12);
        CHECK(std::abs((point_of(m, l) - p).norm() - d) <= 1e-12);
        ++outside;
      }
    }
    CHECK(inside > 100);
    CHECK(outside > 100);
  }

  TEST_CASE("PointLocator: two threads get the same answers as one") {
    const TetMesh m = jittered_unit_box(8, 0.15);
    const PointLocator loc(m);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.2, 1.2);  // some outside
    std::vector<Vec3> pts(20000);
    for (auto& p : pts) p = Vec3(u(rng), u(rng), u(rng));
    std::vector<Location> serial(pts.size()), parallel(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) serial[i] = loc.locate(pts[i]);
    const auto before = loc.stats();
    const auto work = [&](std::size_t begin) {
      for (std::size_t i = begin; i < pts.size(); i += 2) parallel[i] = loc.locate(pts[i]);
    };
    std::thread a(work, 0), b(work, 1);
    a.join();
    b.join();
    long long outside = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      CHECK(parallel[i].tet == serial[i].tet);
      CHECK(parallel[i].inside == serial[i].inside);
      CHECK(parallel[i].bary == serial[i].bary);
      outside += !serial[i].inside;
    }
    // The atomic counters saw every query of both threads.
    CHECK(loc.stats().outside - before.outside == outside);
    CHECK(outside > 0);
  }

  TEST_CASE("PointLocator: moved locator and empty mesh") {
    const TetMesh m = jittered_unit_box(3, 0.1);
    PointLocator a(m);
    PointLocator b(std::move(a));
    check_inside(m, b.locate(Vec3(0.3, 0.6, 0.9)), Vec3(0.3, 0.6, 0.9));
    const TetMesh empty = build_tet_mesh(MatX3(0, 3), MatX4i(0, 4));
    const PointLocator e(empty);
    const Location l = e.locate(Vec3(0, 0, 0));
    CHECK(l.tet == -1);
    CHECK_FALSE(l.inside);
  }

}  // TEST_SUITE
