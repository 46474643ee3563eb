/// @file remesh_classify.cpp
/// Stages 5–6 of the remesher (remesh_stages.hpp): the cells inside solids are removed by a
/// flood fill between solid faces and one winding number per region, the fluid volume is
/// checked against box − solids, and the fluid cells become a TetMesh with vertex provenance
/// and face tags (walls / inflow / open patches of the box, solid faces with body, triangle
/// and barycentric weights).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/remesh_stages.hpp"

namespace tetfsi::mesh::detail {

// ---------------------------------------------------------------------------------------
// Stage 5: classification
// ---------------------------------------------------------------------------------------

void RemeshContext::classify_cells() {
  const Index nT = static_cast<Index>(tets.rows());
  region.assign(nT, -1);
  std::vector<Index> stack;
  // Flat cells on a surface (is_flat_surface_cell) belong to the solid: the fluid meets the
  // surface through their other two faces, which cover the same quad.
  flat.assign(nT, 0);
  parallel_for_each(nT, 16384, [&](Index t) {
    flat[t] = is_flat_surface_cell(tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3));
  });
  for (Index seed = 0; seed < nT; ++seed) {
    if (region[seed] >= 0) continue;
    const int r = static_cast<int>(region_fluid.size());
    region[seed] = r;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const Index t = stack.back();
      stack.pop_back();
      for (int k = 0; k < 4; ++k) {
        const Index u = nbrs(t, k);
        if (u < 0 || region[u] >= 0 || is_barrier(t, k)) continue;
        region[u] = r;
        stack.push_back(u);
      }
    }
    region_fluid.push_back(region_is_fluid(seed));
  }
}

bool RemeshContext::is_barrier(Index t, int k) const {
  const int a = tets(t, (k + 1) % 4), b = tets(t, (k + 2) % 4), c = tets(t, (k + 3) % 4);
  if (a < nL || b < nL || c < nL) return false;
  if (flat[t] || (nbrs(t, k) >= 0 && flat[nbrs(t, k)])) return true;
  const SurfaceFacet* f = facet_tri.find(sorted_key(a, b, c));
  return f && f->tri != -1;
}

bool RemeshContext::region_is_fluid(Index seed) {
  const Vec3 x =
      0.25 * (pts[tets(seed, 0)] + pts[tets(seed, 1)] + pts[tets(seed, 2)] + pts[tets(seed, 3)]);
  if (flat[seed]) {
    ++report.flat_cells_removed;
    return false;
  }
  bool inside = false;
  for (std::size_t b = 0; b < solids.size() && !inside; ++b) {
    if ((x.array() < set.body_lo[b].array()).any() || (x.array() > set.body_hi[b].array()).any())
      continue;
    inside = winding_number(x, solids[b].vertices, solids[b].triangles) > 0.5;
  }
  return !inside;
}

void RemeshContext::collect_fluid_cells() {
  const Index nT = static_cast<Index>(tets.rows());
  // Fluid cells, with the vertices they use renumbered compactly.
  std::vector<int> new_id(pts.size(), -1);
  old_id.clear();
  Index nF = 0;
  for (Index t = 0; t < nT; ++t) nF += region_fluid[region[t]];
  ftets.resize(nF, 4);
  std::vector<Index> row_of(static_cast<std::size_t>(nT), -1);
  Index row = 0;
  for (Index t = 0; t < nT; ++t) {
    if (!region_fluid[region[t]]) continue;
    row_of[static_cast<std::size_t>(t)] = row;
    for (int k = 0; k < 4; ++k) {
      int& id = new_id[tets(t, k)];
      if (id < 0) {
        id = static_cast<int>(old_id.size());
        old_id.push_back(tets(t, k));
      }
      ftets(row, k) = id;
    }
    ++row;
  }
  fnbrs.resize(nF, 4);
  parallel_for_each(nT, 16384, [&](Index t) {  // each fluid cell writes its own row
    const Index r = row_of[static_cast<std::size_t>(t)];
    if (r < 0) return;
    for (int k = 0; k < 4; ++k)
      fnbrs(r, k) = nbrs(t, k) < 0 ? -1 : row_of[static_cast<std::size_t>(nbrs(t, k))];
  });
  report.cells_removed = nT - nF;
  TETFSI_REQUIRE(MeshError, nF > 0, "remesh: no fluid cell is left: the solids fill the domain");
}

