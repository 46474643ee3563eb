/// @file remesh_lattice.cpp
/// Stages 1–2 of the remesher (remesh_stages.hpp): vertex placement. A graded BCC lattice on
/// a 2:1-balanced octree whose spacing follows the sizing field, lattice points near the
/// refined solid surfaces dropped, the cell budget, and the Delaunay's coordinates.
#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "mesh/remesh_stages.hpp"

namespace tetfsi::mesh::detail {

namespace {

/// Lattice points closer to a solid than this fraction of their local spacing are dropped:
/// the surface vertices take their place (fewer short edges and slivers at the surface).
constexpr double kProtection = 0.5;
/// Points on the box faces are moved within the face by up to this fraction of their
/// spacing (deterministic). A square grid of wall points under the BCC centres makes
/// co-spherical pyramids, each with an interior face of d_f = 0 (458 in a 10³ box); the
/// jitter removes them (0) and keeps the minimum dihedral at 40° (45° without). The same
/// jitter on the faces between octree levels removed most d_f = 0 faces there too but made
/// slivers (min dihedral 0.4°), so those stay exact: the octree transitions keep ~15% of
/// their faces co-spherical (d_f = 0 up to round-off) and no sliver.
constexpr double kWallJitter = 0.1;

/// Sort items by their 64-bit `key` (LSD radix sort, 16-bit digits; digits that every key
/// shares are skipped): several times faster than std::sort on the octree's ~10⁶ items.
/// Items with equal keys keep their relative order (stable).
template <class Item>
void radix_sort_by_key(std::vector<Item>& items) {
  std::vector<Item> tmp(items.size());
  std::vector<std::size_t> count(1 << 16);
  for (int shift = 0; shift < 64; shift += 16) {
    std::fill(count.begin(), count.end(), 0);
    for (const Item& it : items) ++count[(it.key >> shift) & 0xFFFF];
    if (!items.empty() && count[(items[0].key >> shift) & 0xFFFF] == items.size()) continue;
    std::size_t sum = 0;
    for (std::size_t& c : count) {
      const std::size_t n = c;
      c = sum;
      sum += n;
    }
    for (const Item& it : items) tmp[count[(it.key >> shift) & 0xFFFF]++] = it;
    items.swap(tmp);
  }
}

/// The graded lattice: the leaves of an octree over the box (root cubes of at most
/// far_size), split while larger than the size field at their centre, 2:1-balanced.
class Octree {
 public:
  Octree(const FluidDomain& domain, const SolidSet& set, const SizeField& size)
      : m_domain(domain), m_set(set), m_size(size) {
    const Vec3 L = domain.hi - domain.lo;
    for (int a = 0; a < 3; ++a) {
      m_n[a] = std::max(1, static_cast<int>(std::ceil(L(a) / size.far() - 1e-9)));
      m_root(a) = L(a) / m_n[a];
    }
    // One root size for all axes if the box allows it (the box's sides commensurate with a
    // size ≤ far_size, e.g. 1.4 × 1.4 × 0.8 with 0.2): an isotropic lattice (see Lattice).
    double best = 0;
    int best_n[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a)
      for (int N = m_n[a]; N <= 4 * m_n[a]; ++N) {
        const double r = L(a) / N;
        int n[3];
        bool ok = true;
        for (int b = 0; b < 3 && ok; ++b) {
          n[b] = static_cast<int>(std::lround(L(b) / r));
          ok = n[b] >= 1 && std::abs(L(b) / r - n[b]) <= 1e-9 * n[b];
        }
        if (ok && r > best) best = r, std::copy(n, n + 3, best_n);
      }
    if (best > 0) {
      m_isotropic = true;
      for (int a = 0; a < 3; ++a) m_n[a] = best_n[a];
      m_root = Vec3::Constant(best);
    }
    const double rmax = m_root.maxCoeff();
    m_levels = std::max(0, static_cast<int>(std::ceil(std::log2(rmax / size.surface()) - 1e-9)));
    if (size.sizing->refine) m_levels += 3;  // the refinement field may ask for finer cells
    const long long span = static_cast<long long>(*std::max_element(m_n, m_n + 3))
                           << (m_levels + 1);
    TETFSI_REQUIRE(InputError, span < (1LL << 21),
                   "remesh: the sizes span too many levels (domain {:.4g} m, surface size {:.4g} "
                   "m): use a larger surface_size or far_size",
                   L.maxCoeff(), size.surface());
    m_leaves.resize(m_levels + 1);
  }

