/// Tests of solid/contact_geometry.cpp: closest points against brute-force sampling, CCD
/// against analytic contact times and against fine time sampling of random motions, and the
/// box tree against O(n²) brute force.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "solid/contact_geometry.hpp"

using namespace tetfsi;
using namespace tetfsi::solid;

namespace {

struct Rng {
  std::mt19937_64 gen;
  explicit Rng(unsigned seed) : gen(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<>(lo, hi)(gen); }
  Vec3 vec(double lo, double hi) { return {uniform(lo, hi), uniform(lo, hi), uniform(lo, hi)}; }
};

/// min over the barycentric grid (i/N, j/N, 1 − (i + j)/N) of |p − x|.
double sampled_point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, int N) {
  double best = INFINITY;
  for (int i = 0; i <= N; ++i) {
    for (int j = 0; i + j <= N; ++j) {
      const double u = double(i) / N, v = double(j) / N;
      best = std::min(best, (p - (u * a + v * b + (1 - u - v) * c)).squaredNorm());
    }
  }
  return std::sqrt(best);
}

/// min over the grid (i/N, j/N) of |p0 + s u − q0 − t v|.
double sampled_edge_edge(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, int N) {
  double best = INFINITY;
  for (int i = 0; i <= N; ++i) {
    const Vec3 x = p0 + (double(i) / N) * (p1 - p0);
    for (int j = 0; j <= N; ++j) {
      best = std::min(best, (x - q0 - (double(j) / N) * (q1 - q0)).squaredNorm());
    }
  }
  return std::sqrt(best);
}