void RemeshContext::check_fluid_volume() const {
  const Index nT = static_cast<Index>(tets.rows());
  // Safety net: the fluid volume must be the box minus the solids (signed, so cavities count
  // as fluid); anything else is a leak through a triangle that was not recovered.
  double expected = (domain.hi - domain.lo).prod(), fluid = 0.0;
  for (const SolidSurface& sol : solids)
    for (Index t = 0; t < sol.triangles.rows(); ++t)
      expected -= Vec3(sol.vertices.row(sol.triangles(t, 0)))
                      .dot(Vec3(sol.vertices.row(sol.triangles(t, 1)))
                               .cross(Vec3(sol.vertices.row(sol.triangles(t, 2))))) /
                  6.0;
  // Per chunk (in parallel): its fluid volume and its first degenerate fluid cell (one of no
  // volume that the sliver rounds left); summed and picked in chunk order.
  constexpr Index kGrain = 16384;
  const std::size_t nc = static_cast<std::size_t>(num_chunks(nT, kGrain));
  std::vector<double> part(nc, 0.0);
  std::vector<Index> first(nc, -1);
  parallel_for_chunks(nT, kGrain, [&](Index begin, Index end) {
    const std::size_t c = static_cast<std::size_t>(begin / kGrain);
    for (Index t = begin; t < end; ++t) {
      if (!region_fluid[region[t]]) continue;
      part[c] +=
          (pts[tets(t, 1)] - pts[tets(t, 0)])
              .dot((pts[tets(t, 2)] - pts[tets(t, 0)]).cross(pts[tets(t, 3)] - pts[tets(t, 0)])) /
          6.0;
      if (first[c] < 0 && is_degenerate(tets, t)) first[c] = t;
    }
  });
  Index degenerate = -1;
  for (std::size_t c = 0; c < nc; ++c) {
    fluid += part[c];
    if (degenerate < 0) degenerate = first[c];
  }
  if (degenerate >= 0) {
    const Vec3 x = 0.25 * (pts[tets(degenerate, 0)] + pts[tets(degenerate, 1)] +
                           pts[tets(degenerate, 2)] + pts[tets(degenerate, 3)]);
    int surface = 0;
    for (int k = 0; k < 4; ++k) surface += tets(degenerate, k) >= nL;
    throw MeshError(fmt::format(
        "remesh: a fluid cell at ({:.6g}, {:.6g}, {:.6g}) with {} of its 4 vertices on solids "
        "is flat (coplanar to round-off) and deleting lattice vertices did not remove it (none "
        "but box points, or the rounds ran out): change surface_size slightly and report the "
        "scene",
        x.x(), x.y(), x.z(), surface));
  }
  TETFSI_REQUIRE(MeshError, std::abs(fluid - expected) <= 1e-8 * (domain.hi - domain.lo).prod(),
                 "remesh: the fluid cells fill {:.9g} m^3 but the box minus the solids is {:.9g} "
                 "m^3: a solid surface leaks (not recovered); try a smaller surface_size and "
                 "report the scene",
                 fluid, expected);
}

// ---------------------------------------------------------------------------------------
// Stage 6: the TetMesh and its tags
// ---------------------------------------------------------------------------------------

TetMesh RemeshContext::build_fluid_mesh() {
  MatX3 verts(old_id.size(), 3);
  for (std::size_t v = 0; v < old_id.size(); ++v) verts.row(v) = pts[old_id[v]].transpose();
  TetMesh m = build_tet_mesh(std::move(verts), std::move(ftets), fnbrs);
  for (std::size_t v = 0; v < old_id.size(); ++v) {
    const int o = old_id[v];
    if (o < nL) continue;
    const SurfacePoint& sp = surf->points[surface_id(o)];
    m.vertex_body(v) = solids[sp.body].body;
    m.vertex_triangle(v) = set.local(sp.on.front().first);
    m.vertex_bary.row(v) = sp.on.front().second.transpose();
  }
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (!m.is_boundary(f)) {
      m.face_kind[f] = FaceKind::Interior;
      continue;
    }
    const int a = old_id[m.faces(f, 0)], b = old_id[m.faces(f, 1)], c = old_id[m.faces(f, 2)];
    if (a >= nL && b >= nL && c >= nL &&
        (tag_solid_face(m, f, a, b, c) || tag_straddling_face(m, f, a, b, c)))
      continue;
    tag_box_face(m, f, a, b, c);
  }
  return m;
}

