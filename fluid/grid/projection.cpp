#include "fluid/grid/projection.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "core/timer.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;

double grid_surface_theta(const GridCells& gc, Index f) {
  const auto c = gc.grid.face_cells(f);
  const bool first_air = gc.air_cell(c[0]);
  const double pl = gc.phi[first_air ? c[1] : c[0]], pa = gc.phi[first_air ? c[0] : c[1]];
  // the ghost fluid [Gibou02]: θ = φ_liquid / (φ_liquid − φ_air), the liquid's share of the
  // centre-to-centre segment, bounded away from 0 [Enright03]
  const double denom = pa - pl;
  const double theta = pl < 0 && denom > 0 ? -pl / denom : 1.0;
  return std::clamp(theta, k_min_surface_theta, 1.0);
}

double grid_face_dual(const GridCells& gc, Index f) {
  const double h = gc.grid.h[gc.grid.face_axis(f)];
  if (gc.face_kind[f] == FaceKind::Open) return 0.5 * h;
  return gc.surface_face(f) ? grid_surface_theta(gc, f) * h : h;
}

Index grid_inner_cell(const GridCells& gc, Index f) {
  const auto c = gc.grid.face_cells(f);
  const Index in = c[0] >= 0 ? c[0] : c[1];
  return gc.fluid(in) ? in : -1;
}

GridNumbering number_fluid_cells(const GridCells& gc) {
  GridNumbering n;
  n.unknown = VecXi::Constant(gc.grid.num_cells(), -1);
  for (Index c = 0; c < gc.grid.num_cells(); ++c)
    if (gc.fluid(c)) {
      n.unknown[c] = static_cast<Index>(n.cell.size());
      n.cell.push_back(c);
    }
  return n;
}

namespace {

/// The pressure coupling A/d of face f and the unknowns on its two sides (−1: none): both
/// for an Interior face between fluid cells, one for a free-surface face (p = 0 across it) or
/// an Open box face; w = 0 for a face that couples nothing (walls, solids, the air).
struct FaceCoupling {
  double w = 0.0;
  Index a = -1, b = -1;
};
FaceCoupling face_coupling(const GridCells& gc, const GridNumbering& n, Index f) {
  const FaceKind k = gc.face_kind[f];
  if (k != FaceKind::Interior && k != FaceKind::Open) return {};
  const GridSpec& g = gc.grid;
  const double w = g.face_area(g.face_axis(f)) / grid_face_dual(gc, f);
  if (k == FaceKind::Open) {
    const Index in = grid_inner_cell(gc, f);
    return in >= 0 ? FaceCoupling{w, n.unknown[in], -1} : FaceCoupling{};
  }
  const auto c = g.face_cells(f);
  const Index a = n.unknown[c[0]], b = n.unknown[c[1]];
  if (a < 0 && b < 0) return {};  // between two air cells
  return {w, a, b};
}

}  // namespace

