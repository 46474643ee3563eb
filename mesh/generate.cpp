/// @file generate.cpp
/// Structured tet meshes of boxes (Kuhn/Freudenthal split of a hexahedral grid).
#include "mesh/generate.hpp"

#include <array>
#include <utility>

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
  logger().debug("make_box: {} x {} x {} cells, {} vertices, {} tets", cells(0), cells(1),
                 cells(2), m.num_vertices(), m.num_tets());
  return m;
}

}  // namespace tetfsi::mesh
