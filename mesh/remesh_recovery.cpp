/// @file remesh_recovery.cpp
/// Stage 4 of the remesher (remesh_stages.hpp): conformity recovery. Every solid triangle
/// must be exactly a union of Delaunay faces; the triangles that are not get Steiner points
/// on the solid surface, flat cells straddling coplanar triangles or crossing a cavity's edge
/// are split away, and slivers are perturbed or lose a lattice vertex, the check repeating
/// after each change. Also the cell and face predicates stages 5–6 share.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "core/timer.hpp"
#include "mesh/quality.hpp"
#include "mesh/remesh_stages.hpp"

namespace tetfsi::mesh::detail {

namespace {

/// Cells with a smaller minimum dihedral angle (degrees) lose a lattice vertex, in up to
/// kSliverRounds rounds.
constexpr double kSliverDeg = 5.0;
/// Cells with no solid vertex and a smaller minimum dihedral angle (degrees) get a lattice
/// vertex perturbed.
constexpr double kAwayDeg = 10.0;
constexpr int kPerturbRounds = 4;
constexpr int kSliverRounds = 2;
/// Further rounds, after the kSliverRounds, that delete a lattice vertex of each degenerate
/// cell only (is_degenerate below): a cell made by a later perturbation or deletion.
constexpr int kDegenerateRounds = 6;
/// A cell of four surface vertices of one body with |6V| below this times (longest edge)³ is
/// flat (coplanar up to round-off).
constexpr double kFlat = 1e-9;
/// Where the shared edge under a flat cell straddling two triangles is split.
constexpr double kStraddleSplitAt = 0.45;

/// The rows t of T (in increasing order) for which keep(t): the cells are screened in
/// parallel chunks, whose lists are joined in chunk order (the same at any thread count).
template <class Pred>
std::vector<Index> filter_cells(const MatX4i& T, Pred&& keep) {
  constexpr Index kGrain = 16384;
  std::vector<std::vector<Index>> parts(static_cast<std::size_t>(num_chunks(T.rows(), kGrain)));
  parallel_for_chunks(T.rows(), kGrain, [&](Index begin, Index end) {
    auto& part = parts[static_cast<std::size_t>(begin / kGrain)];
    for (Index t = begin; t < end; ++t)
      if (keep(t)) part.push_back(t);
  });
  std::vector<Index> out;
  for (const auto& part : parts) out.insert(out.end(), part.begin(), part.end());
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Cell and face predicates
// ---------------------------------------------------------------------------------------

int RemeshContext::common_triangle(int a, int b, int c) const {
  for (const auto& ea : surf->points[surface_id(a)].on) {
    bool in_b = false, in_c = false;
    for (const auto& eb : surf->points[surface_id(b)].on) in_b |= eb.first == ea.first;
    if (!in_b) continue;
    for (const auto& ec : surf->points[surface_id(c)].on) in_c |= ec.first == ea.first;
    if (in_c) return ea.first;
  }
  return -1;
}

bool RemeshContext::on_box(const Vec3& x) const {
  return (x.array() == domain.lo.array()).any() || (x.array() == domain.hi.array()).any();
}

// Cheap screen for small dihedral angles: the shape measure 6√2 V / l_rms³ below `shape`
// (a small dihedral angle θ makes the tet flat, V ≤ c sin θ l³; 0.3 for 5°, 0.5 for 10°),
// before the exact test by dihedral angles.
bool RemeshContext::maybe_flat(const std::array<int, 4>& c, double shape) const {
  const Vec3& a = pts[c[0]];
  const Vec3 e1 = pts[c[1]] - a, e2 = pts[c[2]] - a, e3 = pts[c[3]] - a;
  const double l2 = e1.squaredNorm() + e2.squaredNorm() + e3.squaredNorm() +
                    (e2 - e1).squaredNorm() + (e3 - e1).squaredNorm() + (e3 - e2).squaredNorm();
  const double v6 = e1.dot(e2.cross(e3));  // √2 v6 < shape (l2/6)^1.5, without pow
  return v6 <= 0 || 2.0 * v6 * v6 < shape * shape * (l2 / 6.0) * (l2 / 6.0) * (l2 / 6.0);
}

// A degenerate cell: its signed volume in metres, in double precision, is at most
// kFlat × (longest edge)³. The Delaunay's exact predicates see a positive cell, but in the
// Delaunay's own coordinates (lattice units, surface points snapped to lattice planes, see
// to_dt): four points coplanar in exact arithmetic (e.g. a lattice edge under a sheet's edge
// across its thickness, both parallel to the sheet's normal and symmetric about its mid-plane:
// a co-circular trapezoid) make a cell whose volume in metres is round-off of either sign.
// In the fluid it has no volume (1/V in the operators; build_tet_mesh rejects V ≤ 0).
bool RemeshContext::is_degenerate(const MatX4i& T, Index t) const {
  const Vec3& a = pts[T(t, 0)];
  const Vec3 e1 = pts[T(t, 1)] - a, e2 = pts[T(t, 2)] - a, e3 = pts[T(t, 3)] - a;
  const double l2 =
      std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm(), (e2 - e1).squaredNorm(),
                (e3 - e1).squaredNorm(), (e3 - e2).squaredNorm()});
  return e1.dot(e2.cross(e3)) <= kFlat * l2 * std::sqrt(l2);
}

// A face of surface points with no common triangle that still lies in the surface: it
// straddles coplanar triangles (the plane of a triangle of one vertex holds the other two).
// It seals the solid like a triangle's own faces do.
bool RemeshContext::in_surface(int a, int b, int c) const {
  const SurfacePoint &pa = surf->points[surface_id(a)], &pb = surf->points[surface_id(b)],
                     &pc = surf->points[surface_id(c)];
  if (pa.body != pb.body || pa.body != pc.body) return false;
  const double scale = (pa.x - pb.x).norm() + (pb.x - pc.x).norm() + (pc.x - pa.x).norm();
  for (const auto& e : pa.on) {
    const auto& T = set.corners[e.first];
    const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]).normalized();
    if (std::abs((pb.x - T[0]).dot(n)) <= 1e-9 * scale &&
        std::abs((pc.x - T[0]).dot(n)) <= 1e-9 * scale)
      return true;
  }
  return false;
}