  Lattice build() {
    // Candidate triangles of each root cube (within the keep radius of subdivide, from the
    // triangle's box): binned, not by testing every triangle against every root.
    const double keep = std::max(0.0, cube_size(0) - m_size.surface()) / m_size.sizing->grading +
                        0.5 * extent(0).norm();
    const std::size_t nroots = static_cast<std::size_t>(m_n[0]) * m_n[1] * m_n[2];
    std::vector<std::vector<int>> cand(nroots);
    for (std::size_t g = 0; g < m_set.corners.size(); ++g) {
      int lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        const double u0 = (m_set.box_lo[g](a) - keep - m_domain.lo(a)) / m_root(a) - 0.5;
        const double u1 = (m_set.box_hi[g](a) + keep - m_domain.lo(a)) / m_root(a) - 0.5;
        lo[a] = std::max(0, static_cast<int>(std::ceil(u0)));
        hi[a] = std::min(m_n[a] - 1, static_cast<int>(std::floor(u1)));
      }
      for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
          for (int i = lo[0]; i <= hi[0]; ++i) {
            const Vec3 c = centre(0, i, j, k);
            const Vec3 d = (m_set.box_lo[g] - c).cwiseMax(c - m_set.box_hi[g]).cwiseMax(0.0);
            if (d.norm() < keep)
              cand[i +
                   static_cast<std::size_t>(m_n[0]) * (j + static_cast<std::size_t>(m_n[1]) * k)]
                  .push_back(static_cast<int>(g));
          }
    }
    // Each root cube's subtree on its own (in parallel), its leaves gathered per level; the
    // sets then hold the same leaves whatever the order (and balance's closure is unique).
    std::vector<std::vector<std::vector<std::uint64_t>>> found(nroots);
    parallel_for_each(static_cast<Index>(nroots), 1, [&](Index r) {
      const int i = static_cast<int>(r % m_n[0]);
      const int j = static_cast<int>((r / m_n[0]) % m_n[1]);
      const int k = static_cast<int>(r / (static_cast<Index>(m_n[0]) * m_n[1]));
      found[r].resize(m_levels + 1);
      subdivide(0, i, j, k, cand[r], found[r]);
    });
    for (const auto& per_root : found)
      for (int l = 0; l <= m_levels; ++l)
        m_leaves[l].insert(per_root[l].begin(), per_root[l].end());
    balance();
    return points();
  }

 private:
  Vec3 extent(int level) const { return m_root / static_cast<double>(1 << level); }
  Vec3 centre(int level, int i, int j, int k) const {
    return m_domain.lo + extent(level).cwiseProduct(Vec3(i + 0.5, j + 0.5, k + 0.5));
  }
  double cube_size(int level) const { return m_root.maxCoeff() / static_cast<double>(1 << level); }