bool RemeshContext::tag_solid_face(TetMesh& m, Index f, int a, int b, int c) const {
  const int g = common_triangle(a, b, c);
  if (g < 0) return false;
  m.face_kind[f] = FaceKind::Solid;
  m.face_body(f) = solids[set.tri_body[g]].body;
  m.face_triangle(f) = set.local(g);
  const Vec3 w =
      (surf->bary(surface_id(a), g) + surf->bary(surface_id(b), g) + surf->bary(surface_id(c), g)) /
      3.0;
  m.face_bary.row(f) = w.transpose();
  return true;
}

// A face of a flat cell that straddles two coplanar triangles: it is attributed to the
// triangle that holds its centroid.
bool RemeshContext::tag_straddling_face(TetMesh& m, Index f, int a, int b, int c) {
  const Vec3 x = m.face_centroids.row(f).transpose();
  int best = -1;
  Vec3 best_w;
  double best_err = kInf;
  for (int v : {a, b, c})
    for (const auto& e : surf->points[surface_id(v)].on) {
      const auto& T = set.corners[e.first];
      const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]);
      const double n2 = n.squaredNorm();
      const Vec3 w((T[2] - T[1]).cross(x - T[1]).dot(n) / n2,
                   (T[0] - T[2]).cross(x - T[2]).dot(n) / n2, 0.0);
      const Vec3 wz(w(0), w(1), 1.0 - w(0) - w(1));
      const double err = std::max(0.0, -wz.minCoeff()) + std::abs((x - T[0]).dot(n)) / n2;
      if (err < best_err) best_err = err, best = e.first, best_w = wz;
    }
  if (best >= 0 && best_err < 1e-6) {
    m.face_kind[f] = FaceKind::Solid;
    m.face_body(f) = solids[set.tri_body[best]].body;
    m.face_triangle(f) = set.local(best);
    m.face_bary.row(f) = best_w.cwiseMax(0.0).transpose() / best_w.cwiseMax(0.0).sum();
    ++report.straddling_faces;
    return true;
  }
  return false;
}

void RemeshContext::tag_box_face(TetMesh& m, Index f, int a, int b, int c) const {
  int side = -1;
  for (int s = 0; s < 6 && side < 0; ++s) {
    const int ax = s / 2;
    const double plane = (s % 2) ? domain.hi(ax) : domain.lo(ax);
    if (pts[a](ax) == plane && pts[b](ax) == plane && pts[c](ax) == plane) side = s;
  }
  if (side < 0) {
    const Vec3 x = m.face_centroids.row(f).transpose();
    throw MeshError(fmt::format(
        "remesh: boundary face {} at ({:.6g}, {:.6g}, {:.6g}) is neither on the domain box nor "
        "on a solid triangle (a leak in the fluid mesh): report this with the scene",
        f, x.x(), x.y(), x.z()));
  }
  m.face_kind[f] = domain.default_kind;
  const Vec3 x = m.face_centroids.row(f).transpose();
  Vec2 uv;
  int j = 0;
  for (int ax = 0; ax < 3; ++ax)
    if (ax != side / 2) uv(j++) = x(ax);
  for (std::size_t p = 0; p < domain.patches.size(); ++p) {
    const DomainPatch& dp = domain.patches[p];
    if (dp.side == side && (uv.array() >= dp.lo.array() - 1e-9).all() &&
        (uv.array() <= dp.hi.array() + 1e-9).all()) {
      m.face_kind[f] = dp.kind;
      m.face_patch(f) = static_cast<int>(p);
    }
  }
}

}  // namespace tetfsi::mesh::detail
