#include "fluid/grid/advect.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "fluid/grid/interface.hpp"

namespace tetfsi::fluid {

namespace {

/// Faces or cells per chunk of the parallel loops.
constexpr Index kGrain = 1024;

/// A point's place on the grid: per axis b its two clamped lattice indices and weights for
/// the faces of axis b (t = 0, at lo + i h) and for the cell-centred lattice (t = 1, at
/// lo + (i + ½) h, where the other axes' faces lie), and the cell holding it (cell_at).
struct PointWeights {
  std::array<std::array<std::array<Index, 2>, 3>, 2> idx{};
  std::array<std::array<std::array<double, 2>, 3>, 2> wt{};
  Index cell = 0;
};

PointWeights point_weights(const GridSpec& g, const Vec3& x) {
  PointWeights pw;
  std::array<Index, 3> ijk{};
  for (int b = 0; b < 3; ++b) {
    const double s0 = (x[b] - g.lo[b]) / g.h[b];
    for (int t = 0; t < 2; ++t) {
      const double s = s0 - (t == 0 ? 0.0 : 0.5);
      const Index base = floor_index(s);
      const double frac = s - static_cast<double>(base);
      const Index top = g.n[b] - t;
      pw.idx[t][b] = {std::clamp<Index>(base, 0, top), std::clamp<Index>(base + 1, 0, top)};
      pw.wt[t][b] = {1.0 - frac, frac};
    }
    ijk[b] = std::clamp<Index>(floor_index(s0), 0, g.n[b] - 1);
  }
  pw.cell = g.cell(ijk[0], ijk[1], ijk[2]);
  return pw;
}

/// Side-aware trilinear interpolation of the faces of axis a at x (weights pw); `probe` (at
/// x) when x is near a body. The corners are visited in the order corner = u0 + 2 u1 + 4 u2
/// and summed in that order.
double face_component_at(const GridCells& gc, const VecX& u, int a, const PointWeights& pw,
                         const GridSolids::Probe* probe) {
  const GridSpec& g = gc.grid;
  // per axis b: the two clamped indices and weights of the corners below and above x
  std::array<const std::array<Index, 2>*, 3> idx{};
  std::array<const std::array<double, 2>*, 3> wt{};
  for (int b = 0; b < 3; ++b) {
    idx[b] = &pw.idx[b == a ? 0 : 1][b];
    wt[b] = &pw.wt[b == a ? 0 : 1][b];
  }
  // cell (i, j, k) = i + n0 (j + n1 k); face (i, j, k) of axis a = off + i + d0 (j + d1 k)
  const Index n0 = g.n[0], n1 = g.n[1], na = g.n[a];
  const Index stride_a = a == 0 ? 1 : (a == 1 ? n0 : n0 * n1);
  const Index d0 = n0 + (a == 0), d1 = n1 + (a == 1);
  const double* ua = u.data() + g.face_offset(a);
  const int* body = gc.cell_body.data();
  const std::uint8_t* air = gc.air.empty() ? nullptr : gc.air.data();
  const auto fluid = [&](Index c) { return c >= 0 && body[c] < 0 && (!air || !air[c]); };
  double sum = 0, value = 0;
  for (int u2 = 0; u2 < 2; ++u2)
    for (int u1 = 0; u1 < 2; ++u1) {
      const Index j = (*idx[1])[u1], k = (*idx[2])[u2];
      for (int u0 = 0; u0 < 2; ++u0) {
        const double w = (*wt[0])[u0] * (*wt[1])[u1] * (*wt[2])[u2];
        if (w <= 0) continue;
        const std::array<Index, 3> ijk{(*idx[0])[u0], j, k};
        // the face's two cells (g.face_cells) from (i, j, k): the one above, and one below
        const Index c = ijk[0] + n0 * (j + n1 * k);
        const Index above = ijk[a] < na ? c : -1;
        const Index below = ijk[a] > 0 ? c - stride_a : -1;
        if (!fluid(below) && !fluid(above)) continue;
        if (probe && !probe->visible(g.face_centre(a, ijk))) continue;
        value += w * ua[ijk[0] + d0 * (j + d1 * k)];
        sum += w;
      }
    }
  return sum > 0 ? value / sum : 0.0;
}

/// b moved back inside the box and to just before the first body triangle on a → b. `clear`:
/// no triangle within two cells of a's cell (GridSolids::clear), so that a segment shorter
/// than a cell on every axis meets none.
Vec3 stop(const GridCells& gc, const Vec3& a, Vec3 b, bool clear, bool& clamped) {
  const GridSpec& g = gc.grid;
  const double hmin = g.h.minCoeff(), margin = 1e-6 * hmin;
  const Vec3 lo = g.lo.array() + margin, hi = g.hi().array() - margin;
  const Vec3 inside = b.cwiseMax(lo).cwiseMin(hi);
  if (inside != b) clamped = true;
  b = inside;
  if (clear && ((b - a).cwiseAbs().array() <= g.h.array()).all()) return b;
  double s = 0;
  if (gc.solids.first_crossing(a, b, nullptr, &s)) {
    const double len = (b - a).norm();
    b = a + std::max(0.0, s - 1e-3 * hmin / len) * (b - a);
    clamped = true;
  }
  return b;
}

double face_component_at(const GridCells& gc, const VecX& u, int a, const Vec3& x) {
  const PointWeights pw = point_weights(gc.grid, x);
  if (!gc.solids.near(pw.cell)) return face_component_at(gc, u, a, pw, nullptr);
  // the 2 × 2 × 2 face centres queried lie within a cell of x
  const GridSolids::Probe probe(gc.solids, x, 1, x - gc.grid.h, x + gc.grid.h);
  return face_component_at(gc, u, a, pw, &probe);
}

/// grid_velocity_at with x's weights; also gives x's cell.
Vec3 velocity_at(const GridCells& gc, const VecX& u, const Vec3& x, Index* cell = nullptr) {
  const PointWeights pw = point_weights(gc.grid, x);
  if (cell) *cell = pw.cell;
  if (!gc.solids.near(pw.cell))
    return Vec3(face_component_at(gc, u, 0, pw, nullptr), face_component_at(gc, u, 1, pw, nullptr),
                face_component_at(gc, u, 2, pw, nullptr));
  const GridSolids::Probe probe(gc.solids, x, 1, x - gc.grid.h, x + gc.grid.h);
  return Vec3(face_component_at(gc, u, 0, pw, &probe), face_component_at(gc, u, 1, pw, &probe),
              face_component_at(gc, u, 2, pw, &probe));
}

}  // namespace

Vec3 grid_velocity_at(const GridCells& gc, const VecX& u, const Vec3& x) {
  return velocity_at(gc, u, x);
}

Vec3 grid_trace_back(const GridCells& gc, const VecX& u, const Vec3& x, double h, bool& clamped) {
  // [Stam99] RK2 (midpoint) back-trace
  Index cell = 0;
  const Vec3 v = velocity_at(gc, u, x, &cell);
  const bool clear = gc.solids.clear(cell, 2);
  const Vec3 xm = stop(gc, x, x - 0.5 * h * v, clear, clamped);
  return stop(gc, x, x - h * velocity_at(gc, u, xm), clear, clamped);
}

GridAdvected grid_advect(const GridCells& old, const GridCells& now, const VecX& u,
                         const Eigen::MatrixXd& scalars, double h, const Eigen::VectorXd& fill) {
  const GridSpec& g = now.grid;
  TETFSI_CHECK(
      u.size() == g.num_faces() && scalars.rows() == g.num_cells() && fill.size() == scalars.cols(),
      "grid_advect: sizes u {}, scalars {} × {}, fill {}", u.size(), scalars.rows(), scalars.cols(),
      fill.size());
  GridAdvected out;
  out.u = VecX::Zero(g.num_faces());
  // Each face and cell writes its own slot (and clamped flag), in parallel.
  std::vector<char> face_clamped(static_cast<size_t>(g.num_faces()), 0);
  std::vector<char> cell_clamped(static_cast<size_t>(g.num_cells()), 0);
  parallel_for_each(g.num_faces(), kGrain, [&](Index f) {
    const mesh::FaceKind k = now.face_kind[f];
    if (k != mesh::FaceKind::Interior && k != mesh::FaceKind::Open) return;
    bool clamped = false;
    const Vec3 x = grid_trace_back(old, u, g.face_centre(f), h, clamped);
    face_clamped[f] = clamped;
    out.u[f] = face_component_at(old, u, g.face_axis(f), x);
  });
  out.scalars.resize(g.num_cells(), scalars.cols());
  parallel_for_each(g.num_cells(), kGrain, [&](Index c) {
    if (!now.fluid(c)) {
      out.scalars.row(c) = fill.transpose();
      return;
    }
    bool clamped = false;
    const Vec3 x = grid_trace_back(old, u, g.cell_centre(c), h, clamped);
    cell_clamped[c] = clamped;
    const CellStencil8 st = grid_cell_stencil8(old, x);
    if (st.empty()) {
      if (old.fluid(c))
        out.scalars.row(c) = scalars.row(c);
      else
        out.scalars.row(c) = fill.transpose();
      return;
    }
    out.scalars.row(c).setZero();
    for (const auto& [d, w] : st) out.scalars.row(c) += w * scalars.row(d);
  });
  for (const char c : face_clamped) out.traces_clamped += c;
  for (const char c : cell_clamped) out.traces_clamped += c;
  return out;
}

}  // namespace tetfsi::fluid
