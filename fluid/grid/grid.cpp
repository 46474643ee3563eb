#include "fluid/grid/grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/parallel.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;

// ---- GridSpec ----------------------------------------------------------------------------

GridSpec GridSpec::from_cells(const Vec3& lo, const Vec3& hi, const std::array<Index, 3>& n) {
  GridSpec g;
  g.lo = lo;
  g.n = n;
  for (int a = 0; a < 3; ++a) {
    TETFSI_REQUIRE(InputError, n[a] >= 1, "fluid.grid.cells: {} cells along {}: use at least 1",
                   n[a], "xyz"[a]);
    TETFSI_REQUIRE(InputError, hi[a] > lo[a], "fluid.domain: the box is empty along {}", "xyz"[a]);
    g.h[a] = (hi[a] - lo[a]) / static_cast<double>(n[a]);
  }
  return g;
}

GridSpec GridSpec::from_cell_size(const Vec3& lo, const Vec3& hi, double cell_size) {
  TETFSI_REQUIRE(InputError, std::isfinite(cell_size) && cell_size > 0,
                 "fluid.grid.cell_size = {}: use a length > 0 (m)", cell_size);
  std::array<Index, 3> n{};
  for (int a = 0; a < 3; ++a) n[a] = std::max<Index>(1, std::llround((hi[a] - lo[a]) / cell_size));
  return from_cells(lo, hi, n);
}

int GridSpec::face_side(Index f) const {
  const int a = face_axis(f);
  const Index i = face_ijk(f)[a];
  return i == 0 ? 2 * a : (i == n[a] ? 2 * a + 1 : -1);
}

// ---- triangles ---------------------------------------------------------------------------