  /// Splits cube (level, i, j, k) while it is larger than the size field; its leaves go to
  /// leaves[level] (one vector per level).
  void subdivide(int level, int i, int j, int k, const std::vector<int>& cand,
                 std::vector<std::vector<std::uint64_t>>& leaves) const {
    const Vec3 c = centre(level, i, j, k);
    const double s = cube_size(level);
    // Split iff s > size(c) = min(far, surface + grading · dist, refine): the distance only
    // matters below (s − surface) / grading, so stop at the first triangle that close, and
    // skip triangles whose box is farther.
    const double reach = (s / (1.0 + 1e-9) - m_size.surface()) / m_size.sizing->grading;
    double dist = kInf;
    if (reach > 0) {
      for (int g : cand) {
        const Vec3 d = (m_set.box_lo[g] - c).cwiseMax(c - m_set.box_hi[g]).cwiseMax(0.0);
        if (d.squaredNorm() >= reach * reach) continue;
        const auto& t = m_set.corners[g];
        dist = std::min(dist, (closest_on_triangle(c, t[0], t[1], t[2]) - c).norm());
        if (dist < reach) break;
      }
    }
    const bool split = level < m_levels && s > m_size.at(c, dist) * (1.0 + 1e-9);
    if (!split) {
      leaves[level].push_back(pack3(i, j, k));
      return;
    }
    const int cl = level + 1;
    const double cs = cube_size(cl);
    const double hd = 0.5 * extent(cl).norm();
    const double keep = std::max(0.0, cs - m_size.surface()) / m_size.sizing->grading + hd;
    std::vector<int> sub;
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const int ci = 2 * i + dx, cj = 2 * j + dy, ck = 2 * k + dz;
          const Vec3 cc = centre(cl, ci, cj, ck);
          sub.clear();
          for (int g : cand) {
            const Vec3 d = (m_set.box_lo[g] - cc).cwiseMax(cc - m_set.box_hi[g]).cwiseMax(0.0);
            if (d.norm() < keep) sub.push_back(g);
          }
          subdivide(cl, ci, cj, ck, sub, leaves);
        }
  }

  /// The leaf containing cube (level, i, j, k)'s region, as its level, or −1 if that cube
  /// is itself subdivided.
  int leaf_level_containing(int level, int i, int j, int k) const {
    // The leaves tile the box, so at most one level holds the cube's region; looked for from
    // the cube's own level down (the neighbours of a leaf are mostly within a level of it).
    for (int l = level; l >= 0; --l) {
      const int sh = level - l;
      if (m_leaves[l].count(pack3(i >> sh, j >> sh, k >> sh))) return l;
    }
    return -1;
  }

  void split_leaf(int level, int i, int j, int k) {
    m_leaves[level].erase(pack3(i, j, k));
    for (int d = 0; d < 8; ++d)
      m_leaves[level + 1].insert(pack3(2 * i + (d & 1), 2 * j + ((d >> 1) & 1), 2 * k + (d >> 2)));
  }

