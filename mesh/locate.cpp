/// @file locate.cpp
/// Point location in a TetMesh: a visibility walk from a hint [DPT02], with a uniform grid of
/// tet bounding boxes as the fallback and for the nearest tet of points outside the mesh.
///
/// [DPT02] O. Devillers, S. Pion, M. Teillaud. Walking in a triangulation. International
///   Journal of Foundations of Computer Science 13(2) (2002) 181–199.
/// [Ericson05] C. Ericson. Real-Time Collision Detection. Morgan Kaufmann, 2005, §5.1.5.
#include "mesh/locate.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Geometry>  // cross()

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/geometry.hpp"

namespace tetfsi::mesh {

namespace {

/// "Inside" tolerance on barycentric coordinates (relative to the tet's size).
constexpr double kInsideTol = 1e-10;
/// Target number of tets per grid bucket (by volume; a tet overlaps several buckets).
constexpr double kTetsPerBucket = 6.0;

/// Local faces of a tet with outward normals; face k opposite vertex k.
constexpr int kOutwardFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

inline Vec3 vertex(const TetMesh& m, Index v) {
  const double* x = m.vertices.data() + 3 * static_cast<std::ptrdiff_t>(v);
  return {x[0], x[1], x[2]};
}

/// Barycentric coordinates of p in tet t: λ_k = 6 vol(tet with vertex k replaced by p) / 6 V,
/// from triple products of the vertices relative to p (accurate near p), normalised by their
/// sum so that Σ λ_k = 1 to rounding. A degenerate tet gives non-finite values.
inline Vec4 barycentric(const TetMesh& m, Index t, const Vec3& p) {
  const int* r = m.tets.data() + 4 * static_cast<std::ptrdiff_t>(t);
  const Vec3 A = vertex(m, r[0]) - p, B = vertex(m, r[1]) - p, C = vertex(m, r[2]) - p,
             D = vertex(m, r[3]) - p;
  const Vec3 cd = C.cross(D), bd = B.cross(D), bc = B.cross(C);
  const Vec4 w(B.dot(cd), -A.dot(cd), A.dot(bd), -A.dot(bc));
  return w / w.sum();
}

}  // namespace

struct PointLocator::Impl {
  const TetMesh* mesh = nullptr;
  // Uniform grid over the mesh's bounding box; bucket (i, j, k) = i + n0 (j + n1 k) holds
  // every tet whose (slightly enlarged) bounding box overlaps it (CSR: start/items).
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero(), size = Vec3::Ones(), inv_size = Vec3::Ones();
  std::array<int, 3> dims{1, 1, 1};
  std::vector<int> start, items;
  std::vector<int> seed;  ///< per bucket: a tet whose centroid is in it (else any), −1 if empty
  int max_steps = 100;
  double slack = 0.0;  ///< bbox enlargement (m): covers the "inside" tolerance

  mutable std::atomic<long long> walks{0}, walk_steps{0}, fallbacks{0}, outside{0};

  explicit Impl(const TetMesh& m);
  /// lo, hi, slack, dims, size, inv_size from the tets' bounding box.
  void set_grid(const TetMesh& m);
  std::array<int, 3> cell_of(const Vec3& p) const {
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) {
      // floor(x) < 0 iff x < 0, and ≥ dims iff x ≥ dims; between, the cast is the floor
      // (std::floor would be a call to libm in code built for x86-64's baseline)
      const double x = (p(a) - lo(a)) * inv_size(a);
      c[a] = x < 0.0 ? 0 : (x >= dims[a] ? dims[a] - 1 : static_cast<int>(x));
    }
    return c;
  }
  int bucket(int i, int j, int k) const { return i + dims[0] * (j + dims[1] * k); }
  bool in_box(const Vec3& p) const {
    return (p.array() >= (lo.array() - slack)).all() && (p.array() <= (hi.array() + slack)).all();
  }
  Location walk(const Vec3& p, Index t, bool& ok) const;
  Location scan_bucket(const Vec3& p, bool& ok) const;
  Location nearest(const Vec3& p) const;
};