namespace {

struct Tri {
  Vec3 p[3];
};

Tri triangle(const mesh::SolidSurface& s, Index t) {
  Tri r;
  for (int k = 0; k < 3; ++k) r.p[k] = s.vertices.row(s.triangles(t, k)).transpose();
  return r;
}

/// Edge function of p against the 2D edge (e0 → e1), computed from the lexicographically
/// smaller endpoint so that the two triangles sharing an edge get exactly opposite values.
double edge_function(const Vec2& e0, const Vec2& e1, const Vec2& p) {
  const bool swap = e1[0] < e0[0] || (e1[0] == e0[0] && e1[1] < e0[1]);
  const Vec2& a = swap ? e1 : e0;
  const Vec2& b = swap ? e0 : e1;
  const double v = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
  return swap ? -v : v;
}

/// Top-left rule for a counter-clockwise triangle: a point on edge (e0 → e1) counts when the
/// edge is a left edge (going down) or a top edge (horizontal, going left), so a line through
/// a shared edge or vertex of a closed surface meets exactly one of the triangles there.
bool owns_edge(const Vec2& e0, const Vec2& e1) {
  const double dy = e1[1] - e0[1], dx = e1[0] - e0[0];
  return dy < 0.0 || (dy == 0.0 && dx < 0.0);
}

/// Whether the 2D point p is in the projected triangle q (any orientation), ties by the
/// top-left rule; fills the barycentric weights.
bool in_projected(const Vec2 q[3], const Vec2& p, Vec3& w) {
  const double area = edge_function(q[0], q[1], q[2]);
  if (area == 0.0) return false;
  int order[3] = {0, 1, 2};
  if (area < 0.0) std::swap(order[1], order[2]);
  double e[3];
  for (int k = 0; k < 3; ++k) {
    const Vec2& a = q[order[k]];
    const Vec2& b = q[order[(k + 1) % 3]];
    e[k] = edge_function(a, b, p);
    if (e[k] < 0.0 || (e[k] == 0.0 && !owns_edge(a, b))) return false;
  }
  const double A = std::abs(area);
  // e[k] is the weight of the vertex opposite edge k, i.e. order[(k + 2) % 3].
  for (int k = 0; k < 3; ++k) w[order[(k + 2) % 3]] = e[k] / A;
  return true;
}

/// The two axes other than a, in increasing order.
std::array<int, 2> other_axes(int a) {
  return a == 0 ? std::array{1, 2} : std::array{0, 3 - a};
}

/// Every grid line along axis a through cell-centre coordinates that crosses triangle T:
/// visit(j, k, coordinate along a, barycentric weights), (j, k) the line's cell indices on
/// the other two axes (in increasing axis order).
template <class Visit>
void rasterize_axis(const GridSpec& g, int a, const Tri& T, Visit&& visit) {
  const auto [b, c] = other_axes(a);
  Vec2 q[3];
  for (int k = 0; k < 3; ++k) q[k] = Vec2(T.p[k][b], T.p[k][c]);
  const auto range = [&](int ax, double lo, double hi, Index& i0, Index& i1) {
    i0 = std::max<Index>(0, static_cast<Index>(std::ceil((lo - g.lo[ax]) / g.h[ax] - 0.5)));
    i1 = std::min<Index>(g.n[ax] - 1, floor_index((hi - g.lo[ax]) / g.h[ax] - 0.5));
  };
  Index j0, j1, k0, k1;
  range(b, std::min({q[0][0], q[1][0], q[2][0]}), std::max({q[0][0], q[1][0], q[2][0]}), j0, j1);
  range(c, std::min({q[0][1], q[1][1], q[2][1]}), std::max({q[0][1], q[1][1], q[2][1]}), k0, k1);
  for (Index k = k0; k <= k1; ++k)
    for (Index j = j0; j <= j1; ++j) {
      const Vec2 p(g.lo[b] + (static_cast<double>(j) + 0.5) * g.h[b],
                   g.lo[c] + (static_cast<double>(k) + 0.5) * g.h[c]);
      Vec3 w;
      if (!in_projected(q, p, w)) continue;
      visit(j, k, w[0] * T.p[0][a] + w[1] * T.p[1][a] + w[2] * T.p[2][a], w);
    }
}

/// (i, j, k) of the point at index i along axis a on the grid line (j, k) (other_axes order).
std::array<Index, 3> line_ijk(int a, Index i, Index j, Index k) {
  const auto [b, c] = other_axes(a);
  std::array<Index, 3> ijk{};
  ijk[a] = i;
  ijk[b] = j;
  ijk[c] = k;
  return ijk;
}

}  // namespace

// ---- GridSolids --------------------------------------------------------------------------