// A flat cell: four surface points of one body with |6V| ≤ kFlat l³ (coplanar up to
// round-off; a co-circular coplanar quad is a valid but flat Delaunay cell with a
// meaningless circumcentre).
bool RemeshContext::is_flat_cell(int v0, int v1, int v2, int v3) const {
  if (v0 < nL || v1 < nL || v2 < nL || v3 < nL) return false;
  const int body = surf->points[surface_id(v0)].body;
  if (surf->points[surface_id(v1)].body != body || surf->points[surface_id(v2)].body != body ||
      surf->points[surface_id(v3)].body != body)
    return false;
  const Vec3 e1 = pts[v1] - pts[v0], e2 = pts[v2] - pts[v0], e3 = pts[v3] - pts[v0];
  const double l = std::max(
      {e1.norm(), e2.norm(), e3.norm(), (e2 - e1).norm(), (e3 - e1).norm(), (e3 - e2).norm()});
  return std::abs(e1.dot(e2.cross(e3))) <= kFlat * l * l * l;
}

// A flat cell on a surface: its plane is that of a triangle of one of its points (a
// co-circular quad of the surface, e.g. a square of a box face, once rotated and rounded).
// A flat cell whose points lie on two faces meeting at a crease is not: an isosceles
// trapezoid of points mirrored across the crease (the two sides of a cavity's edge, where
// both faces are sampled alike) is co-circular, and its plane cuts through the fluid.
bool RemeshContext::is_flat_surface_cell(int v0, int v1, int v2, int v3) const {
  if (!is_flat_cell(v0, v1, v2, v3)) return false;
  const int v[4] = {v0, v1, v2, v3};
  double scale = 0.0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) scale = std::max(scale, (pts[v[i]] - pts[v[j]]).norm());
  for (int i = 0; i < 4; ++i)
    for (const auto& e : surf->points[surface_id(v[i])].on) {
      const auto& T = set.corners[e.first];
      const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]).normalized();
      bool all = true;
      for (int j = 0; j < 4 && all; ++j) all = std::abs((pts[v[j]] - T[0]).dot(n)) <= 1e-9 * scale;
      if (all) return true;
    }
  return false;
}

// ---------------------------------------------------------------------------------------
// The recovery loop
// ---------------------------------------------------------------------------------------

void RemeshContext::recover_conformity() {
  prepare_recovery();
  for (int round = 0;; ++round) {
    double t0 = now_seconds();
    sync_surface_cells(round == 0 || !sizing.local_recovery);
    const std::vector<int> missing = missing_triangles();
    std::vector<int> split;
    if (missing.empty()) {
      // Conforming. A flat cell whose four surface points span two coplanar triangles (a
      // co-circular quad of a rotated box face) would leave fluid faces straddling both:
      // split the sub-triangles under it instead (their shared edge, by LEPP), within the
      // round budget.
      split = flat_cell_subs(flat_cells());
      report.seconds_recovery_check += now_seconds() - t0;
      if (split.empty() || round >= options.max_recovery_rounds) {
        // Slivers are removed by deleting a lattice vertex of each, then conformity is
        // checked again. They come from points that are coplanar in exact arithmetic but not
        // after rounding (a lattice plane through a box solid's face, or lattice points at
        // octree transitions when the box needs an anisotropic lattice).
        t0 = now_seconds();
        const bool changed = clean_up_slivers();
        report.seconds_recovery_slivers += now_seconds() - t0;
        if (!changed) break;
        ++report.cleanup_rounds;
        continue;
      }
    } else {
      report.seconds_recovery_check += now_seconds() - t0;
      if (round >= options.max_recovery_rounds) throw_unrecovered(missing, round);
      split = unrecovered_subs(missing);
    }
    report.recovery_rounds = round + 1;
    // Straddled quads are split off-centre: a midpoint makes right isosceles triangles whose
    // quads with the neighbours are co-circular again (22 rounds at 1M cells; 0.45: a few).
    t0 = now_seconds();
    insert_steiner_points(split, missing.empty() ? kStraddleSplitAt : 0.5);
    report.seconds_recovery_insert += now_seconds() - t0;
  }
  dt.extract(tets, nbrs);
  sort_cells();
  report.steiner_points = static_cast<Index>(surf->points.size()) - report.surface_points;
  report.cells_delaunay = static_cast<Index>(tets.rows());
}