  /// 2:1 balance across faces, edges and corners: neighbouring leaves differ by at most one
  /// level (graded spacing, no abrupt jumps).
  void balance() {
    for (int level = m_levels; level >= 2; --level) {
      std::vector<std::uint64_t> keys(m_leaves[level].begin(), m_leaves[level].end());
      const int n[3] = {m_n[0] << level, m_n[1] << level, m_n[2] << level};
      for (std::uint64_t key : keys) {
        const int i = key & 0x1FFFFF, j = (key >> 21) & 0x1FFFFF, k = (key >> 42) & 0x1FFFFF;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int a = i + dx, b = j + dy, c = k + dz;
              if ((dx | dy | dz) == 0 || a < 0 || b < 0 || c < 0 || a >= n[0] || b >= n[1] ||
                  c >= n[2])
                continue;
              for (;;) {
                const int l = leaf_level_containing(level, a, b, c);
                if (l < 0 || l >= level - 1) break;
                const int sh = level - l;
                split_leaf(l, a >> sh, b >> sh, c >> sh);
              }
            }
      }
    }
  }

  /// Whether every leaf around the lattice point q (units of half the finest spacing) has the
  /// same level and q is a corner of each: wall jitter only there, since jittered wall points
  /// where octree levels meet made slivers (min dihedral 3°).
  bool uniform_around(const std::uint64_t q[3], int fine) const {
    int level = -1;
    for (int d = 0; d < 8; ++d) {
      std::int64_t p[3];
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        p[a] = static_cast<std::int64_t>(q[a]) + ((d >> a & 1) ? 1 : -1);
        inside &= p[a] >= 0 && p[a] < (static_cast<std::int64_t>(m_n[a]) << fine);
      }
      if (!inside) continue;
      int l = m_levels;  // the one leaf holding p, finest levels first
      for (; l >= 0; --l) {
        const int sh = fine - l;
        if (m_leaves[l].count(pack3(p[0] >> sh, p[1] >> sh, p[2] >> sh))) break;
      }
      if (l < 0 || (level >= 0 && l != level)) return false;
      level = l;
    }
    const std::uint64_t step = 1ULL << (fine - level);
    return q[0] % step == 0 && q[1] % step == 0 && q[2] % step == 0;
  }

  /// Per lattice key (pack3 on the grid of half the finest spacing, `fine` levels) of the
  /// corners of leaf faces on the box: the axes its points may not move along (bit a set =
  /// the normal of a box face it lies on).
  std::unordered_map<std::uint64_t, std::uint8_t> box_face_axes(int fine) const {
    std::unordered_map<std::uint64_t, std::uint8_t> fixed;
    for (int level = 0; level <= m_levels; ++level) {
      const std::uint64_t step = 1ULL << (fine - level);
      const int n[3] = {m_n[0] << level, m_n[1] << level, m_n[2] << level};
      for (std::uint64_t key : m_leaves[level]) {
        const int c[3] = {static_cast<int>(key & 0x1FFFFF),
                          static_cast<int>((key >> 21) & 0x1FFFFF),
                          static_cast<int>((key >> 42) & 0x1FFFFF)};
        for (int a = 0; a < 3; ++a)
          for (int side = 0; side < 2; ++side) {
            int nb[3] = {c[0], c[1], c[2]};
            nb[a] += side ? 1 : -1;
            if (nb[a] >= 0 && nb[a] < n[a]) continue;  // not on the box
            const int b1 = (a + 1) % 3, b2 = (a + 2) % 3;
            for (int d = 0; d < 4; ++d) {
              std::uint64_t q[3];
              q[a] = (c[a] + side) * step;
              q[b1] = (c[b1] + (d & 1)) * step;
              q[b2] = (c[b2] + (d >> 1)) * step;
              fixed[pack3(q[0], q[1], q[2])] |= static_cast<std::uint8_t>(1u << a);
            }
          }
      }
    }
    return fixed;
  }

  /// Corners and centres of the leaves (BCC), deduplicated on the integer grid of half the
  /// finest spacing; points on the box faces get the exact face coordinate.
  Lattice points() const {
    struct Item {
      std::uint64_t key;
      double size;
    };
    std::vector<Item> items;
    const int fine = m_levels + 1;  // half-steps of the finest level
    for (int level = 0; level <= m_levels; ++level) {
      const std::uint64_t step = 1ULL << (fine - level);
      const double s = cube_size(level);
      for (std::uint64_t key : m_leaves[level]) {
        const std::uint64_t i = key & 0x1FFFFF, j = (key >> 21) & 0x1FFFFF,
                            k = (key >> 42) & 0x1FFFFF;
        for (int d = 0; d < 8; ++d)
          items.push_back(
              {pack3((i + (d & 1)) * step, (j + ((d >> 1) & 1)) * step, (k + (d >> 2)) * step), s});
        items.push_back({pack3(i * step + step / 2, j * step + step / 2, k * step + step / 2), s});
      }
    }
    // Points on the box faces are jittered within them (kWallJitter); 'fixed' holds the axes
    // they may not move along (the normals of the faces they lie on).
    std::unordered_map<std::uint64_t, std::uint8_t> fixed = box_face_axes(fine);
    // By key, then (a point shared by leaves of several levels) the smallest size first.
    radix_sort_by_key(items);
    for (std::size_t n = 0, m = 0; n < items.size(); n = m) {
      std::size_t best = n;
      for (m = n + 1; m < items.size() && items[m].key == items[n].key; ++m)
        if (items[m].size < items[best].size) best = m;
      std::swap(items[n], items[best]);
    }
    Lattice out;
    out.isotropic = m_isotropic;
    out.unit = m_root(0) / static_cast<double>(1ULL << fine);
    const std::uint64_t qmax[3] = {static_cast<std::uint64_t>(m_n[0]) << fine,
                                   static_cast<std::uint64_t>(m_n[1]) << fine,
                                   static_cast<std::uint64_t>(m_n[2]) << fine};
    const Vec3 unit = m_root / static_cast<double>(1ULL << fine);
    for (std::size_t n = 0; n < items.size(); ++n) {
      if (n > 0 && items[n].key == items[n - 1].key) continue;
      const std::uint64_t q[3] = {items[n].key & 0x1FFFFF, (items[n].key >> 21) & 0x1FFFFF,
                                  (items[n].key >> 42) & 0x1FFFFF};
      Vec3 x;
      for (int a = 0; a < 3; ++a)
        x(a) =
            q[a] == qmax[a] ? m_domain.hi(a) : m_domain.lo(a) + static_cast<double>(q[a]) * unit(a);
      auto fx = fixed.find(items[n].key);
      if (kWallJitter > 0 && fx != fixed.end() && uniform_around(q, fine)) {
        // Points on a patch's rectangle edge stay on it, so lattice-aligned patches are exact.
        for (const DomainPatch& dp : m_domain.patches) {
          int j = 0;
          for (int a = 0; a < 3; ++a) {
            if (a == dp.side / 2) continue;
            if (std::abs(x(a) - dp.lo(j)) < 1e-12 || std::abs(x(a) - dp.hi(j)) < 1e-12)
              fx->second |= static_cast<std::uint8_t>(1u << a);
            ++j;
          }
        }
        // Deterministic jitter (hash of the lattice key), tangential on the box faces.
        std::uint64_t h = items[n].key * 0x9E3779B97F4A7C15ULL;
        for (int a = 0; a < 3; ++a) {
          h ^= h >> 31;
          h *= 0xBF58476D1CE4E5B9ULL;
          h ^= h >> 29;
          const double u = static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0) * 2.0 - 1.0;
          if (!(fx->second >> a & 1) && q[a] != 0 && q[a] != qmax[a])
            x(a) += kWallJitter * items[n].size * u;
        }
      }
      if (m_isotropic) {
        Vec3 y;
        for (int a = 0; a < 3; ++a)
          y(a) = x(a) == (q[a] == qmax[a] ? m_domain.hi(a)
                                          : m_domain.lo(a) + static_cast<double>(q[a]) * unit(a))
                     ? static_cast<double>(q[a])
                     : (x(a) - m_domain.lo(a)) / unit(a);  // jittered
        out.y.push_back(y);
      }
      out.points.push_back(x);
      out.size.push_back(items[n].size);
    }
    return out;
  }

  const FluidDomain& m_domain;
  const SolidSet& m_set;
  const SizeField& m_size;
  int m_n[3];
  Vec3 m_root;
  int m_levels = 0;
  bool m_isotropic = false;
  std::vector<std::unordered_set<std::uint64_t>> m_leaves;  ///< per level
};