GridSolids::GridSolids(const GridSpec& g, std::vector<mesh::SolidSurface> surfaces)
    : m_grid(g), m_surfaces(std::move(surfaces)), m_margin(1e-9 * g.h.minCoeff()) {
  const Index nc = g.num_cells();
  std::vector<std::array<Index, 6>> range;  // per packed triangle: cell index box
  for (size_t b = 0; b < m_surfaces.size(); ++b) {
    const mesh::SolidSurface& s = m_surfaces[b];
    for (Index t = 0; t < s.triangles.rows(); ++t) {
      const Tri T = triangle(s, t);
      Packed P;
      P.p0 = T.p[0];
      P.e1 = T.p[1] - T.p[0];
      P.e2 = T.p[2] - T.p[0];
      P.e12 = P.e1.norm() * P.e2.norm();
      const Vec3 cr = P.e1.cross(P.e2);
      const double area2 = cr.norm();
      const Vec3 n = area2 > 0 ? Vec3(cr / area2) : Vec3::Zero();
      m_planes.emplace_back(n[0], n[1], n[2], n.dot(P.p0));
      P.lo = T.p[0].cwiseMin(T.p[1]).cwiseMin(T.p[2]);
      P.hi = T.p[0].cwiseMax(T.p[1]).cwiseMax(T.p[2]);
      P.body = static_cast<Index>(b);
      P.tri = t;
      std::array<Index, 6> r{};
      for (int a = 0; a < 3; ++a) {
        const double eps = 1e-9 * g.h[a];
        r[a] = g.axis_index(a, P.lo[a] - eps);
        r[3 + a] = g.axis_index(a, P.hi[a] + eps);
      }
      m_tris.push_back(P);
      range.push_back(r);
    }
  }
  // Two passes (count, fill) into compressed lists per reach, in body-then-triangle order.
  for (int reach = 0; reach < 3; ++reach) {
    std::vector<Index>& start = m_start[reach];
    std::vector<Index>& items = m_items[reach];
    start.assign(nc + 1, 0);
    const auto each_cell = [&](const std::array<Index, 6>& r, auto&& f) {
      for (Index k = std::max<Index>(0, r[2] - reach); k <= std::min(g.n[2] - 1, r[5] + reach); ++k)
        for (Index j = std::max<Index>(0, r[1] - reach); j <= std::min(g.n[1] - 1, r[4] + reach);
             ++j)
          for (Index i = std::max<Index>(0, r[0] - reach); i <= std::min(g.n[0] - 1, r[3] + reach);
               ++i)
            f(g.cell(i, j, k));
    };
    for (const auto& r : range) each_cell(r, [&](Index c) { ++start[c + 1]; });
    for (Index c = 0; c < nc; ++c) start[c + 1] += start[c];
    items.resize(start[nc]);
    std::vector<Index> fill(start.begin(), start.end() - 1);
    for (size_t p = 0; p < range.size(); ++p)
      each_cell(range[p], [&](Index c) { items[fill[c]++] = static_cast<Index>(p); });
  }
  m_near.assign(nc, 0);  // a bucket within one cell: a reach-1 list
  for (Index c = 0; c < nc; ++c) m_near[c] = m_start[1][c] < m_start[1][c + 1];
}

/// Segment a + s d, s ∈ [0, 1], against a triangle (Möller–Trumbore, closed: a hit on an
/// edge counts, so queries err towards "blocked"); dn = |d|.
bool GridSolids::crosses(const Packed& T, const Vec3& a, const Vec3& d, double dn, double& s,
                         Vec3& bary) const {
  const Vec3 q = d.cross(T.e2);
  const double det = T.e1.dot(q);
  if (std::abs(det) <= 1e-14 * (T.e12 * dn)) return false;  // parallel
  const Vec3 r = a - T.p0;
  const double u = r.dot(q) / det;
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 w = r.cross(T.e1);
  const double v = d.dot(w) / det;
  if (v < 0.0 || u + v > 1.0) return false;
  s = T.e2.dot(w) / det;
  if (s < 0.0 || s > 1.0) return false;
  bary = Vec3(1.0 - u - v, u, v);
  return true;
}

bool GridSolids::first_crossing(const Vec3& a, const Vec3& b, SurfacePoint* hit,
                                double* t_out) const {
  if (m_tris.empty()) return false;
  const GridSpec& g = m_grid;
  std::array<Index, 3> i0{}, i1{};
  const Vec3 slo = a.cwiseMin(b).array() - m_margin, shi = a.cwiseMax(b).array() + m_margin;
  for (int ax = 0; ax < 3; ++ax) {
    const double lo = std::min(a[ax], b[ax]), hi = std::max(a[ax], b[ax]);
    i0[ax] = g.axis_index(ax, lo);
    i1[ax] = g.axis_index(ax, hi);
  }
  // A segment within two cells of the middle of its cell range, where no triangle's box
  // reaches (the reach-2 list of the middle cell empty), meets no triangle.
  if ((i1[0] - i0[0]) <= 4 && (i1[1] - i0[1]) <= 4 && (i1[2] - i0[2]) <= 4) {
    const Index mid = g.cell((i0[0] + i1[0]) / 2, (i0[1] + i1[1]) / 2, (i0[2] + i1[2]) / 2);
    if (clear(mid, 2)) {
      if (t_out) *t_out = std::numeric_limits<double>::infinity();
      return false;
    }
  }
  const Vec3 d = b - a;
  const double dn = d.norm();
  double best = std::numeric_limits<double>::infinity();
  for (Index k = i0[2]; k <= i1[2]; ++k)
    for (Index j = i0[1]; j <= i1[1]; ++j)
      for (Index i = i0[0]; i <= i1[0]; ++i) {
        const Index c = g.cell(i, j, k);
        for (Index e = m_start[0][c]; e < m_start[0][c + 1]; ++e) {
          // plane and box tests first: they cannot reject a crossing (their slack is far
          // above round-off)
          if (one_side(m_items[0][e], a, b)) continue;
          const Packed& T = m_tris[m_items[0][e]];
          if (box_misses(T, slo, shi)) continue;
          double s = 0;
          Vec3 w;
          if (!crosses(T, a, d, dn, s, w) || s >= best) continue;
          best = s;
          if (hit) *hit = SurfacePoint{T.body, T.tri, w};
          if (!hit && !t_out) return true;
        }
      }
  if (t_out) *t_out = best;
  return std::isfinite(best);
}