void RemeshContext::sort_cells() {
  // The vertices are in canonical order (Delaunay), the smallest first: a counting sort by it,
  // then each (short) bucket by the other three, sorted once per cell (`rest`). Buckets,
  // keys and the permutation are independent per item: parallel, the same at any thread
  // count.
  const Index n = tets.rows();
  constexpr Index kGrain = 16384;
  std::vector<std::array<int, 3>> rest(static_cast<std::size_t>(n));
  parallel_for_each(n, kGrain, [&](Index t) {
    std::array<int, 3> k = {tets(t, 1), tets(t, 2), tets(t, 3)};
    sort3(k[0], k[1], k[2]);
    rest[t] = k;
  });
  std::vector<Index> start(pts.size() + 1, 0);
  for (Index t = 0; t < n; ++t) ++start[tets(t, 0) + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Index> order(static_cast<std::size_t>(n));
  {
    std::vector<Index> next(start.begin(), start.end() - 1);
    for (Index t = 0; t < n; ++t) order[next[tets(t, 0)]++] = t;
  }
  parallel_for_each(static_cast<Index>(pts.size()), kGrain, [&](Index v) {
    if (start[v + 1] - start[v] > 1)
      std::sort(order.begin() + start[v], order.begin() + start[v + 1],
                [&](Index a, Index b) { return rest[a] < rest[b]; });
  });
  std::vector<int> rank(static_cast<std::size_t>(n));
  parallel_for_each(n, kGrain, [&](Index i) { rank[order[i]] = static_cast<int>(i); });
  MatX4i T(n, 4), N(n, 4);
  parallel_for_each(n, kGrain, [&](Index i) {
    T.row(i) = tets.row(order[i]);
    for (int k = 0; k < 4; ++k) {
      const int o = nbrs(order[i], k);
      N(i, k) = o < 0 ? -1 : rank[o];
    }
  });
  tets.swap(T);
  nbrs.swap(N);
}

void RemeshContext::prepare_recovery() {
  tri_area.resize(set.corners.size());
  for (std::size_t g = 0; g < tri_area.size(); ++g) tri_area[g] = set.area(static_cast<int>(g));
  // Lattice points near the surface, to drop those inside new sub-triangles' spheres.
  lattice_grid = HashGrid(2.0 * size.surface());
  for (int v = 0; v < nL; ++v) {
    for (std::size_t b = 0; b < set.body_lo.size(); ++b) {
      const double m = 4.0 * size.far();
      if ((pts[v].array() >= set.body_lo[b].array() - m).all() &&
          (pts[v].array() <= set.body_hi[b].array() + m).all()) {
        lattice_grid.add_point(pts[v], v);
        break;
      }
    }
  }
  lattice_removed.assign(nL, 0);
}

void RemeshContext::sync_surface_cells(bool full) {
  surface_cells.resize(pts.size() - nL);
  tri_dirty.resize(set.corners.size(), 0);
  if (full) {
    for (auto& list : surface_cells) list.clear();
    flat_surface_cells.clear();
    facet_tri.clear();
    covered.assign(set.corners.size(), 0.0);
    MatX4i cells;
    dt.cells_touching(nL, cells, 3);
    add_surface_cells(cells, [](const std::array<int, 4>&) { return true; });
    dirty_tris.resize(set.corners.size());
    std::iota(dirty_tris.begin(), dirty_tris.end(), 0);
    tri_dirty.assign(set.corners.size(), 1);
    dt.track_changes(true);
    return;
  }
  const std::vector<int> changed = dt.take_changed();
  changed_mark.resize(pts.size(), 0);  // all 0 between calls: reset below, not refilled
  changed_since_cleanup.resize(pts.size(), 0);
  for (int v : changed) {
    changed_mark[v] = 1;
    if (!changed_since_cleanup[v]) {
      changed_since_cleanup[v] = 1;
      changed_since_cleanup_ids.push_back(v);
    }
  }
  // Every cell created or destroyed since the last call has all four vertices changed, so
  // its smallest surface vertex too.
  const auto all_changed = [&](const std::array<int, 4>& c) {
    return changed_mark[c[0]] && changed_mark[c[1]] && changed_mark[c[2]] && changed_mark[c[3]];
  };
  std::vector<int> around;  // the changed surface vertices, in order
  for (int v : changed)
    if (v >= nL && changed_mark[v] == 1) {
      changed_mark[v] = 2;
      around.push_back(v);
    }
  std::sort(around.begin(), around.end());
  for (int v : around) {
    auto& list = surface_cells[v - nL];
    for (std::size_t i = 0; i < list.size();) {
      if (!all_changed(list[i])) {
        ++i;
        continue;
      }
      remove_surface_facets(list[i]);
      flat_surface_cells.erase(list[i]);
      list[i] = list.back();
      list.pop_back();
    }
  }
  // The current cells with every vertex changed and three on the surface: from the stars of
  // the changed surface vertices, or, past a tenth of the surface (the first round's Steiner
  // points and lattice removals touch most of it), from one pass over every cell, which then
  // costs less than the stars (at 1M cells: 0.02-0.03 s for the pass, 0.24 s for the stars
  // of the whole surface). Only the cells that changed are removed and added either way
  // (before 2026-12-06 a large change rebuilt every facet: 0.06-0.08 s). The same cells
  // either way, in another order (only the facets' area sums depend on it, in round-off).
  MatX4i cells;
  if (10 * around.size() > surface_cells.size())
    dt.cells_touching(nL, cells, 3, &changed_mark);
  else
    dt.cells_around_unsorted(around, cells);
  add_surface_cells(cells, all_changed);
  for (int v : changed) changed_mark[v] = 0;
}

void RemeshContext::add_surface_cells(const MatX4i& cells,
                                      const std::function<bool(const std::array<int, 4>&)>& use) {
  // In cell order: the lists, the facets' cell counts, and the facets seen for the first
  // time (their triangle and area come next, in parallel: pure functions of the points).
  struct Fresh {
    int a, b, e;
    int tri = -1;
    double area = 0.0;
  };
  std::vector<Fresh> fresh;
  std::vector<std::array<int, 4>> quads;  // cells with four surface vertices
  for (Index t = 0; t < cells.rows(); ++t) {
    const std::array<int, 4> c = {cells(t, 0), cells(t, 1), cells(t, 2), cells(t, 3)};
    if (!use(c)) continue;
    int lowest = std::numeric_limits<int>::max(), n = 0;
    for (int v : c)
      if (v >= nL) lowest = std::min(lowest, v), ++n;
    if (n < 3) continue;
    surface_cells[lowest - nL].push_back(c);
    if (n == 4) quads.push_back(c);
    for (int k = 0; k < 4; ++k) {
      const int a = c[(k + 1) % 4], b = c[(k + 2) % 4], e = c[(k + 3) % 4];
      if (a < nL || b < nL || e < nL) continue;
      if (++facet_tri[sorted_key(a, b, e)].cells == 1) fresh.push_back({a, b, e});
    }
  }
  parallel_for_each(static_cast<Index>(fresh.size()), 2048, [&](Index i) {
    Fresh& f = fresh[i];
    const int g = common_triangle(f.a, f.b, f.e);
    f.tri = g >= 0 ? g : (in_surface(f.a, f.b, f.e) ? -2 : -1);
    if (g >= 0) f.area = 0.5 * (pts[f.b] - pts[f.a]).cross(pts[f.e] - pts[f.a]).norm();
  });
  std::vector<char> flat(quads.size());
  parallel_for_each(static_cast<Index>(quads.size()), 2048, [&](Index i) {
    flat[i] = is_flat_cell(quads[i][0], quads[i][1], quads[i][2], quads[i][3]);
  });
  // In the same order again: the areas summed as one cell at a time would.
  for (const Fresh& f : fresh) {
    facet_tri.find(sorted_key(f.a, f.b, f.e))->tri = f.tri;
    if (f.tri >= 0) covered[f.tri] += f.area;
    mark_dirty(f.a, f.b, f.e);
  }
  for (std::size_t i = 0; i < quads.size(); ++i)
    if (flat[i]) flat_surface_cells.insert(quads[i]);
}

void RemeshContext::remove_surface_facets(const std::array<int, 4>& c) {
  for (int k = 0; k < 4; ++k) {
    const int a = c[(k + 1) % 4], b = c[(k + 2) % 4], e = c[(k + 3) % 4];
    if (a < nL || b < nL || e < nL) continue;
    const TripleKey key = sorted_key(a, b, e);
    SurfaceFacet* f = facet_tri.find(key);
    if (--f->cells > 0) continue;
    if (f->tri >= 0) covered[f->tri] -= 0.5 * (pts[b] - pts[a]).cross(pts[e] - pts[a]).norm();
    facet_tri.erase(key);
    mark_dirty(a, b, e);
  }
}

void RemeshContext::mark_dirty(int a, int b, int c) {
  for (int v : {a, b, c})
    for (const auto& e : surf->points[surface_id(v)].on) mark_triangle_dirty(e.first);
}

void RemeshContext::mark_triangle_dirty(int g) {
  if (tri_dirty[g]) return;
  tri_dirty[g] = 1;
  dirty_tris.push_back(g);
}

MatX4i RemeshContext::flat_cells() const {
  MatX4i out(static_cast<Index>(flat_surface_cells.size()), 4);
  Index t = 0;
  for (const auto& c : flat_surface_cells) out.row(t++) << c[0], c[1], c[2], c[3];
  return out;
}

// A triangle is recovered if each of its sub-triangles is a Delaunay face, or if other
// faces on it tile it exactly (another diagonal of a co-circular quad). Over-coverage
// comes from flat cells on the surface (both diagonals), which classification handles.
std::vector<int> RemeshContext::missing_triangles() {
  std::vector<int> check;
  if (sizing.local_recovery) {
    check = dirty_tris;
    check.insert(check.end(), last_missing.begin(), last_missing.end());
    std::sort(check.begin(), check.end());
    check.erase(std::unique(check.begin(), check.end()), check.end());
  } else {
    check.resize(covered.size());
    std::iota(check.begin(), check.end(), 0);
  }
  for (int g : dirty_tris) tri_dirty[g] = 0;
  dirty_tris.clear();
  std::vector<int> missing;
  for (int g : check) {
    if (std::abs(covered[g] - tri_area[g]) <= 1e-9 * tri_area[g]) continue;
    bool all = true;
    for (int sub : surf->subs_of(g)) {
      const SubTri& st = surf->subs[sub];
      all &= facet_tri.contains(sorted_key(st.v[0] + nL, st.v[1] + nL, st.v[2] + nL));
    }
    if (!all) missing.push_back(g);
  }
  last_missing = missing;
  return missing;
}

std::vector<int> RemeshContext::unrecovered_subs(const std::vector<int>& missing) const {
  std::vector<int> split;
  for (int g : missing)
    for (int s : surf->subs_of(g)) {
      const SubTri& st = surf->subs[s];
      if (!facet_tri.contains(sorted_key(st.v[0] + nL, st.v[1] + nL, st.v[2] + nL)))
        split.push_back(s);
    }
  return split;
}

void RemeshContext::throw_unrecovered(const std::vector<int>& missing, int round) const {
  const int g = missing.front();
  const int b = set.tri_body[g];
  throw MeshError(fmt::format(
      "remesh: body {}: triangle {} (and {} more) is not recovered by the fluid mesh after "
      "{} "
      "rounds of Steiner points ({:.3g} of its area covered): the surface is too close to "
      "itself, another body or a wall for the mesh size; use a smaller surface_size",
      solids[b].body, set.local(g), missing.size() - 1, round, covered[g] / tri_area[g]));
}

void RemeshContext::insert_steiner_points(const std::vector<int>& split, double at) {
  std::vector<int> new_subs;
  const int before = static_cast<int>(surf->points.size());
  surf->refine_subs(split, &new_subs, at);
  // Keep the new sub-triangles' diametral spheres empty of lattice points (removed together).
  std::vector<int> drop;
  for (int s : new_subs) {
    mark_triangle_dirty(surf->subs[s].tri);
    if (!surf->subs[s].alive) continue;
    Vec3 c;
    double r2;
    surf->diametral(surf->subs[s], c, r2);
    const double r = std::sqrt(r2);
    lattice_grid.for_box(c - Vec3::Constant(r), c + Vec3::Constant(r), [&](int v) {
      if (!lattice_removed[v] && (pts[v] - c).squaredNorm() <= r2 * (1.0 + 1e-9)) {
        lattice_removed[v] = 1;
        drop.push_back(v);
      }
    });
  }
  dt.remove_many(drop);
  for (int p = before; p < static_cast<int>(surf->points.size()); ++p) {
    pts.push_back(surf->points[p].x);
    dt_pts.push_back(to_dt(pts.back()));
    dt.insert(dt_pts.back(), static_cast<int>(pts.size()) - 1);
  }
}

// ---------------------------------------------------------------------------------------
// Flat cells and slivers
// ---------------------------------------------------------------------------------------

// Sub-triangles to split under flat cells: the faces of a flat cell straddling coplanar
// triangles (no triangle holds all four of its points), and for a flat cell off the surface
// and in the fluid (a zero-volume fluid cell), the sub-triangles on one of its edges that
// lie in the surface: the edge on the lowest triangle id, so one face of the crease only
// (splitting both sides alike keeps the mirror symmetry, and the trapezoids come back); if
// it has no such edge, the sub-triangles at its points.
std::vector<int> RemeshContext::flat_cell_subs(const MatX4i& cells) const {
  std::unordered_map<int, std::vector<int>> subs_at_point;  // built only if needed
  std::vector<int> out;
  for (Index t = 0; t < cells.rows(); ++t) {
    const int v0 = cells(t, 0), v1 = cells(t, 1), v2 = cells(t, 2), v3 = cells(t, 3);
    if (!is_flat_cell(v0, v1, v2, v3)) continue;
    if (!is_flat_surface_cell(v0, v1, v2, v3)) {
      // Inside the solid (at a convex edge of it) it goes with the solid's cells: the side of
      // a triangle holding one of its edges, else the winding number.
      const int c[4] = {v0, v1, v2, v3};
      if (flat_cell_side(c) < 0) continue;
      int best_g = std::numeric_limits<int>::max();
      std::array<int, 2> best_on{-1, -1};
      for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) {
          const std::array<int, 2> on = surf->subs_on_edge(cells(t, i) - nL, cells(t, j) - nL);
          const int g = common_triangle(cells(t, i), cells(t, j), cells(t, j));
          if (g >= 0 && g < best_g && (on[0] >= 0 || on[1] >= 0)) best_g = g, best_on = on;
        }
      if (best_g != std::numeric_limits<int>::max()) {
        for (int s : best_on)
          if (s >= 0) out.push_back(s);
      } else {
        if (subs_at_point.empty())
          for (std::size_t sub = 0; sub < surf->subs.size(); ++sub)
            if (surf->subs[sub].alive)
              for (int k = 0; k < 3; ++k)
                subs_at_point[surf->subs[sub].v[k] + nL].push_back(static_cast<int>(sub));
        for (int k = 0; k < 4; ++k) {
          const auto& at = subs_at_point[cells(t, k)];
          out.insert(out.end(), at.begin(), at.end());
        }
      }
      continue;
    }
    const int g = common_triangle(v0, v1, v2);
    bool common = false;
    if (g >= 0)
      for (const auto& e : surf->points[surface_id(v3)].on) common |= e.first == g;
    if (common) continue;  // flat on one triangle: handled by classification, no straddle
    for (int k = 0; k < 4; ++k) {
      const int s = surf->sub_with(cells(t, (k + 1) % 4) - nL, cells(t, (k + 2) % 4) - nL,
                                   cells(t, (k + 3) % 4) - nL);
      if (s >= 0) out.push_back(s);
    }
  }
  // In the order of the subs' ids, each once: the same list whatever the cells' order.
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

int RemeshContext::flat_cell_side(const int c[4]) const {
  // Inside the solid (at a convex edge of it) it goes with the solid's cells: the side of a
  // triangle holding one of its edges, else the winding number.
  int side = 0;
  for (int i = 0; i < 4 && side == 0; ++i)
    for (int j = i + 1; j < 4 && side == 0; ++j) {
      const int g = common_triangle(c[i], c[j], c[j]);
      if (g < 0) continue;
      const auto& T = set.corners[g];
      const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]);
      double d = 0.0;
      for (int k = 0; k < 4; ++k) {
        const double dk = (pts[c[k]] - T[0]).dot(n);
        if (std::abs(dk) > std::abs(d)) d = dk;
      }
      side = d > 0 ? 1 : -1;
    }
  if (side == 0) {
    const int b = surf->points[surface_id(c[0])].body;
    const Vec3 x = 0.25 * (pts[c[0]] + pts[c[1]] + pts[c[2]] + pts[c[3]]);
    side = winding_number(x, solids[b].vertices, solids[b].triangles) > 0.5 ? -1 : 1;
  }
  return side;
}