SparseMatrix grid_pressure_matrix(const GridCells& gc, const GridNumbering& n, const Regions& r) {
  const GridSpec& g = gc.grid;
  const Index nu = static_cast<Index>(n.cell.size());
  // Each unknown's column straight into compressed storage (symmetric: column = row). The
  // entries of a column, by row: −z, −y, −x neighbour, the cell, +x, +y, +z (unknowns are in
  // cell order); the diagonal sums its faces in face order (−x, +x, −y, +y, −z, +z), the
  // order setFromTriplets of the faces' triplets summed them in: the same matrix bit for bit.
  // The couplings of each unknown's six faces, kept from the counting pass for the filling.
  std::vector<std::array<FaceCoupling, 6>> faces(static_cast<std::size_t>(nu));
  std::vector<Index> count(static_cast<std::size_t>(nu) + 1, 0);
  parallel_for_each(nu, 4096, [&](Index i) {
    const auto ijk = g.cell_ijk(n.cell[i]);
    Index k = 1;
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        auto fi = ijk;
        fi[a] += side;
        const FaceCoupling fc = face_coupling(gc, n, g.face(a, fi[0], fi[1], fi[2]));
        faces[i][2 * a + side] = fc;
        k += fc.a >= 0 && fc.b >= 0;
      }
    count[i + 1] = k;
  });
  for (Index i = 0; i < nu; ++i) count[i + 1] += count[i];
  SparseMatrix M(nu, nu);
  M.resizeNonZeros(count[nu]);
  std::copy(count.begin(), count.end(), M.outerIndexPtr());
  parallel_for_each(nu, 4096, [&](Index i) {
    double diag = 0.0;
    int below = 0, above = 0;  // neighbours with smaller / larger unknowns, by axis
    std::array<std::pair<Index, double>, 3> lower{}, upper{};
    for (int e = 0; e < 6; ++e) {
      const FaceCoupling& fc = faces[i][e];
      if (fc.w == 0.0) continue;
      diag += fc.w;
      if (fc.a >= 0 && fc.b >= 0) {
        if (e % 2 == 0)
          lower[below++] = {fc.a, -fc.w};  // the −axis face: the neighbour is c[0]
        else
          upper[above++] = {fc.b, -fc.w};
      }
    }
    Index k = M.outerIndexPtr()[i];
    for (int e = below - 1; e >= 0; --e) {  // −z, −y, −x
      M.innerIndexPtr()[k] = static_cast<Index>(lower[e].first);
      M.valuePtr()[k++] = lower[e].second;
    }
    M.innerIndexPtr()[k] = static_cast<Index>(i);
    M.valuePtr()[k++] = diag;
    for (int e = 0; e < above; ++e) {  // +x, +y, +z
      M.innerIndexPtr()[k] = static_cast<Index>(upper[e].first);
      M.valuePtr()[k++] = upper[e].second;
    }
  });
  // One pin per region without an Open face: double the diagonal of its first cell.
  for (Index reg = 0; reg < r.count(); ++reg)
    if (!r.has_open[reg])
      M.coeffRef(n.unknown[r.first_cell[reg]], n.unknown[r.first_cell[reg]]) *= 2.0;
  return M;
}

void grid_apply_gradient(const GridCells& gc, const VecX& q, const VecX& q_open, VecX& u) {
  const GridSpec& g = gc.grid;
  const Index nf = g.num_faces();
  // see [Chentanez06, Eq. (2)]: u = u* − (h/ρ) G p on the pressure-coupled faces (each face
  // its own slot, in parallel).
  parallel_for_each(nf, 4096, [&](Index f) {
    const FaceKind k = gc.face_kind[f];
    if (k == FaceKind::Interior) {
      const auto c = g.face_cells(f);
      u[f] -= (q[c[1]] - q[c[0]]) / grid_face_dual(gc, f);
    } else if (k == FaceKind::Open) {
      const Index in = grid_inner_cell(gc, f);
      if (in < 0) return;
      const double qo = q_open.size() == nf ? q_open[f] : 0.0;
      const bool upper = g.face_cells(f)[1] < 0;  // the box's upper side: +e_a points out
      u[f] -= (upper ? qo - q[in] : q[in] - qo) / grid_face_dual(gc, f);
    }
  });
}

VecX grid_net_flux(const GridCells& gc, const VecX& u) {
  const GridSpec& g = gc.grid;
  VecX flux = VecX::Zero(g.num_cells());
  // Per cell, its faces in global face order (lower then upper, axis by axis): the sums of a
  // loop over the faces, bit for bit.
  parallel_for_each(g.num_cells(), 4096, [&](Index c) {
    if (!gc.fluid(c)) return;
    const auto ijk = g.cell_ijk(c);
    double sum = 0;
    for (int a = 0; a < 3; ++a) {
      const double area = g.face_area(a);
      auto up = ijk;
      ++up[a];
      sum -= area * u[g.face(a, ijk[0], ijk[1], ijk[2])];  // c is above its lower face
      sum += area * u[g.face(a, up[0], up[1], up[2])];
    }
    flux[c] = sum;
  });
  return flux;
}

VecX grid_flux_excess(const GridCells& gc, const VecX& u) {
  VecX flux = grid_net_flux(gc, u);
  if (gc.volume_source.size() == flux.size()) flux -= gc.volume_source;  // 0 off fluid cells
  return flux;
}