GridSolids::Probe::Probe(const GridSolids& solids, const Vec3& x, int reach)
    : Probe(solids, x, reach, Vec3::Constant(-std::numeric_limits<double>::infinity()),
            Vec3::Constant(std::numeric_limits<double>::infinity())) {}

GridSolids::Probe::Probe(const GridSolids& solids, const Vec3& x, int reach, const Vec3& qlo,
                         const Vec3& qhi)
    : m_solids(&solids), m_x(x) {
  TETFSI_CHECK(reach >= 0 && reach <= 2, "GridSolids::Probe: reach {} (0..2)", reach);
  if (solids.m_tris.empty()) return;
  const GridSpec& g = solids.m_grid;
  std::array<Index, 3> i{};
  for (int a = 0; a < 3; ++a) {
    i[a] = g.axis_index(a, x[a]);
    const Index lo = i[a] - reach, hi = i[a] + reach;
    const double inf = std::numeric_limits<double>::infinity();
    m_box_lo[a] = std::max(qlo[a], lo <= 0 ? -inf : g.lo[a] + static_cast<double>(lo) * g.h[a]);
    m_box_hi[a] =
        std::min(qhi[a], hi >= g.n[a] - 1 ? inf : g.lo[a] + static_cast<double>(hi + 1) * g.h[a]);
  }
  if ((x.array() < m_box_lo.array()).any() || (x.array() > m_box_hi.array()).any()) {
    m_box_lo = m_box_hi = x;  // (not inside its own block by round-off: every query falls back)
    m_box_hi[0] = -std::numeric_limits<double>::infinity();
    return;
  }
  // A triangle whose box misses the query box (with the segment test's slack) fails the box
  // test of every query inside it: it is left out.
  const Vec3 klo = m_box_lo.array() - solids.m_margin, khi = m_box_hi.array() + solids.m_margin;
  const Index c = g.cell(i[0], i[1], i[2]);
  const Index* begin = solids.m_items[reach].data() + solids.m_start[reach][c];
  const Index* end = solids.m_items[reach].data() + solids.m_start[reach][c + 1];
  for (const Index* e = begin; e != end; ++e) {
    const Packed& T = solids.m_tris[*e];
    if (box_misses(T, klo, khi)) continue;
    const Eigen::Vector4d& P = solids.m_planes[*e];
    m_idx.push_back(*e);
    m_side.emplace_back(P[0], P[1], P[2], P[0] * x[0] + P[1] * x[1] + P[2] * x[2] - P[3]);
  }
}