MatX4i RemeshContext::screen_sliver_candidates() {
  std::vector<std::array<int, 4>> next;
  const auto keep_flat = [&](const MatX4i& cells, auto&& also) {
    const std::vector<Index> rows =
        filter_cells(cells, [&](Index t) { return also(t) && maybe_flat(cells, t, 0.5); });
    for (Index t : rows) next.push_back({cells(t, 0), cells(t, 1), cells(t, 2), cells(t, 3)});
  };
  MatX4i cells;
  // In the passes over every cell the screen runs inside the pass (in parallel).
  const std::function<bool(const std::array<int, 4>&)> flat_enough =
      [&](const std::array<int, 4>& c) { return maybe_flat(c, 0.5); };
  const auto take_all = [&] {
    for (Index t = 0; t < cells.rows(); ++t)
      next.push_back({cells(t, 0), cells(t, 1), cells(t, 2), cells(t, 3)});
  };
  if (!sizing.local_recovery || !candidates_valid) {
    dt.cells_touching(0, cells, 0, nullptr, &flat_enough);  // every finite cell
    take_all();
  } else {
    // A cell created or destroyed since the last pass has all four vertices changed: the
    // other candidates are still cells, with the same points.
    const std::vector<char>& mark = changed_since_cleanup;
    const auto all_changed = [&](const std::array<int, 4>& c) {
      return mark[c[0]] && mark[c[1]] && mark[c[2]] && mark[c[3]];
    };
    for (const auto& c : sliver_candidates)
      if (!all_changed(c)) next.push_back(c);
    if (10 * changed_since_cleanup_ids.size() > pts.size()) {
      dt.cells_touching(0, cells, 0, &changed_since_cleanup, &flat_enough);  // all changed
      take_all();
    } else {
      dt.cells_around_any_order(changed_since_cleanup_ids, cells);
      keep_flat(cells, [&](Index t) {
        return all_changed({cells(t, 0), cells(t, 1), cells(t, 2), cells(t, 3)});
      });
    }
  }
  std::sort(next.begin(), next.end());  // the same list whatever order the cells came in
  for (int v : changed_since_cleanup_ids) changed_since_cleanup[v] = 0;
  changed_since_cleanup_ids.clear();
  sliver_candidates = std::move(next);
  candidates_valid = true;
  MatX4i out(static_cast<Index>(sliver_candidates.size()), 4);
  for (std::size_t t = 0; t < sliver_candidates.size(); ++t)
    for (int k = 0; k < 4; ++k) out(static_cast<Index>(t), k) = sliver_candidates[t][k];
  return out;
}