Regions grid_regions(const GridCells& gc) {
  const GridSpec& g = gc.grid;
  // Fluid cells joined through Interior faces (not across a free surface or into the air).
  const Index stride[3] = {1, g.n[0], g.n[0] * g.n[1]};
  Regions r = connected_regions(
      g.num_cells(), [&](Index c) { return gc.fluid(c); },
      [&](Index c, auto&& visit) {
        const auto ijk = g.cell_ijk(c);
        for (int a = 0; a < 3; ++a)
          for (int side = 0; side < 2; ++side) {
            if (side == 0 ? ijk[a] == 0 : ijk[a] + 1 == g.n[a]) continue;
            auto fi = ijk;
            fi[a] += side;
            const Index d = c + (side == 0 ? -stride[a] : stride[a]);
            if (gc.interior(g.face(a, fi[0], fi[1], fi[2])) && gc.fluid(d)) visit(d);
          }
      });
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] == FaceKind::Open) {
      const Index in = grid_inner_cell(gc, f);
      if (in >= 0) r.has_open[r.cell_region[in]] = true;
    } else if (gc.surface_face(f)) {  // p = 0 at a free surface fixes the level too
      for (Index c : g.face_cells(f))
        if (gc.fluid(c)) r.has_open[r.cell_region[c]] = true;
    }
  return r;
}

ProjectionReport grid_project(const GridCells& gc, const VecX& q_open, VecX& u, VecX& q,
                              LinearSolver& solver) {
  const GridSpec& g = gc.grid;
  const Index nc = g.num_cells(), nf = g.num_faces();
  TETFSI_CHECK(u.size() == nf, "u has {} entries for {} faces", u.size(), nf);
  ProjectionReport rep;
  double t0 = now_seconds();
  const GridNumbering n = number_fluid_cells(gc);
  const Index nu = static_cast<Index>(n.cell.size());
  const Regions regions = grid_regions(gc);
  const SparseMatrix M = grid_pressure_matrix(gc, n, regions);
  rep.groups = nu;
  // D u = 0 (see [Chentanez06, Eq. (2)]; its grid discretisation) for u = u* − G q: M q = −V D u* +
  // Σ_open (A/d) q_open.
  rep.divergence_before = grid_net_flux(gc, u).cwiseAbs().maxCoeff() / g.cell_volume();
  const VecX flux = grid_flux_excess(gc, u);
  VecX b(nu);
  for (Index i = 0; i < nu; ++i) b[i] = -flux[n.cell[i]];
  if (q_open.size() == nf)
    for (Index f = 0; f < nf; ++f)
      if (gc.face_kind[f] == FaceKind::Open && grid_inner_cell(gc, f) >= 0)
        b[n.unknown[grid_inner_cell(gc, f)]] +=
            g.face_area(g.face_axis(f)) / grid_face_dual(gc, f) * q_open[f];
  // A closed region's net boundary flux cannot be absorbed: remove it evenly (equal cells).
  std::vector<double> sum(regions.count(), 0.0), abs_sum(regions.count(), 0.0);
  std::vector<Index> cells(regions.count(), 0);
  for (Index i = 0; i < nu; ++i) {
    const Index r = regions.cell_region[n.cell[i]];
    sum[r] += b[i];
    abs_sum[r] += std::abs(b[i]);
    ++cells[r];
  }
  for (Index r = 0; r < regions.count(); ++r) {
    if (regions.has_open[r]) continue;
    ++rep.pinned_regions;
    if (abs_sum[r] > 0)
      rep.incompatibility = std::max(rep.incompatibility, std::abs(sum[r]) / abs_sum[r]);
  }
  for (Index i = 0; i < nu; ++i) {
    const Index r = regions.cell_region[n.cell[i]];
    if (!regions.has_open[r]) b[i] -= sum[r] / static_cast<double>(cells[r]);
  }
  rep.assembly_s = now_seconds() - t0;

  t0 = now_seconds();
  solver.set_grid(GridLayout{{g.n[0], g.n[1], g.n[2]}, n.cell});
  solver.setup(M);
  rep.setup_s = now_seconds() - t0;
  VecX x = VecX::Zero(nu);
  if (q.size() == nc)
    for (Index i = 0; i < nu; ++i) x[i] = q[n.cell[i]];
  const SolveReport sr = solver.solve(b, x);
  rep.solve_s = sr.solve_s;
  rep.converged = sr.converged;
  rep.iterations = sr.iterations;
  rep.residual = sr.residual;
  TETFSI_REQUIRE(SolverError, x.allFinite(),
                 "grid pressure solve ({}) returned a non-finite pressure after {} iterations",
                 sr.backend, sr.iterations);
  q = VecX::Zero(nc);
  for (Index i = 0; i < nu; ++i) q[n.cell[i]] = x[i];
  grid_apply_gradient(gc, q, q_open, u);
  rep.divergence_after = grid_flux_excess(gc, u).cwiseAbs().maxCoeff() / g.cell_volume();
  return rep;
}

}  // namespace tetfsi::fluid