/// Linear motion of n vertices: x(t) = x0 + t (x1 − x0).
Vec3 lerp(const Vec3& x0, const Vec3& x1, double t) {
  return x0 + t * (x1 - x0);
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("contact geometry: point_triangle against dense barycentric sampling") {
    // The grid of spacing h = (longest edge)/N has a point within h of the closest point x*,
    // displaced along the closest feature (face: in the plane; edge: along it; vertex: x*
    // itself), i.e. orthogonal to p − x*: so the sampled minimum is ≤ sqrt(d² + h²), and
    // within 1e-3 relative of d once d ≥ 0.1 × longest edge (N = 200: (h/d)²/2 ≤ 1.25e-3 at
    // worst, 1/4 of it for the nearest grid point).
    Rng rng(11);
    const int N = 200;
    int regions[4] = {0, 0, 0, 0};  // closest point on a vertex, an edge, the face; degenerate
    for (int k = 0; k < 2000; ++k) {
      const Vec3 a = rng.vec(-1, 1), b = rng.vec(-1, 1);
      Vec3 c = rng.vec(-1, 1);
      const bool degenerate = k % 25 == 0;
      if (degenerate) c = k % 50 == 0 ? a : a + rng.uniform(-1, 2) * (b - a);  // collinear
      // p: barycentric coordinates in [−1, 2] (every Voronoi region; a third of the cases
      // over the face: u, v ≥ 0, u + v ≤ 1) plus a normal offset, well off the plane for 3/4
      // of the cases, nearly in it for the rest.
      double u = rng.uniform(-1, 2), v = rng.uniform(-1, 2);
      if (k % 3 == 0) {
        u = rng.uniform(0, 1);
        v = rng.uniform(0, 1);
        if (u + v > 1) {
          u = 1 - u;
          v = 1 - v;
        }
      }
      Vec3 n = (b - a).cross(c - a);
      n = n.norm() > 0 ? n.normalized() : Vec3(rng.vec(-1, 1).normalized());
      const double e = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
      const bool far = k % 4 != 0;
      const double off = far ? rng.uniform(0.2, 1.0) * e : rng.uniform(-0.01, 0.01) * e;
      const Vec3 p = u * a + v * b + (1 - u - v) * c + (rng.uniform(0, 1) < 0.5 ? off : -off) * n;

      const PointTriangle r = point_triangle(p, a, b, c);
      const double sampled = sampled_point_triangle(p, a, b, c, N);
      const double h = e / N;
      CHECK(r.distance <= sampled + 1e-12);  // never above the sampled minimum (round-off)
      CHECK(sampled <= std::sqrt(r.distance * r.distance + h * h) + 1e-12);
      if (far) CHECK(sampled - r.distance <= 1e-3 * sampled);
      double sum = 0;
      int zeros = 0;
      for (double w : r.w) {
        CHECK(w >= 0.0);
        CHECK(w <= 1.0);
        sum += w;
        zeros += w == 0.0;
      }
      CHECK(std::abs(sum - 1.0) <= 1e-14);
      CHECK((r.closest - (r.w[0] * a + r.w[1] * b + r.w[2] * c)).norm() <= 1e-14);
      CHECK(std::abs((p - r.closest).norm() - r.distance) <= 1e-14);
      ++regions[degenerate ? 3 : 2 - std::min(zeros, 2)];
    }
    MESSAGE("closest on a vertex / an edge / the face / degenerate: ", regions[0], " / ",
            regions[1], " / ", regions[2], " / ", regions[3]);
    CHECK(std::min({regions[0], regions[1], regions[2]}) >= 200);
  }

  TEST_CASE("contact geometry: edge_edge against brute-force sampling") {
    // The grid (i/N, j/N) has a point within (|u| + |v|)/(2N) of a closest pair, displaced
    // orthogonally to their difference: sampled ≤ sqrt(d² + h²) with h = (|u| + |v|)/N.
    Rng rng(12);
    const int N = 300;
    int checked_relative = 0;
    for (int k = 0; k < 1000; ++k) {
      Vec3 p0 = rng.vec(-1, 1), p1 = rng.vec(-1, 1), q0 = rng.vec(-1, 1), q1 = rng.vec(-1, 1);
      switch (k % 8) {
        case 1:  // parallel, offset
          q1 = q0 + rng.uniform(-2, 2) * (p1 - p0);
          break;
        case 2:  // collinear, overlapping or not
          q0 = p0 + rng.uniform(-1, 2) * (p1 - p0);
          q1 = p0 + rng.uniform(-1, 2) * (p1 - p0);
          break;
        case 3:  // p a point
          p1 = p0;
          break;
        case 4:  // q a point
          q1 = q0;
          break;
        case 5:  // both points
          p1 = p0;
          q1 = q0;
          break;
        case 6:  // crossing: q0q1 through a point of p0p1, distance 0
          q1 = 2 * lerp(p0, p1, rng.uniform(0, 1)) - q0;
          break;
        default:
          break;
      }
      const EdgeEdge r = edge_edge(p0, p1, q0, q1);
      const double sampled = sampled_edge_edge(p0, p1, q0, q1, N);
      const double len = (p1 - p0).norm() + (q1 - q0).norm(), h = len / N;
      CHECK(r.s >= 0.0);
      CHECK(r.s <= 1.0);
      CHECK(r.t >= 0.0);
      CHECK(r.t <= 1.0);
      CHECK(std::abs((lerp(p0, p1, r.s) - lerp(q0, q1, r.t)).norm() - r.distance) <= 1e-14);
      CHECK(r.distance <= sampled + 1e-12);
      CHECK(sampled <= std::sqrt(r.distance * r.distance + h * h) + 1e-12);
      if (r.distance >= 0.1 * len) {
        CHECK(sampled - r.distance <= 1e-3 * sampled);
        ++checked_relative;
      }
      if (k % 8 == 6) CHECK(r.distance <= 1e-12);
    }
    CHECK(checked_relative >= 300);
  }

  TEST_CASE("contact geometry: CCD of a point falling through and sliding into a triangle") {
    const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
    for (double tol : {1e-3, 0.0}) {
      // Falling through the face at speed 2: d = 1 − 2t reaches tol at (1 − tol)/2. The result
      // is never after that and at most 1e-6 relative before it.
      const double t_fall = (1 - tol) / 2;
      CcdReport rep;
      const double t =
          ccd_point_triangle(Vec3(0.2, 0.3, 1), a, b, c, Vec3(0.2, 0.3, -1), a, b, c, tol, &rep);
      CHECK(t <= t_fall + 1e-15);
      CHECK(t >= t_fall * (1 - 1e-6));
      CHECK_FALSE(rep.capped);
      // The same relative motion with the triangle rising and the point still.
      const Vec3 up(0, 0, 2);
      const double t2 = ccd_point_triangle(Vec3(0.2, 0.3, 1), a, b, c, Vec3(0.2, 0.3, 1), a + up,
                                           b + up, c + up, tol, nullptr);
      CHECK(t2 <= t_fall + 1e-15);
      CHECK(t2 >= t_fall * (1 - 1e-6));
      // Coplanar: sliding in the triangle's plane into its edge x = 0 (d = 1 − 2t again).
      const double t3 =
          ccd_point_triangle(Vec3(-1, 0.3, 0), a, b, c, Vec3(1, 0.3, 0), a, b, c, tol, nullptr);
      CHECK(t3 <= t_fall + 1e-15);
      CHECK(t3 >= t_fall * (1 - 1e-6));
    }
    // Zero motion: a hit at 0 if within tol, none otherwise.
    const double tol = 1e-3;
    const Vec3 near(0.2, 0.2, 0.5 * tol), far(0.2, 0.2, 2 * tol);
    CHECK(ccd_point_triangle(near, a, b, c, near, a, b, c, tol) == 0.0);
    CHECK(ccd_point_triangle(far, a, b, c, far, a, b, c, tol) == -1.0);
    // A common translation of all four vertices (L = 0 after removing it): no hit.
    const Vec3 shift(3, -2, 7);
    CHECK(ccd_point_triangle(far, a, b, c, far + shift, a + shift, b + shift, c + shift, tol) ==
          -1.0);
  }

  TEST_CASE("contact geometry: CCD of a point passing beside a triangle is not a hit") {
    // Clear of the triangle by 2 tol all along: beside the hypotenuse x + y = 1 (falling
    // through its plane, and sliding along it in the plane), and above the face.
    const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
    const double tol = 1e-3, s = std::sqrt(2.0) * tol;  // (0.5 + s, 0.5 + s): 2 tol from it
    const Vec3 beside(0.5 + s, 0.5 + s, 0);
    CHECK(ccd_point_triangle(beside + Vec3(0, 0, 1), a, b, c, beside - Vec3(0, 0, 1), a, b, c,
                             tol) == -1.0);
    CHECK(ccd_point_triangle(beside + Vec3(-1, 1, 0), a, b, c, beside + Vec3(1, -1, 0), a, b, c,
                             tol) == -1.0);
    CHECK(ccd_point_triangle(Vec3(-1, 0.2, 2 * tol), a, b, c, Vec3(2, 0.2, 2 * tol), a, b, c,
                             tol) == -1.0);
  }

  TEST_CASE("contact geometry: CCD of crossing and parallel edges") {
    const double tol = 1e-3;
    const Vec3 q0(0, -1, 0), q1(0, 1, 0);  // fixed, along y
    for (double tl : {tol, 0.0}) {
      // Along x, swept from z = 1 to z = −1 through q: d = 1 − 2t reaches tl at (1 − tl)/2.
      const double t_hit = (1 - tl) / 2;
      const double t = ccd_edge_edge(Vec3(-1, 0, 1), Vec3(1, 0, 1), q0, q1, Vec3(-1, 0, -1),
                                     Vec3(1, 0, -1), q0, q1, tl);
      CHECK(t <= t_hit + 1e-15);
      CHECK(t >= t_hit * (1 - 1e-6));
    }
    // Parallel to q (along y), 2 tol away in x, sliding past it along y: no hit.
    const Vec3 dx(2 * tol, 0, 0);
    CHECK(ccd_edge_edge(dx + Vec3(0, -3, 0), dx + Vec3(0, -2, 0), q0, q1, dx + Vec3(0, 2, 0),
                        dx + Vec3(0, 3, 0), q0, q1, tol) == -1.0);
    // Parallel and overlapping, approaching from x = 1 to x = −1: touch at (1 − tol)/2.
    const double t_par = ccd_edge_edge(Vec3(1, -0.5, 0), Vec3(1, 0.5, 0), q0, q1, Vec3(-1, -0.5, 0),
                                       Vec3(-1, 0.5, 0), q0, q1, tol);
    CHECK(t_par <= (1 - tol) / 2 + 1e-15);
    CHECK(t_par >= (1 - tol) / 2 * (1 - 1e-6));
    // Collinear, end to end: the upper end moves from y = −3 to y = 1, reaching q0 − tol at
    // y = −1 − tol, t = (2 − tol)/4.
    const double t_col = ccd_edge_edge(Vec3(0, -4, 0), Vec3(0, -3, 0), q0, q1, Vec3(0, 0, 0),
                                       Vec3(0, 1, 0), q0, q1, tol);
    CHECK(t_col <= (2 - tol) / 4 + 1e-15);
    CHECK(t_col >= (2 - tol) / 4 * (1 - 1e-6));
  }

  TEST_CASE("contact geometry: CCD against fine time sampling of random motions") {
    // For random linear motions (generic, coplanar, one primitive still, parallel edges) and
    // 1000 time samples s_i: if some d(s_i) ≤ tol the CCD reports a hit at t ≤ the first such
    // s_i (slack 1e-12: the time round-off, nothing more: conservative advancement never steps
    // over the first touch); whenever it reports t (not capped), d(t) ≤ tol (1 + 1e-6) + 1e-12
    // (the stopping gap is 1e-7 tol + 1e-12 (d(0) + L), d(0) + L < 10 here).
    Rng rng(13);
    const double tol = 0.02;
    int hits = 0, misses = 0, capped = 0, max_iterations = 0;
    const auto check = [&](const std::function<double(double)>& d, double t, const CcdReport& rep) {
      double first = -1;
      for (int i = 0; i < 1000 && first < 0; ++i) {
        if (d(i / 999.0) <= tol) first = i / 999.0;
      }
      if (first >= 0) {
        CHECK(t >= 0);
        CHECK(t <= first + 1e-12);
      }
      if (t >= 0 && !rep.capped) CHECK(d(t) <= tol * (1 + 1e-6) + 1e-12);
      (t >= 0 ? hits : misses) += 1;
      capped += rep.capped;
      max_iterations = std::max(max_iterations, rep.iterations);
    };
    for (int k = 0; k < 4000; ++k) {
      std::array<Vec3, 4> x0, x1;
      for (int i = 0; i < 4; ++i) {
        x0[i] = rng.vec(0, 1);
        x1[i] = x0[i] + rng.vec(-0.6, 0.6);
      }
      const int variant = (k / 2) % 4;
      if (variant == 1) {  // coplanar motion
        for (int i = 0; i < 4; ++i) x0[i].z() = x1[i].z() = 0.5;
      } else if (variant == 2) {  // the triangle / the second edge still
        x1[1] = x0[1];
        x1[2] = x0[2];
        x1[3] = x0[3];
      }
      CcdReport rep;
      if (k % 2 == 0) {
        const double t =
            ccd_point_triangle(x0[0], x0[1], x0[2], x0[3], x1[0], x1[1], x1[2], x1[3], tol, &rep);
        check(
            [&](double s) {
              return point_triangle(lerp(x0[0], x1[0], s), lerp(x0[1], x1[1], s),
                                    lerp(x0[2], x1[2], s), lerp(x0[3], x1[3], s))
                  .distance;
            },
            t, rep);
      } else {
        if (variant == 3) {  // parallel edges, moving parallel
          x0[3] = x0[2] + (x0[1] - x0[0]);
          x1[3] = x1[2] + (x1[1] - x1[0]);
        }
        const double t =
            ccd_edge_edge(x0[0], x0[1], x0[2], x0[3], x1[0], x1[1], x1[2], x1[3], tol, &rep);
        check(
            [&](double s) {
              return edge_edge(lerp(x0[0], x1[0], s), lerp(x0[1], x1[1], s), lerp(x0[2], x1[2], s),
                               lerp(x0[3], x1[3], s))
                  .distance;
            },
            t, rep);
      }
    }
    MESSAGE("hits ", hits, ", misses ", misses, ", capped ", capped, ", most iterations ",
            max_iterations);
    CHECK(hits >= 500);
    CHECK(misses >= 500);
  }

  TEST_CASE("contact geometry: BoxTree query pairs and self_pairs equal brute force") {
    Rng rng(14);
    const auto random_boxes = [&](int n) {
      std::vector<Box> boxes(n);
      for (int i = 0; i < n; ++i) {
        boxes[i].extend(rng.vec(0, 1));
        if (i % 10 != 0) boxes[i].extend(boxes[i].lo + rng.vec(0, 0.1));  // some are points
        if (i % 7 == 0 && i > 0) boxes[i] = boxes[i - 1];                 // duplicates
        if (i % 11 == 0 && i > 0) {  // sharing a face with the previous box (closed: overlap)
          boxes[i] = boxes[i - 1];
          const double w = boxes[i].hi.x() - boxes[i].lo.x();
          boxes[i].lo.x() += w;
          boxes[i].hi.x() += w;
        }
      }
      return boxes;
    };
    const std::vector<Box> A = random_boxes(3000), B = random_boxes(2000);
    BoxTree ta, tb, empty;
    ta.build(A);
    tb.build(B);
    empty.build({});
    CHECK(ta.size() == 3000);

    std::vector<std::pair<Index, Index>> brute, got;
    for (Index i = 0; i < 3000; ++i) {
      for (Index j = 0; j < 2000; ++j) {
        if (A[i].overlaps(B[j])) brute.emplace_back(i, j);
      }
    }
    ta.pairs(tb, got);
    CHECK(got == brute);
    brute.clear();
    got.clear();
    for (Index i = 0; i < 3000; ++i) {
      for (Index j = i + 1; j < 3000; ++j) {
        if (A[i].overlaps(A[j])) brute.emplace_back(i, j);
      }
    }
    ta.self_pairs(got);
    CHECK(got == brute);
    MESSAGE("pairs within 3000 boxes: ", brute.size());
    CHECK(brute.size() >= 3000);

    for (int k = 0; k < 200; ++k) {
      Box q;
      q.extend(rng.vec(-0.1, 1.1));
      q.extend(q.lo + rng.vec(0, 0.3));
      std::vector<Index> expect, found{-7};  // appended to: the -7 stays first
      for (Index i = 0; i < 3000; ++i) {
        if (A[i].overlaps(q)) expect.push_back(i);
      }
      ta.query(q, found);
      expect.insert(expect.begin(), -7);
      CHECK(found == expect);
    }
    got.clear();
    empty.pairs(ta, got);
    ta.pairs(empty, got);
    empty.self_pairs(got);
    CHECK(got.empty());
  }

  TEST_CASE("contact geometry: Box extend inflate and closed overlaps") {
    Box b;
    CHECK_FALSE(b.overlaps(b));  // empty
    b.extend(Vec3(0, 0, 0));
    b.extend(Vec3(1, 2, 3));
    CHECK(b.lo == Vec3(0, 0, 0));
    CHECK(b.hi == Vec3(1, 2, 3));
    Box touching;
    touching.extend(Vec3(1, 2, 3));
    touching.extend(Vec3(2, 3, 4));
    CHECK(b.overlaps(touching));
    Box apart = touching;
    apart.lo.x() = 1.5;
    CHECK_FALSE(b.overlaps(apart));
    apart.inflate(0.5);
    CHECK(apart.lo == Vec3(1.0, 1.5, 2.5));
    CHECK(b.overlaps(apart));
  }
}