bool RemeshContext::clean_up_slivers() {
  // Both screens below look only at cells that may be flat (maybe_flat at 0.3 or 0.5).
  const MatX4i cand = screen_sliver_candidates();
  bool changed = false;
  if (perturb_rounds < kPerturbRounds) {
    ++perturb_rounds;
    const int moved = perturb_away_slivers(cand);
    report.sliver_points_moved += moved;
    changed |= moved > 0;
  }
  // After the sliver rounds, degenerate cells (is_degenerate) still lose a vertex, once
  // no vertex was moved in this pass (`cand` then holds the current triangulation's).
  const bool degenerate_only = cleanup_rounds >= kSliverRounds;
  if (cleanup_rounds < kSliverRounds + kDegenerateRounds && !(degenerate_only && changed)) {
    ++cleanup_rounds;
    const std::vector<int> drop = sliver_vertices(cand, degenerate_only);
    for (int v : drop) lattice_removed[v] = 1;
    dt.remove_many(drop);
    report.sliver_points_removed += static_cast<Index>(drop.size());
    changed |= !drop.empty();
  }
  return changed;
}

std::vector<int> RemeshContext::sliver_vertices(const MatX4i& T, bool degenerate_only) const {
  const std::vector<Index> cand = filter_cells(T, [&](Index t) {
    bool lattice = false;
    for (int k = 0; k < 4; ++k) lattice |= T(t, k) < nL;
    return lattice && maybe_flat(T, t, 0.3) && (!degenerate_only || is_degenerate(T, t));
  });
  std::vector<char> degenerate(cand.size());
  for (std::size_t i = 0; i < cand.size(); ++i) degenerate[i] = is_degenerate(T, cand[i]);
  MatX4i sub(static_cast<Index>(cand.size()), 4);
  for (std::size_t i = 0; i < cand.size(); ++i) sub.row(i) = T.row(cand[i]);
  MatX3 P(static_cast<Index>(pts.size()), 3);
  for (std::size_t v = 0; v < pts.size(); ++v) P.row(v) = pts[v].transpose();
  const TetQuality q = tet_quality(P, sub);
  std::vector<int> drop;
  for (Index i = 0; i < sub.rows(); ++i) {
    if (!degenerate[i] && !(q.min_dihedral_deg(i) < kSliverDeg)) continue;
    int best = -1;
    double best_d = kInf;
    for (int k = 0; k < 4; ++k) {
      const int v = sub(i, k);
      if (v >= nL || on_box(pts[v])) continue;
      if (best < 0) best = v;
      for (int j = 0; j < 4; ++j) {
        if (sub(i, j) < nL) continue;
        const double d = (pts[v] - pts[sub(i, j)]).squaredNorm();
        if (d < best_d) best_d = d, best = v;
      }
    }
    if (best >= 0) drop.push_back(best);
  }
  std::sort(drop.begin(), drop.end());
  drop.erase(std::unique(drop.begin(), drop.end()), drop.end());
  return drop;
}