/// Drop lattice points inside (or on) a sub-triangle's diametral sphere, or closer to the
/// surface than kProtection × their spacing. Returns the flags (1 = keep).
std::vector<char> exclude_near_surface(const Lattice& lat, const RefinedSurface& surf,
                                       const SizeField& size) {
  std::vector<char> keep(lat.points.size(), 1);
  if (surf.subs.empty()) return keep;
  const double protect = kProtection * 4.0 * size.surface();  // bound on kProtection × spacing
  HashGrid grid(2.0 * size.surface());
  std::vector<Vec3> cs(surf.subs.size());
  std::vector<double> r2s(surf.subs.size()), rs(surf.subs.size());
  for (std::size_t s = 0; s < surf.subs.size(); ++s) {
    const SubTri& st = surf.subs[s];
    if (!st.alive) continue;
    surf.diametral(st, cs[s], r2s[s]);
    rs[s] = std::sqrt(r2s[s]);
    const Vec3 lo = surf.x(st.v[0]).cwiseMin(surf.x(st.v[1])).cwiseMin(surf.x(st.v[2]));
    const Vec3 hi = surf.x(st.v[0]).cwiseMax(surf.x(st.v[1])).cwiseMax(surf.x(st.v[2]));
    const Vec3 rr = Vec3::Constant(rs[s] * (1.0 + 1e-9));
    const Vec3 pp = Vec3::Constant(protect);
    grid.add_box(lo.cwiseMin(cs[s] - rr) - pp, hi.cwiseMax(cs[s] + rr) + pp, static_cast<int>(s));
  }
  // Each point decides its own flag: in parallel, the same flags at any thread count.
  parallel_for_each(static_cast<Index>(lat.points.size()), 4096, [&](Index p) {
    const Vec3& x = lat.points[p];
    const auto* items = grid.at(x);
    if (!items) return;
    const double prot = std::min(protect, kProtection * lat.size[p]);
    for (int s : *items) {
      const double d2 = (x - cs[s]).squaredNorm();
      if (d2 <= r2s[s] * (1.0 + 1e-9)) {
        keep[p] = 0;
        return;
      }
      // The triangle lies in its diametral ball: farther than r + prot from the centre, it is
      // farther than prot from x (with a margin for round-off, so the flag is the same).
      const double far = (rs[s] + prot) * (1.0 + 1e-6);
      if (d2 > far * far) continue;
      const SubTri& st = surf.subs[s];
      if ((closest_on_triangle(x, surf.x(st.v[0]), surf.x(st.v[1]), surf.x(st.v[2])) - x)
              .squaredNorm() < prot * prot) {
        keep[p] = 0;
        return;
      }
    }
  });
  return keep;
}

}  // namespace

