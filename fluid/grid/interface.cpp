#include "fluid/grid/interface.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "core/error.hpp"
#include "core/parallel.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;

GridInterface::GridInterface(const GridCells& gc, std::vector<BodyInterface> bodies)
    : m_gc(&gc), m_bodies(std::move(bodies)) {
  m_offsets.assign(m_bodies.size() + 1, 0);
  for (size_t b = 0; b < m_bodies.size(); ++b)
    m_offsets[b + 1] = m_offsets[b] + m_bodies[b].num_nodes;
  const GridSpec& g = gc.grid;
  for (Index f = 0; f < g.num_faces(); ++f) {
    if (gc.face_kind[f] != FaceKind::Solid) continue;
    const SurfacePoint& sp = gc.face_solid[f];
    if (sp.body < 0) continue;  // no crossing found: the face keeps velocity 0
    TETFSI_REQUIRE(MeshError, sp.body < static_cast<Index>(m_bodies.size()),
                   "grid Solid face {} refers to body {} of {}", f, sp.body, m_bodies.size());
    const BodyInterface& bi = m_bodies[sp.body];
    TETFSI_REQUIRE(MeshError, sp.triangle >= 0 && sp.triangle < bi.triangles.rows(),
                   "grid Solid face {} refers to triangle {} of body {} ({} triangles)", f,
                   sp.triangle, sp.body, bi.triangles.rows());
    GridInterfaceFace i;
    i.face = f;
    i.axis = g.face_axis(f);
    i.body = sp.body;
    for (int k = 0; k < 3; ++k) {
      i.node[k] = bi.surface_node[bi.triangles(sp.triangle, k)];
      i.dof[k] = 3 * (m_offsets[sp.body] + i.node[k]);
      i.weight[k] = sp.bary[k];
    }
    m_faces.push_back(i);
  }
}

void GridInterface::apply_H(const std::vector<VecX>& u, VecX& u_face) const {
  for (const GridInterfaceFace& i : m_faces) {
    if (u[i.body].size() == 0) continue;
    double v = 0;  // [Chentanez06, §3.4] the flux at the crossing [GSLF05]
    for (int k = 0; k < 3; ++k) v += i.weight[k] * u[i.body][3 * i.node[k] + i.axis];
    u_face[i.face] = v;
  }
}

SparseMatrix GridInterface::H() const {
  Triplets t;
  for (const GridInterfaceFace& i : m_faces)
    for (int k = 0; k < 3; ++k) t.emplace_back(i.face, i.dof[k] + i.axis, i.weight[k]);
  SparseMatrix H(m_gc->grid.num_faces(), num_dofs());
  H.setFromTriplets(t.begin(), t.end());
  return H;
}

SparseMatrix GridInterface::D1() const {
  const GridSpec& g = m_gc->grid;
  Triplets t;
  for (const GridInterfaceFace& i : m_faces) {
    const auto c = g.face_cells(i.face);
    const double a = g.face_area(i.axis) / g.cell_volume();
    if (m_gc->fluid(c[0])) t.emplace_back(c[0], i.face, a);  // c[0]'s upper face
    if (m_gc->fluid(c[1])) t.emplace_back(c[1], i.face, -a);
  }
  SparseMatrix D(g.num_cells(), g.num_faces());
  D.setFromTriplets(t.begin(), t.end());
  return D;
}

SparseMatrix GridInterface::J_consistent() const {
  // J = (V D1 H)ᵀ [docs/method/grid_fluid.md]
  const SparseMatrix VD1H = (m_gc->grid.cell_volume() * D1()) * H();
  return SparseMatrix(VD1H.transpose());
}