// Slivers away from the solids (octree transitions in oblique staircases) are perturbed
// rather than deleted [Tournois, Srinivasan & Alliez 2009, sliver perturbation]: each
// lattice vertex of each is moved by 0.05–0.2 of its spacing in up to 12 pseudo-random
// directions, keeping the first move that raises the smallest dihedral angle of the cells
// with no solid vertex around its star's vertices (all the cells a move can change).
// Measured on a thin sheet tilted 3°, 17°, 45° and 71°: min dihedral away from it
// 3.7–11° without, 10.0–11.0° with four rounds. Returns the number moved.
int RemeshContext::perturb_away_slivers(const MatX4i& T) {
  MatX3 P(static_cast<Index>(pts.size()), 3);
  const std::vector<int> targets = away_sliver_targets(T, P);
  int moved = 0;
  for (const int v : targets) moved += perturb_vertex(v, P);
  return moved;
}

std::vector<int> RemeshContext::away_sliver_targets(const MatX4i& T, MatX3& P) const {
  std::vector<int> targets;
  // Cells with no solid vertex that may have a small angle.
  const std::vector<Index> cand = filter_cells(T, [&](Index t) {
    bool surface = false;
    for (int k = 0; k < 4; ++k) surface |= T(t, k) >= nL;
    return !surface && maybe_flat(T, t, 0.5);
  });
  for (std::size_t v = 0; v < pts.size(); ++v) P.row(v) = pts[v].transpose();
  MatX4i sub(static_cast<Index>(cand.size()), 4);
  for (std::size_t i = 0; i < cand.size(); ++i) sub.row(i) = T.row(cand[i]);
  const TetQuality q = tet_quality(P, sub);
  for (Index i = 0; i < sub.rows(); ++i) {
    if (!(q.min_dihedral_deg(i) < kAwayDeg)) continue;
    for (int k = 0; k < 4; ++k)
      if (!on_box(pts[sub(i, k)])) targets.push_back(sub(i, k));
  }
  std::sort(targets.begin(), targets.end());
  targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
  return targets;
}