PointLocator::Impl::Impl(const TetMesh& m) : mesh(&m) {
  const Index nt = m.num_tets();
  if (nt == 0) return;
  max_steps = static_cast<int>(10.0 * std::cbrt(static_cast<double>(nt))) + 100;
  set_grid(m);
  // Each bucket's tets in increasing order (CSR), grouped in parallel.
  const auto range = [&](Index t, std::array<int, 3>& c0, std::array<int, 3>& c1) {
    Vec3 a = vertex(m, m.tets(t, 0)), b = a;
    for (int k = 1; k < 4; ++k) {
      const Vec3 x = vertex(m, m.tets(t, k));
      a = a.cwiseMin(x);
      b = b.cwiseMax(x);
    }
    const double e = 1e-8 * (b - a).maxCoeff() + slack;
    c0 = cell_of(a - Vec3::Constant(e));
    c1 = cell_of(b + Vec3::Constant(e));
  };
  const Index nb = dims[0] * dims[1] * dims[2];
  group_by_key(
      nt, nb,
      [&](Index t, auto&& emit) {
        std::array<int, 3> c0{}, c1{};
        range(t, c0, c1);
        for (int k = c0[2]; k <= c1[2]; ++k)
          for (int j = c0[1]; j <= c1[1]; ++j)
            for (int i = c0[0]; i <= c1[0]; ++i) emit(bucket(i, j, k));
      },
      start, items);
  // A bucket's seed: its last tet whose centroid lies in it (walks from it are shortest),
  // else its first tet. A tet's centroid bucket is among its buckets.
  std::vector<int> home(static_cast<std::size_t>(nt));
  parallel_for_each(nt, 16384, [&](Index t) {
    Vec3 centroid = Vec3::Zero();
    for (int k = 0; k < 4; ++k) centroid += vertex(m, m.tets(t, k));
    const auto c = cell_of(0.25 * centroid);
    home[static_cast<std::size_t>(t)] = bucket(c[0], c[1], c[2]);
  });
  seed.assign(static_cast<std::size_t>(nb), -1);
  parallel_for_each(nb, 16384, [&](Index b) {
    const int first = start[static_cast<std::size_t>(b)],
              end = start[static_cast<std::size_t>(b) + 1];
    if (first == end) return;
    int& s = seed[static_cast<std::size_t>(b)];
    s = items[static_cast<std::size_t>(first)];
    for (int q = end - 1; q >= first; --q)
      if (home[static_cast<std::size_t>(items[static_cast<std::size_t>(q)])] == b) {
        s = items[static_cast<std::size_t>(q)];
        break;
      }
  });
}

void PointLocator::Impl::set_grid(const TetMesh& m) {
  const Index nt = m.num_tets();
  // The bounding box of the tets' vertices: per chunk, then combined (min / max are exact).
  const Index grain = 65536;
  std::vector<Vec3> part_lo(static_cast<std::size_t>(num_chunks(nt, grain))), part_hi(part_lo);
  parallel_for_chunks(nt, grain, [&](Index begin, Index end) {
    Vec3 l = Vec3::Constant(std::numeric_limits<double>::infinity()), h = -l;
    for (Index t = begin; t < end; ++t)
      for (int k = 0; k < 4; ++k) {
        const Vec3 x = vertex(m, m.tets(t, k));
        l = l.cwiseMin(x);
        h = h.cwiseMax(x);
      }
    part_lo[static_cast<std::size_t>(begin / grain)] = l;
    part_hi[static_cast<std::size_t>(begin / grain)] = h;
  });
  lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  for (std::size_t c = 0; c < part_lo.size(); ++c) {
    lo = lo.cwiseMin(part_lo[c]);
    hi = hi.cwiseMax(part_hi[c]);
  }
  const Vec3 ext = (hi - lo).cwiseMax(1e-12 * (hi - lo).norm() + 1e-300);
  slack = 1e-9 * ext.maxCoeff();
  // Bucket edge from the mean volume per tet; per-axis counts capped so the grid stays
  // O(#T) even for very flat boxes.
  const double h = std::cbrt(ext.prod() * kTetsPerBucket / static_cast<double>(nt));
  double total = 1.0;
  for (int a = 0; a < 3; ++a) {
    dims[a] = static_cast<int>(std::clamp(std::ceil(ext(a) / h), 1.0, 2048.0));
    total *= dims[a];
  }
  while (total > 4.0 * static_cast<double>(nt) + 64) {
    total = 1.0;
    for (int a = 0; a < 3; ++a) {
      dims[a] = std::max(1, dims[a] / 2);
      total *= dims[a];
    }
  }
  for (int a = 0; a < 3; ++a) {
    size(a) = ext(a) / dims[a];
    inv_size(a) = 1.0 / size(a);
  }
}