void RemeshContext::place_vertices() {
  double last_estimate = -1.0;
  for (int attempt = 0;; ++attempt) {
    // The surface's refinement and the lattice are independent: side by side.
    run_alongside(
        [&] {
          surf = std::make_unique<RefinedSurface>(set);
          refine_surface(*surf, size, 40);
        },
        [&] { lat = Octree(domain, set, size).build(); });
    keep = exclude_near_surface(lat, *surf, size);
    const Index kept = static_cast<Index>(std::count(keep.begin(), keep.end(), 1));
    // A BCC lattice has 6 tets per vertex; near surfaces a little more.
    const double estimate = 6.3 * static_cast<double>(kept + surf->points.size());
    if (sizing.max_cells <= 0 || estimate <= sizing.max_cells || attempt == 6) break;
    double f = 1.02 * std::cbrt(estimate / sizing.max_cells);
    // The octree's levels are a factor 2 apart: a scale that changed nothing must grow more.
    if (last_estimate > 0 && estimate >= 0.99 * last_estimate) f = std::max(f, 1.26);
    last_estimate = estimate;
    size.scale *= f;
    logger().debug(
        "remesh: about {:.0f} cells would exceed the budget of {}: sizes scaled by {:.3g}",
        estimate, sizing.max_cells, size.scale);
  }
  report.size_scale = size.scale;
}

Vec3 RemeshContext::to_dt(const Vec3& x) const {
  // Surface points within 1e-7 lattice units of a lattice plane are put on it: a solid whose
  // faces lie on lattice planes (round numbers) otherwise makes nearly flat cells with lattice
  // points, from round-off alone.
  if (!lat.isotropic) return x;
  Vec3 y = (x - domain.lo) / lat.unit;
  for (int a = 0; a < 3; ++a)
    if (std::abs(y(a) - std::round(y(a))) <= 1e-7) y(a) = std::round(y(a));
  return y;
}

void RemeshContext::collect_points() {
  for (std::size_t p = 0; p < lat.points.size(); ++p)
    if (keep[p]) {
      pts.push_back(lat.points[p]);
      dt_pts.push_back(lat.isotropic ? lat.y[p] : lat.points[p]);
      pt_size.push_back(lat.size[p]);
    }
  nL = static_cast<int>(pts.size());
  report.lattice_points = nL;
  report.surface_points = 0;
  for (int b : surf->body_vertex) report.surface_points += b >= 0;
  for (const SurfacePoint& sp : surf->points) {
    pts.push_back(sp.x);
    dt_pts.push_back(to_dt(sp.x));
  }
}

}  // namespace tetfsi::mesh::detail
