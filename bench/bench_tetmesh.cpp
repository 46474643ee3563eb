/// @file bench_tetmesh.cpp
/// `tetfsi_bench_tetmesh [N]`: speed of build_tet_mesh, update_geometry and PointLocator on a
/// jittered make_box mesh of N³ cubes (6 N³ tets; N = 55 gives ~1M), one thread. Each figure
/// is printed with a floor measured in the same run: one pass over the tets that forms and
/// sorts every face's vertex triple (what any face builder must at least do), and, for point
/// location, one barycentric evaluation per query in its known tet.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <random>
#include <vector>

#include "mesh/generate.hpp"
#include "mesh/locate.hpp"
#include "mesh/tet_mesh.hpp"

using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Best of `reps` runs of f (seconds).
template <class F>
double best_of(int reps, F&& f) {
  double best = 1e300;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = Clock::now();
    f();
    best = std::min(best, since(t0));
  }
  return best;
}

/// A make_box mesh of n³ cubes in the unit box with its inner vertices moved by up to 0.15 h.
VolumeMesh jittered_box(int n, std::mt19937& rng) {
  VolumeMesh v = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(n, n, n));
  std::uniform_real_distribution<double> jitter(-0.15 / n, 0.15 / n);
  for (Index i = 0; i < v.num_vertices(); ++i) {
    for (int a = 0; a < 3; ++a) {
      const double x = v.vertices(i, a);
      if (x > 1e-9 && x < 1 - 1e-9) v.vertices(i, a) = x + jitter(rng);
    }
  }
  return v;
}

/// Floor of the face builders (s): form and sort the 4 T face triples (no matching), best of 3;
/// `sink` takes a checksum.
double face_key_floor(const VolumeMesh& v, long long& sink) {
  const Index nt = v.num_tets();
  return best_of(3, [&] {
    for (Index t = 0; t < nt; ++t) {
      for (int k = 0; k < 4; ++k) {
        std::array<int, 3> f{v.tets(t, (k + 1) & 3), v.tets(t, (k + 2) & 3),
                             v.tets(t, (k + 3) & 3)};
        std::sort(f.begin(), f.end());
        sink += f[0] ^ f[1] ^ f[2];
      }
    }
  });
}

/// Times build_tet_mesh and update_geometry of `v` against the face-key floor, prints them and
/// returns the mesh.
TetMesh time_build(const VolumeMesh& v, long long& sink) {
  const Index nt = v.num_tets();
  const double floor_keys = face_key_floor(v, sink);
  TetMesh m;
  const double build = best_of(3, [&] { m = build_tet_mesh(v.vertices, v.tets); });
  const double geometry = best_of(3, [&] { update_geometry(m); });
  std::printf("build_tet_mesh    %.3f s  (%.2f M tets/s; %.1f x the face-key floor %.3f s)\n",
              build, nt / build / 1e6, build / floor_keys, floor_keys);
  std::printf("update_geometry   %.3f s  (%d faces)\n", geometry, m.num_faces());
  return m;
}

/// Good hints: face centroids moved by up to 0.3 h (kept in the unit box), one per face.
std::vector<Vec3> moved_face_centroids(const TetMesh& m, int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> move(-0.3 / n, 0.3 / n);
  const Index nf = m.num_faces();
  std::vector<Vec3> pts(static_cast<std::size_t>(nf));
  for (Index f = 0; f < nf; ++f) {
    pts[static_cast<std::size_t>(f)] =
        (Vec3(m.face_centroids.row(f)) + Vec3(move(rng), move(rng), move(rng)))
            .cwiseMax(0.0)
            .cwiseMin(1.0);
  }
  return pts;
}

/// Times hinted location (each moved face centroid hinted by the face's first tet) against one
/// barycentric evaluation per query, and prints it; `check` takes a checksum.
void time_hinted(const TetMesh& m, const PointLocator& loc, int n, std::mt19937& rng,
                 double& check) {
  const Index nf = m.num_faces();
  const std::vector<Vec3> pts = moved_face_centroids(m, n, rng);
  const double floor_bary = best_of(3, [&] {
    for (Index f = 0; f < nf; ++f) {
      const auto r = m.tets.row(m.face_tets(f, 0));
      const Vec3 p = pts[static_cast<std::size_t>(f)];
      const Vec3 a = Vec3(m.vertices.row(r(0))) - p, b = Vec3(m.vertices.row(r(1))) - p,
                 c = Vec3(m.vertices.row(r(2))) - p, d = Vec3(m.vertices.row(r(3))) - p;
      check += b.dot(c.cross(d)) - a.dot(c.cross(d));
    }
  });
  const double hinted = best_of(3, [&] {
    for (Index f = 0; f < nf; ++f) {
      check += loc.locate(pts[static_cast<std::size_t>(f)], m.face_tets(f, 0)).bary(0);
    }
  });
  auto st = loc.stats();
  std::printf(
      "locate, hinted    %.2f M queries/s  (%.1f x one barycentric evaluation per query; mean "
      "%.2f steps, %lld fallbacks)\n",
      nf / hinted / 1e6, hinted / floor_bary,
      static_cast<double>(st.walk_steps) / static_cast<double>(std::max(1LL, st.walks)),
      st.fallbacks);
}

/// Times location without a hint of 1M random points in the unit box and prints it.
void time_no_hint(const PointLocator& loc, std::mt19937& rng, double& check) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> rnd(1'000'000);
  for (auto& p : rnd) p = Vec3(u(rng), u(rng), u(rng));
  const double nohint = best_of(1, [&] {
    for (const Vec3& p : rnd) check += loc.locate(p).bary(0);
  });
  std::printf("locate, no hint   %.2f M queries/s  (random points in random order)\n",
              rnd.size() / nohint / 1e6);
}

/// Times location of 100k random points outside the unit box (nearest tet) and prints it.
void time_outside(const PointLocator& loc, std::mt19937& rng, double& check) {
  std::uniform_real_distribution<double> wide(-0.5, 1.5);
  std::vector<Vec3> out;
  while (out.size() < 100'000) {
    const Vec3 p(wide(rng), wide(rng), wide(rng));
    if (((p.array() < 0.0) || (p.array() > 1.0)).any()) out.push_back(p);
  }
  const double outside = best_of(1, [&] {
    for (const Vec3& p : out) check += loc.locate(p).distance;
  });
  std::printf("locate, outside   %.2f M queries/s  (nearest tet and distance)\n",
              out.size() / outside / 1e6);
}

}  // namespace

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 55;
  if (n < 2 || n > 200) {
    std::fprintf(stderr, "usage: tetfsi_bench_tetmesh [N in 2..200] (6 N^3 tets)\n");
    return 2;
  }
  std::mt19937 rng(1);
  const VolumeMesh v = jittered_box(n, rng);
  const Index nt = v.num_tets();
  std::printf("jittered box %d^3 cubes: %d vertices, %d tets\n", n, v.num_vertices(), nt);

  long long sink = 0;
  const TetMesh m = time_build(v, sink);
  auto t0 = Clock::now();
  const PointLocator loc(m);
  std::printf("PointLocator      %.3f s  construction\n", since(t0));

  double check = 0.0;
  time_hinted(m, loc, n, rng, check);
  time_no_hint(loc, rng, check);
  time_outside(loc, rng, check);
  std::printf("(checksums %lld %.6g)\n", sink, check);
  return 0;
}