namespace {

/// grid_cell_stencil with the visibility of a cell (i, j, k) from x given by `sees`.
template <class Sees>
CellStencil8 cell_stencil(const GridCells& gc, const Vec3& x, Sees&& sees) {
  const GridSpec& g = gc.grid;
  std::array<Index, 3> base{};
  Vec3 frac;
  for (int a = 0; a < 3; ++a) {
    const double s = (x[a] - g.lo[a]) / g.h[a] - 0.5;
    base[a] = floor_index(s);
    frac[a] = s - static_cast<double>(base[a]);
  }
  CellStencil8 st;
  double sum = 0;
  for (int corner = 0; corner < 8; ++corner) {
    std::array<Index, 3> ijk{};
    double w = 1;
    for (int a = 0; a < 3; ++a) {
      const int up = (corner >> a) & 1;
      ijk[a] = std::clamp<Index>(base[a] + up, 0, g.n[a] - 1);
      w *= up ? frac[a] : 1.0 - frac[a];
    }
    const Index c = g.cell(ijk[0], ijk[1], ijk[2]);
    // an air cell is read too, as its p = 0 (dropped from the stencil, its weight kept)
    if (w <= 0 || !gc.open_cell(c) || !sees(ijk)) continue;
    if (gc.fluid(c)) st.items[st.size++] = {c, w};
    sum += w;
  }
  for (auto& [c, w] : st) w /= sum;
  return st;
}

/// Every cell's visibility from x through a probe.
struct ProbeSees {
  const GridSpec* g;
  const GridSolids::Probe* probe;
  bool operator()(const std::array<Index, 3>& ijk) const {
    return !probe || probe->visible(g->cell_centre(ijk));
  }
};

/// The least-squares linear fit of grid_cell_stencil_linear over the usable cells of the
/// 4 × 4 × 4 block from `first` (usable[l], l = i + 4 (j + 4 k) relative to `first`);
/// empty if they do not span a volume.
std::vector<std::pair<Index, double>> linear_fit(const GridSpec& g, const Vec3& x,
                                                 const std::array<Index, 3>& first,
                                                 const std::array<bool, 64>& usable) {
  // Least squares over the usable cells: rows [1, (c − x)/h].
  std::vector<Index> cells;
  std::vector<Eigen::Vector4d> rows;
  std::vector<double> wts;
  cells.reserve(64);
  rows.reserve(64);
  wts.reserve(64);
  for (int l = 0; l < 64; ++l) {
    if (!usable[l]) continue;
    const std::array<Index, 3> ijk{first[0] + l % 4, first[1] + (l / 4) % 4, first[2] + l / 16};
    const Vec3 d = (g.cell_centre(ijk) - x).cwiseQuotient(g.h);
    cells.push_back(g.cell(ijk[0], ijk[1], ijk[2]));
    rows.emplace_back(1.0, d[0], d[1], d[2]);
    wts.push_back(1.0 / (1.0 + d.squaredNorm()));
  }
  if (cells.size() < 4) return {};
  Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
  for (size_t r = 0; r < rows.size(); ++r) N += wts[r] * rows[r] * rows[r].transpose();
  const Eigen::FullPivLU<Eigen::Matrix4d> lu(N);
  if (lu.rank() < 4 || lu.rcond() < 1e-8) return {};
  const Eigen::Vector4d e0 = lu.solve(Eigen::Vector4d::UnitX());  // a = e0ᵀ N⁻¹ Aᵀ W p
  std::vector<std::pair<Index, double>> fit;
  for (size_t r = 0; r < rows.size(); ++r) fit.emplace_back(cells[r], wts[r] * e0.dot(rows[r]));
  return fit;
}

}  // namespace

CellStencil8 grid_cell_stencil8(const GridCells& gc, const Vec3& x) {
  const GridSpec& g = gc.grid;
  if (!gc.solids.near(g.cell_at(x))) return cell_stencil(gc, x, ProbeSees{&g, nullptr});
  // the 2 × 2 × 2 cell centres queried lie within a cell of x
  const GridSolids::Probe probe(gc.solids, x, 1, x - g.h, x + g.h);
  return cell_stencil(gc, x, ProbeSees{&g, &probe});
}

std::vector<std::pair<Index, double>> grid_cell_stencil(const GridCells& gc, const Vec3& x) {
  const CellStencil8 st = grid_cell_stencil8(gc, x);
  return {st.begin(), st.end()};
}

std::vector<std::pair<Index, double>> grid_cell_stencil_linear(const GridCells& gc, const Vec3& x) {
  const GridSpec& g = gc.grid;
  const bool near = gc.solids.near(g.cell_at(x));
  std::array<Index, 3> first{};
  bool interior = true;
  for (int a = 0; a < 3; ++a) {
    first[a] = floor_index((x[a] - g.lo[a]) / g.h[a] - 0.5) - 1;
    interior = interior && first[a] + 1 >= 0 && first[a] + 2 < g.n[a];
  }
  // reaches the 4 × 4 × 4 block, whose cell centres are the queries
  const GridSolids::Probe probe(gc.solids, x, 2, g.cell_centre(first),
                                g.cell_centre({first[0] + 3, first[1] + 3, first[2] + 3}));
  if (!interior) {
    const CellStencil8 st = cell_stencil(gc, x, ProbeSees{&g, near ? &probe : nullptr});
    return {st.begin(), st.end()};
  }
  // Which cells of the block x sees (each tested once): the 2 × 2 × 2 corners first.
  std::array<signed char, 64> seen{};  // 0 unknown, 1 visible, −1 hidden or outside
  const auto sees = [&](const std::array<Index, 3>& ijk) {
    const int l =
        static_cast<int>((ijk[0] - first[0]) + 4 * ((ijk[1] - first[1]) + 4 * (ijk[2] - first[2])));
    if (seen[l] == 0) seen[l] = probe.visible(g.cell_centre(ijk)) ? 1 : -1;
    return seen[l] > 0;
  };
  const auto corner_sees = [&](const std::array<Index, 3>& ijk) { return !near || sees(ijk); };
  const CellStencil8 st8 = cell_stencil(gc, x, corner_sees);
  std::vector<std::pair<Index, double>> st(st8.begin(), st8.end());
  bool all_usable = true;
  for (int corner = 0; corner < 8 && all_usable; ++corner) {
    const std::array<Index, 3> ijk{first[0] + 1 + (corner & 1), first[1] + 1 + ((corner >> 1) & 1),
                                   first[2] + 1 + ((corner >> 2) & 1)};
    all_usable = gc.open_cell(g.cell(ijk[0], ijk[1], ijk[2])) && corner_sees(ijk);
  }
  if (all_usable) return st;
  std::array<bool, 64> usable{};
  for (int l = 0; l < 64; ++l) {
    const std::array<Index, 3> ijk{first[0] + l % 4, first[1] + (l / 4) % 4, first[2] + l / 16};
    if (ijk[0] < 0 || ijk[1] < 0 || ijk[2] < 0 || ijk[0] >= g.n[0] || ijk[1] >= g.n[1] ||
        ijk[2] >= g.n[2])
      continue;
    usable[l] = gc.open_cell(g.cell(ijk[0], ijk[1], ijk[2])) && sees(ijk);
  }
  std::vector<std::pair<Index, double>> fit = linear_fit(g, x, first, usable);
  if (fit.empty()) return st;
  std::erase_if(fit, [&](const auto& e) { return gc.air_cell(e.first); });  // p = 0 there
  return fit;
}