Location PointLocator::Impl::walk(const Vec3& p, Index t, bool& ok) const {
  const TetMesh& m = *mesh;
  Index prev = -1;
  ok = false;
  for (int step = 0; step < max_steps; ++step) {
    const Vec4 l = barycentric(m, t, p);
    // Visibility walk [DPT02]: leave through any face that has p on its outer side, trying
    // the faces from a varying start so that no fixed choice can cycle forever; never step
    // straight back.
    const int k0 = static_cast<int>((static_cast<unsigned>(t) * 2654435761u + step) >> 30);
    int exit = -1;
    for (int i = 0; i < 4; ++i) {
      const int k = (k0 + i) & 3;
      if (l(k) < -kInsideTol && (step == 0 || m.neighbours(t, k) != prev)) {
        exit = k;
        break;
      }
    }
    if (exit < 0) {
      if ((l.array() >= -kInsideTol).all()) {  // not NaN either
        walk_steps.fetch_add(step, std::memory_order_relaxed);
        walks.fetch_add(1, std::memory_order_relaxed);
        ok = true;
        return Location{t, l, true, 0.0};
      }
      break;  // only the way back is left (or a degenerate tet): give up
    }
    const Index next = m.neighbours(t, exit);
    if (next < 0) break;  // p is beyond the boundary as seen from here
    prev = t;
    t = next;
  }
  return {};
}

Location PointLocator::Impl::scan_bucket(const Vec3& p, bool& ok) const {
  ok = false;
  if (!in_box(p)) return {};
  const auto c = cell_of(p);
  const int b = bucket(c[0], c[1], c[2]);
  for (int i = start[static_cast<std::size_t>(b)]; i < start[static_cast<std::size_t>(b) + 1];
       ++i) {
    const Index t = items[static_cast<std::size_t>(i)];
    const Vec4 l = barycentric(*mesh, t, p);
    if ((l.array() >= -kInsideTol).all()) {
      ok = true;
      return Location{t, l, true, 0.0};
    }
  }
  return {};
}