bool GridSolids::Probe::visible(const Vec3& b) const {
  if (m_solids->m_tris.empty()) return true;
  // A segment inside the block's box meets only triangles of the block's list (a crossing
  // point lies in a block cell, whose bucket holds every triangle whose box reaches it).
  if ((b.array() < m_box_lo.array()).any() || (b.array() > m_box_hi.array()).any())
    return m_solids->visible(m_x, b);
  if (m_side.empty()) return true;
  const double margin = m_solids->m_margin;
  const Vec3 slo = m_x.cwiseMin(b).array() - margin, shi = m_x.cwiseMax(b).array() + margin;
  const Vec3 d = b - m_x;
  const double dn = d.norm();
  // Whether list entry i's triangle crosses the segment: the plane test first (x and b both
  // farther than the margin on one side cannot cross), then the box, then the crossing.
  const auto hides = [&](size_t i) {
    const Eigen::Vector4d& P = m_side[i];
    const double db = P[0] * d[0] + P[1] * d[1] + P[2] * d[2] + P[3];
    if (one_side(P[3], db, margin)) return false;
    const Packed& T = m_solids->m_tris[m_idx[i]];
    if (box_misses(T, slo, shi)) return false;
    double s = 0;
    Vec3 w;
    return m_solids->crosses(T, m_x, d, dn, s, w);
  };
  if (hides(m_last)) return false;
  const size_t n = m_side.size();
  for (size_t i = 0; i < n; ++i)
    if (i != m_last && hides(i)) {
      m_last = i;
      return false;
    }
  return true;
}

// ---- classification ----------------------------------------------------------------------

namespace {

void classify_box_faces(const GridSpec& g, const mesh::FluidDomain& domain, GridCells& gc) {
  for (Index f = 0; f < g.num_faces(); ++f) {
    const int side = g.face_side(f);
    if (side < 0) continue;
    gc.face_kind[f] = domain.default_kind;
    const Vec3 x = g.face_centre(f);
    const int a = side / 2, b = a == 0 ? 1 : 0, c = a == 2 ? 1 : 2;
    for (size_t p = 0; p < domain.patches.size(); ++p) {
      const mesh::DomainPatch& dp = domain.patches[p];
      if (dp.side != side) continue;
      if (x[b] < dp.lo[0] - 1e-9 || x[b] > dp.hi[0] + 1e-9 || x[c] < dp.lo[1] - 1e-9 ||
          x[c] > dp.hi[1] + 1e-9)
        continue;
      gc.face_kind[f] = dp.kind;
      gc.face_patch[f] = static_cast<Index>(p);
    }
  }
}

void check_body(const GridSpec& g, const mesh::SolidSurface& s) {
  if (s.vertices.rows() == 0) return;
  const Vec3 lo = s.vertices.colwise().minCoeff().transpose();
  const Vec3 hi = s.vertices.colwise().maxCoeff().transpose();
  int small = 0;
  for (int a = 0; a < 3; ++a) {
    TETFSI_REQUIRE(InputError, lo[a] >= g.lo[a] - 1e-9 && hi[a] <= g.hi()[a] + 1e-9,
                   "body {}: it leaves the fluid box along {} ({}..{} vs {}..{}); move it inside "
                   "fluid.domain",
                   s.body, "xyz"[a], lo[a], hi[a], g.lo[a], g.hi()[a]);
    if (hi[a] - lo[a] < g.h[a]) ++small;
  }
  TETFSI_REQUIRE(InputError, small < 2,
                 "body {}: smaller than a grid cell ({} × {} × {} m) on {} axes; the grid cannot "
                 "resolve it: lower fluid.grid.cell_size or raise fluid.grid.cells",
                 s.body, g.h[0], g.h[1], g.h[2], small);
}

/// Cells whose centre is inside a closed surface: parity of the crossings below it along z.
void mark_inside(const GridSpec& g, const mesh::SolidSurface& s, VecXi& cell_body) {
  std::map<std::pair<Index, Index>, std::vector<double>> column;
  for (Index t = 0; t < s.triangles.rows(); ++t)
    rasterize_axis(g, 2, triangle(s, t), [&](Index j, Index k, double z, const Vec3&) {
      column[{j, k}].push_back(z);
    });
  for (auto& [ij, zs] : column) {
    std::sort(zs.begin(), zs.end());
    for (Index k = 0; k < g.n[2]; ++k) {
      const double zc = g.lo[2] + (static_cast<double>(k) + 0.5) * g.h[2];
      const auto below = std::lower_bound(zs.begin(), zs.end(), zc) - zs.begin();
      const auto ijk = line_ijk(2, k, ij.first, ij.second);
      if (below % 2 == 1) cell_body[g.cell(ijk[0], ijk[1], ijk[2])] = s.body;
    }
  }
}

/// Faces whose centre-to-centre segment crosses a triangle of s: Solid, keeping the crossing
/// nearest the face centre (both sides fluid) or the fluid cell (one side solid).
void mark_crossed(const GridSpec& g, const mesh::SolidSurface& s, GridCells& gc,
                  std::vector<double>& dist) {
  for (Index t = 0; t < s.triangles.rows(); ++t)
    for (int a = 0; a < 3; ++a)
      rasterize_axis(g, a, triangle(s, t), [&](Index j, Index k, double x, const Vec3& w) {
        if (x < g.lo[a] || x > g.hi()[a]) return;
        const Index i = std::clamp<Index>(floor_index((x - g.lo[a]) / g.h[a] + 0.5), 0, g.n[a]);
        const auto ijk = line_ijk(a, i, j, k);
        const Index f = g.face(a, ijk[0], ijk[1], ijk[2]);
        gc.face_kind[f] = FaceKind::Solid;
        const auto cells = g.face_cells(f);
        double ref = g.face_centre(f)[a];
        if (cells[0] >= 0 && cells[1] >= 0 && gc.fluid(cells[0]) != gc.fluid(cells[1]))
          ref = g.cell_centre(gc.fluid(cells[0]) ? cells[0] : cells[1])[a];
        const double d = std::abs(x - ref);
        if (d < dist[f]) {
          dist[f] = d;
          gc.face_solid[f] = SurfacePoint{s.body, t, w};
        }
      });
}

}  // namespace