namespace {

/// One solid triangle's share of J_paper: Σ over its samples of w_k w_c per cell c, the
/// cells in the order the samples first reach them; its normal and area per sample.
struct TriangleSamples {
  std::vector<std::pair<Index, Vec3>> acc;
  Vec3 n = Vec3::Zero();
  double aq = 0.0;
};

/// J_paper's samples of triangle `tri` of s (acc empty for a degenerate triangle).
TriangleSamples triangle_samples(const GridCells& gc, const mesh::SolidSurface& s, Index tri,
                                 int per_cell) {
  const double hmin = gc.grid.h.minCoeff();
  TriangleSamples ts;
  Vec3 p[3];
  for (int k = 0; k < 3; ++k) p[k] = s.vertices.row(s.triangles(tri, k)).transpose();
  const Vec3 cr = (p[1] - p[0]).cross(p[2] - p[0]);
  const double area = 0.5 * cr.norm();
  if (!(area > 0)) return ts;
  ts.n = cr.normalized();  // outward: from the solid into the fluid
  const double edge = std::max({(p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm()});
  const int m = std::max(1, static_cast<int>(std::ceil(per_cell * edge / hmin)));
  ts.aq = area / (m * m);
  // The m² sub-triangles' centroids: barycentric ((i + 1/3 or 2/3), (j + …)) / m.
  for (int i = 0; i < m; ++i)
    for (int j = 0; i + j < m; ++j)
      for (int up = 0; up < 2 && (up == 0 || i + j + 1 < m); ++up) {
        const double o = up ? 2.0 / 3.0 : 1.0 / 3.0;
        const Vec3 w((i + o) / m, (j + o) / m, 1.0 - (i + j + 2 * o) / m);
        const Vec3 xq = w[0] * p[0] + w[1] * p[1] + w[2] * p[2];
        // [Chentanez06, §3.4] ∫ p n over the solid face, the pressure read on its own side
        for (const auto& [c, wc] : grid_cell_stencil_linear(gc, xq + 1e-6 * hmin * ts.n)) {
          auto it = std::find_if(ts.acc.begin(), ts.acc.end(),
                                 [c = c](const auto& e) { return e.first == c; });
          if (it == ts.acc.end()) it = ts.acc.insert(ts.acc.end(), {c, Vec3::Zero()});
          it->second += wc * w;
        }
      }
  return ts;
}

}  // namespace

SparseMatrix GridInterface::J_paper(int per_cell) const {
  const GridSpec& g = m_gc->grid;
  Triplets t;
  for (const mesh::SolidSurface& s : m_gc->solids.surfaces()) {
    const BodyInterface& bi = m_bodies[s.body];
    // The triangles' samples in parallel, their triplets in triangle order (bit for bit).
    std::vector<TriangleSamples> samples(static_cast<size_t>(s.triangles.rows()));
    parallel_for_each(s.triangles.rows(), 16,
                      [&](Index tri) { samples[tri] = triangle_samples(*m_gc, s, tri, per_cell); });
    for (Index tri = 0; tri < s.triangles.rows(); ++tri) {
      const TriangleSamples& ts = samples[tri];
      for (const auto& [c, wk] : ts.acc) {
        for (int k = 0; k < 3; ++k) {
          const Index dof = 3 * (m_offsets[s.body] + bi.surface_node[s.triangles(tri, k)]);
          for (int d = 0; d < 3; ++d) t.emplace_back(dof + d, c, -ts.aq * wk[k] * ts.n[d]);
        }
      }
    }
  }
  SparseMatrix J(num_dofs(), g.num_cells());
  J.setFromTriplets(t.begin(), t.end());
  return J;
}

}  // namespace tetfsi::fluid