double RemeshContext::away_min_dihedral(const MatX4i& cells, Index t, const MatX3& P) const {
  if (cells.row(t).maxCoeff() >= nL) return kInf;  // a cell at a solid: not measured
  return dihedral_range_deg(P.row(cells(t, 0)), P.row(cells(t, 1)), P.row(cells(t, 2)),
                            P.row(cells(t, 3)))
      .first;
}

double RemeshContext::worst_around(const std::vector<int>& ring, MatX3& P) const {
  // A minimum over the cells: their order does not matter (no cell's angle is NaN).
  MatX4i around;
  dt.cells_around_any_order(ring, around);
  for (const int v : ring) P.row(v) = pts[v].transpose();
  double worst = kInf;
  for (Index t = 0; t < around.rows(); ++t)
    worst = std::min(worst, away_min_dihedral(around, t, P));
  return worst;
}

bool RemeshContext::raises_worst_around(const std::vector<int>& ring, int v, double above,
                                        MatX3& P) const {
  for (const int w : ring) P.row(w) = pts[w].transpose();
  if (!(above < kInf)) return false;  // nothing is above +inf (worst_around's empty minimum)
  MatX4i around;
  const auto all_above = [&]() {
    for (Index t = 0; t < around.rows(); ++t)
      if (!(away_min_dihedral(around, t, P) > above)) return false;
    return true;
  };
  dt.cells_around_any_order({v}, around);
  if (!all_above()) return false;
  dt.cells_around_any_order(ring, around);
  return all_above();
}