GridCells classify_grid(const GridSpec& g, const mesh::FluidDomain& domain,
                        std::vector<mesh::SolidSurface> surfaces) {
  GridCells gc;
  gc.grid = g;
  const Index nc = g.num_cells(), nf = g.num_faces();
  gc.cell_body = VecXi::Constant(nc, -1);
  gc.face_kind.assign(nf, FaceKind::Interior);
  gc.face_patch = VecXi::Constant(nf, -1);
  gc.face_solid.assign(nf, SurfacePoint{});
  classify_box_faces(g, domain, gc);
  for (const mesh::SolidSurface& s : surfaces) {
    check_body(g, s);
    mark_inside(g, s, gc.cell_body);
  }
  std::vector<double> dist(nf, std::numeric_limits<double>::infinity());
  for (const mesh::SolidSurface& s : surfaces) mark_crossed(g, s, gc, dist);
  gc.solids = GridSolids(g, std::move(surfaces));
  // Faces with no fluid cell carry nothing; a face next to a solid cell is always Solid.
  parallel_for_each(nf, 4096, [&](Index f) {  // each face writes its own slots
    const auto c = g.face_cells(f);
    const bool f0 = gc.fluid(c[0]), f1 = gc.fluid(c[1]);
    if (!f0 && !f1) {
      gc.face_kind[f] = FaceKind::Wall;
      gc.face_solid[f] = SurfacePoint{};
    } else if ((c[0] >= 0 && !f0) || (c[1] >= 0 && !f1)) {
      gc.face_kind[f] = FaceKind::Solid;
      if (gc.face_solid[f].body < 0)  // parity and crossing disagreed (a degenerate hit)
        gc.solids.first_crossing(g.cell_centre(c[0]), g.cell_centre(c[1]), &gc.face_solid[f]);
    }
  });
  return gc;
}

}  // namespace tetfsi::fluid
