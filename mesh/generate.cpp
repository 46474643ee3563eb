/// @file generate.cpp
/// Structured tet meshes of boxes (Kuhn/Freudenthal split of a hexahedral grid).
#include "mesh/generate.hpp"

#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::mesh {

VolumeMesh make_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells) {
  TETFSI_REQUIRE(InputError, lo.allFinite() && hi.allFinite(),
                 "make_box: corners must be finite, got lo ({} {} {}) and hi ({} {} {})", lo.x(),
                 lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
  for (int a = 0; a < 3; ++a) {
    TETFSI_REQUIRE(InputError, lo(a) < hi(a),
                   "make_box: need lo < hi in every axis, got lo ({} {} {}) and hi ({} {} {}); "
                   "swap or widen the corners",
                   lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
    TETFSI_REQUIRE(InputError, cells(a) >= 1,
                   "make_box: need at least one cell per axis, got cells ({} {} {})", cells(0),
                   cells(1), cells(2));
  }
  const long long nvx = cells(0) + 1LL, nvy = cells(1) + 1LL, nvz = cells(2) + 1LL;
  const long long num_cells = static_cast<long long>(cells(0)) * cells(1) * cells(2);
  TETFSI_REQUIRE(InputError, 6 * num_cells < (1LL << 31) && nvx * nvy * nvz < (1LL << 31),
                 "make_box: {} x {} x {} cells give more tets than an int index can hold; use "
                 "fewer cells",
                 cells(0), cells(1), cells(2));

  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(nvx * nvy * nvz), 3);
  const Vec3 h = (hi - lo).cwiseQuotient(cells.cast<double>());
  for (Index k = 0; k < nvz; ++k) {
    for (Index j = 0; j < nvy; ++j) {
      for (Index i = 0; i < nvx; ++i) {
        const Index v = static_cast<Index>(i + nvx * (j + nvy * k));
        // Exact ends: the last layer sits on hi, not on lo + n·h (rounding).
        m.vertices(v, 0) = i == cells(0) ? hi.x() : lo.x() + i * h.x();
        m.vertices(v, 1) = j == cells(1) ? hi.y() : lo.y() + j * h.y();
        m.vertices(v, 2) = k == cells(2) ? hi.z() : lo.z() + k * h.z();
      }
    }
  }

  // Kuhn split: one tet per permutation (p0, p1, p2) of the axes, the path
  // 0 → e_p0 → e_p0 + e_p1 → (1,1,1) along the cell's main diagonal. Every cell uses the
  // same diagonal direction, so the face diagonals of neighbouring cells agree (conforming).
  // Odd permutations give negative tets; swapping the two middle path vertices fixes them.
  constexpr std::array<std::array<int, 3>, 6> kPerms = {
      {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};
  std::array<std::array<int, 4>, 6> local{};  // corner bit codes (x | y<<1 | z<<2)
  for (int p = 0; p < 6; ++p) {
    int code = 0;
    local[p][0] = code;
    for (int s = 0; s < 3; ++s) {
      code |= 1 << kPerms[p][s];
      local[p][s + 1] = code;
    }
    if (p >= 3) std::swap(local[p][1], local[p][2]);  // odd permutation
  }

  m.tets.resize(static_cast<Index>(6 * num_cells), 4);
  Index t = 0;
  for (Index k = 0; k < cells(2); ++k) {
    for (Index j = 0; j < cells(1); ++j) {
      for (Index i = 0; i < cells(0); ++i) {
        for (int p = 0; p < 6; ++p) {
          for (int c = 0; c < 4; ++c) {
            const int code = local[p][c];
            const long long ii = i + (code & 1), jj = j + ((code >> 1) & 1),
                            kk = k + ((code >> 2) & 1);
            m.tets(t, c) = static_cast<Index>(ii + nvx * (jj + nvy * kk));
          }
          ++t;
        }
      }
    }
  }
  logger().debug("make_box: {} x {} x {} cells, {} vertices, {} tets", cells(0), cells(1), cells(2),
                 m.num_vertices(), m.num_tets());
  return m;
}

SurfaceMesh make_icosphere(const Vec3& centre, double radius, int subdivisions) {
  TETFSI_REQUIRE(InputError, std::isfinite(radius) && radius > 0 && centre.allFinite(),
                 "make_icosphere: need a finite centre and radius > 0, got radius {}", radius);
  TETFSI_REQUIRE(InputError, subdivisions >= 0 && subdivisions <= 7,
                 "make_icosphere: subdivisions must be 0..7, got {}", subdivisions);
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<Vec3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<Vec3i> g;
    g.reserve(4 * f.size());
    for (const auto& tri : f) {
      const int a = midpoint(tri(0), tri(1)), b = midpoint(tri(1), tri(2)),
                c = midpoint(tri(2), tri(0));
      g.insert(g.end(), {{tri(0), a, c}, {tri(1), b, a}, {tri(2), c, b}, {a, b, c}});
    }
    f = std::move(g);
  }
  SurfaceMesh s;
  s.vertices.resize(static_cast<Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i)
    s.vertices.row(static_cast<Index>(i)) = (centre + radius * v[i]).transpose();
  s.triangles.resize(static_cast<Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i)
    s.triangles.row(static_cast<Index>(i)) = f[i].transpose();
  return s;
}

}  // namespace tetfsi::mesh