bool RemeshContext::perturb_vertex(int v, MatX3& P) {
  MatX4i star;
  dt.cells_around({v}, star);
  std::vector<int> ring(star.data(), star.data() + star.size());
  std::sort(ring.begin(), ring.end());
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  const double before = worst_around(ring, P);
  const Vec3 old_x = pts[v], old_y = dt_pts[v];
  std::uint64_t h = static_cast<std::uint64_t>(v) * 0x9E3779B97F4A7C15ULL + 1;
  // A failed move is not undone before the next one: the triangulation of the same points is
  // the same whatever the path (CGAL's is unique), and this halves the removals and insertions.
  bool ok = false, displaced = false;
  for (int attempt = 0; attempt < 12 && !ok; ++attempt) {
    Vec3 dir;
    for (int a = 0; a < 3; ++a) {
      h ^= h >> 31;
      h *= 0xBF58476D1CE4E5B9ULL;
      h ^= h >> 29;
      dir(a) = static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0) * 2.0 - 1.0;
    }
    if (dir.norm() < 1e-3) continue;
    const Vec3 x = old_x + (0.05 + 0.05 * (attempt % 4)) * pt_size[v] * dir.normalized();
    if ((x.array() <= domain.lo.array()).any() || (x.array() >= domain.hi.array()).any()) continue;
    dt.remove(v);
    pts[v] = x;
    dt_pts[v] = to_dt(x);
    dt.insert(dt_pts[v], v);
    displaced = true;
    ok = raises_worst_around(ring, v, before, P);
  }
  if (displaced && !ok) {
    dt.remove(v);
    pts[v] = old_x;
    dt_pts[v] = old_y;
    dt.insert(old_y, v);
  }
  return ok;
}

}  // namespace tetfsi::mesh::detail