Location PointLocator::Impl::nearest(const Vec3& p) const {
  const TetMesh& m = *mesh;
  const auto c = cell_of(p);
  // Distance from p to the grid box per axis (0 inside): every tet point is at least that far.
  Vec3 out = Vec3::Zero();
  for (int a = 0; a < 3; ++a) out(a) = std::max({lo(a) - p(a), p(a) - hi(a), 0.0});
  Location best;
  best.distance = std::numeric_limits<double>::infinity();
  const auto visit = [&](int b) {
    for (int i = start[static_cast<std::size_t>(b)]; i < start[static_cast<std::size_t>(b) + 1];
         ++i) {
      const Index t = items[static_cast<std::size_t>(i)];
      const Vec4 l = barycentric(m, t, p);
      const int* r = m.tets.data() + 4 * static_cast<std::ptrdiff_t>(t);
      for (int k = 0; k < 4; ++k) {
        if (!(l(k) < 0.0)) continue;  // the nearest point is on a face p is outside of
        const int* f = kOutwardFace[k];
        Vec3 bc;
        const Vec3 q =
            closest_on_triangle(p, vertex(m, r[f[0]]), vertex(m, r[f[1]]), vertex(m, r[f[2]]), bc);
        const double d = (q - p).norm();
        if (d < best.distance) {
          best.tet = t;
          best.distance = d;
          best.bary.setZero();
          for (int j = 0; j < 3; ++j) best.bary(f[j]) = std::clamp(bc(j), 0.0, 1.0);
          best.bary /= best.bary.sum();
        }
      }
    }
  };
  for (int r = 0;; ++r) {
    const int i0 = std::max(0, c[0] - r), i1 = std::min(dims[0] - 1, c[0] + r);
    const int j0 = std::max(0, c[1] - r), j1 = std::min(dims[1] - 1, c[1] + r);
    const int k0 = std::max(0, c[2] - r), k1 = std::min(dims[2] - 1, c[2] + r);
    // The shell of buckets at Chebyshev distance exactly r from c (clipped to the grid).
    for (int k = k0; k <= k1; ++k) {
      const bool kface = std::abs(k - c[2]) == r;
      for (int j = j0; j <= j1; ++j) {
        const bool jface = kface || std::abs(j - c[1]) == r;
        if (jface) {
          for (int i = i0; i <= i1; ++i) visit(bucket(i, j, k));
        } else {
          if (c[0] - r >= 0) visit(bucket(c[0] - r, j, k));
          if (r > 0 && c[0] + r < dims[0]) visit(bucket(c[0] + r, j, k));
        }
      }
    }
    // Every unvisited tet lies outside the block of rings 0..r: leaving it through a side
    // not on the grid boundary costs at least that side's gap, plus the distance to the grid
    // box in the other two axes.
    const std::array<int, 3> bl = {i0, j0, k0}, bh = {i1, j1, k1};
    double bound2 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      const double others = out.squaredNorm() - out(a) * out(a);
      if (bl[a] > 0) {
        const double gap = std::max(0.0, p(a) - (lo(a) + bl[a] * size(a)));
        bound2 = std::min(bound2, gap * gap + others);
      }
      if (bh[a] < dims[a] - 1) {
        const double gap = std::max(0.0, lo(a) + (bh[a] + 1) * size(a) - p(a));
        bound2 = std::min(bound2, gap * gap + others);
      }
    }
    if (!std::isfinite(bound2)) break;  // the block covers the grid
    if (best.tet >= 0 && best.distance * best.distance <= bound2) break;
  }
  best.inside = false;
  return best;
}

PointLocator::PointLocator(const TetMesh& mesh) : m_impl(std::make_unique<Impl>(mesh)) {}
PointLocator::~PointLocator() = default;
PointLocator::PointLocator(PointLocator&&) noexcept = default;
PointLocator& PointLocator::operator=(PointLocator&&) noexcept = default;

Location PointLocator::locate(const Vec3& p, Index hint, bool nearest_if_outside) const {
  const Impl& s = *m_impl;
  const TetMesh& m = *s.mesh;
  if (m.num_tets() == 0) return {};
  const bool in_box = s.in_box(p);
  if (in_box) {
    if (hint < 0 || hint >= m.num_tets()) {
      const auto c = s.cell_of(p);
      hint = s.seed[static_cast<std::size_t>(s.bucket(c[0], c[1], c[2]))];
    }
    bool ok = false;
    if (hint >= 0) {
      Location l = s.walk(p, hint, ok);
      if (ok) return l;
    }
    s.fallbacks.fetch_add(1, std::memory_order_relaxed);
    Location l = s.scan_bucket(p, ok);
    if (ok) return l;
  }
  s.outside.fetch_add(1, std::memory_order_relaxed);
  if (!nearest_if_outside) return Location{};
  return s.nearest(p);
}

PointLocator::Stats PointLocator::stats() const {
  const Impl& s = *m_impl;
  Stats out;
  out.walks = s.walks.load(std::memory_order_relaxed);
  out.walk_steps = s.walk_steps.load(std::memory_order_relaxed);
  out.fallbacks = s.fallbacks.load(std::memory_order_relaxed);
  out.outside = s.outside.load(std::memory_order_relaxed);
  return out;
}

}  // namespace tetfsi::mesh
