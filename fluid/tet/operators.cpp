#include "fluid/tet/operators.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "core/timer.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;
using mesh::TetMesh;

namespace {

double mean_edge(const TetMesh& m, Index f) {
  const Vec3 a = m.vertices.row(m.faces(f, 0)).transpose();
  const Vec3 b = m.vertices.row(m.faces(f, 1)).transpose();
  const Vec3 c = m.vertices.row(m.faces(f, 2)).transpose();
  return ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0;
}

}  // namespace

VecX effective_dual_lengths(const TetMesh& m, double min_dual_fraction) {
  TETFSI_REQUIRE(InputError, min_dual_fraction > 0 && min_dual_fraction < 1,
                 "min_dual_fraction must be in (0, 1), got {}", min_dual_fraction);
  const Index nf = m.num_faces();
  VecX d(nf);
  parallel_for_each(nf, 8192, [&](Index f) {
    double floor = std::max(min_dual_fraction, 1e-9) * mean_edge(m, f);
    if (m.is_boundary(f)) {
      // Open faces: the circumcentre may lie beyond the face (obtuse boundary tets); bound
      // by a quarter of the tet's height over the face, 3 V / A / 4.
      const Index t = m.face_tets(f, 0);
      floor = std::max(floor, 0.75 * m.volumes[t] / m.face_areas[f]);
    }
    const double df = m.dual_lengths[f];
    d[f] = std::isfinite(df) ? std::max(df, floor) : floor;
  });
  return d;
}

VecX net_flux(const TetMesh& m, const VecX& u) {
  TETFSI_CHECK(u.size() == m.num_faces(), "u has {} entries for {} faces", u.size(), m.num_faces());
  const Index nt = m.num_tets();
  VecX r(nt);
  parallel_for_each(nt, 8192, [&](Index t) {
    double s = 0.0;
    for (int k = 0; k < 4; ++k) {
      const Index f = m.tet_faces(t, k);
      s += m.tet_face_signs(t, k) * m.face_areas[f] * u[f];
    }
    r[t] = s;
  });
  return r;
}

VecX divergence(const TetMesh& m, const VecX& u) {
  return net_flux(m, u).cwiseQuotient(m.volumes);  // [docs/method/tet_fluid.md] (D u)_t
}

VecX gradient(const TetMesh& m, const VecX& d_eff, const VecX& q, const VecX& q_open) {
  const Index nf = m.num_faces();
  VecX g = VecX::Zero(nf);
  for (Index f = 0; f < nf; ++f) {
    const Index t1 = m.face_tets(f, 0), t2 = m.face_tets(f, 1);
    if (t2 >= 0)
      g[f] = (q[t2] - q[t1]) / d_eff[f];
    else if (m.face_kind[f] == FaceKind::Open)
      g[f] = ((q_open.size() == nf ? q_open[f] : 0.0) - q[t1]) / d_eff[f];
  }
  return g;
}

Regions fluid_regions(const TetMesh& m) {
  Regions r = connected_regions(
      m.num_tets(), [](Index) { return true; },
      [&](Index t, auto&& visit) {
        for (int k = 0; k < 4; ++k)
          if (const Index n = m.neighbours(t, k); n >= 0) visit(n);
      });
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open)
      r.has_open[r.cell_region[m.face_tets(f, 0)]] = true;
  return r;
}

PressureGroups pressure_groups(const TetMesh& m, double min_dual_fraction) {
  PressureGroups g;
  g.cell_group = mesh::cospherical_groups(m, min_dual_fraction, &g.count);
  return g;
}

namespace {

/// Stable insertion sort of a short range by `less` (a column has a few to a few dozen
/// entries; std::stable_sort would allocate for each).
template <class T, class Less>
void insertion_sort(T* a, std::size_t n, Less less) {
  for (std::size_t i = 1; i < n; ++i) {
    const T x = a[i];
    std::size_t j = i;
    for (; j > 0 && less(x, a[j - 1]); --j) a[j] = a[j - 1];
    a[j] = x;
  }
}

/// Column k of the pressure matrix (= row k, symmetric) written at `col`, returning its
/// length: (row, value) sorted by row, the diagonal Σ w over the group's faces and each other
/// group's −Σ w over the faces it shares with k, every sum in face order — the order
/// setFromTriplets summed the faces' triplets in, so the same values bit for bit. The group's
/// faces are those of its `cells` (increasing) to other groups and its Open faces; `face_buf`
/// holds at least 4 per cell; `pins`: how often the diagonal is doubled.
std::size_t pressure_column(const TetMesh& m, const VecX& d_eff, const PressureGroups& g, Index k,
                            const Index* cells, Index ncells, int pins, Index* face_buf,
                            std::pair<Index, double>* col) {
  std::size_t nfaces = 0;
  for (Index c = 0; c < ncells; ++c)
    for (int i = 0; i < 4; ++i) {
      const Index f = m.tet_faces(cells[c], i), n = m.neighbours(cells[c], i);
      if (n >= 0 ? g.cell_group[n] != k : m.face_kind[f] == FaceKind::Open) face_buf[nfaces++] = f;
    }
  insertion_sort(face_buf, nfaces, std::less<Index>());
  std::size_t n = 0;
  double diag = 0.0;
  for (std::size_t q = 0; q < nfaces; ++q) {
    const Index f = face_buf[q];
    const double w = m.face_areas[f] / d_eff[f];
    diag += w;
    const Index t2 = m.face_tets(f, 1);
    if (t2 < 0) continue;  // an Open face
    const Index g1 = g.cell_group[m.face_tets(f, 0)], g2 = g.cell_group[t2];
    col[n++] = {g1 == k ? g2 : g1, -w};
  }
  for (int i = 0; i < pins; ++i) diag *= 2.0;
  col[n++] = {k, diag};
  insertion_sort(col, n, [](const auto& a, const auto& b) { return a.first < b.first; });
  std::size_t len = 0;  // duplicates summed in face order
  for (std::size_t i = 0; i < n; ++i) {
    if (len > 0 && col[len - 1].first == col[i].first)
      col[len - 1].second += col[i].second;
    else
      col[len++] = col[i];
  }
  return len;
}

}  // namespace

SparseMatrix pressure_matrix(const TetMesh& m, const VecX& d_eff, const PressureGroups& g,
                             const Regions& regions) {
  const Index ng = g.count, nt = m.num_tets();
  std::vector<Index> start, cells;  // each group's cells, increasing
  group_by_key(
      nt, ng, [&](Index t, auto&& emit) { emit(g.cell_group[t]); }, start, cells);
  // The pin: exact for a compatible right-hand side (see project()).
  std::vector<int> pins(static_cast<std::size_t>(ng), 0);
  for (Index r = 0; r < regions.count(); ++r)
    if (!regions.has_open[r]) ++pins[g.cell_group[regions.first_cell[r]]];
  // Each column into its slot of at most 4 per cell + 1 entries, then packed into M.
  constexpr Index grain = 4096;
  auto slot = [&](Index k) { return 4 * static_cast<std::size_t>(start[k]) + k; };
  std::vector<std::pair<Index, double>> buf(slot(ng));
  std::vector<Index> count(static_cast<std::size_t>(ng) + 1, 0);
  parallel_for_chunks(ng, grain, [&](Index begin, Index end) {
    std::vector<Index> face_buf;
    for (Index k = begin; k < end; ++k) {
      face_buf.resize(4 * static_cast<std::size_t>(start[k + 1] - start[k]));
      count[k + 1] = static_cast<Index>(pressure_column(m, d_eff, g, k, cells.data() + start[k],
                                                        start[k + 1] - start[k], pins[k],
                                                        face_buf.data(), buf.data() + slot(k)));
    }
  });
  for (Index k = 0; k < ng; ++k) count[k + 1] += count[k];
  SparseMatrix M(ng, ng);
  M.resizeNonZeros(count[ng]);
  std::copy(count.begin(), count.end(), M.outerIndexPtr());
  parallel_for_each(ng, grain, [&](Index k) {
    const std::pair<Index, double>* col = buf.data() + slot(k);
    for (Index at = count[k]; at < count[k + 1]; ++at, ++col) {
      M.innerIndexPtr()[at] = col->first;
      M.valuePtr()[at] = col->second;
    }
  });
  return M;
}

namespace {

/// Internal faces of each group and its cells, as CSR-like lists.
struct GroupLists {
  std::vector<Index> cell_start, cells, face_start, faces;
};

GroupLists group_lists(const TetMesh& m, const PressureGroups& g) {
  GroupLists L;
  const Index ng = g.count;
  std::vector<Index> nc(ng + 1, 0), nfc(ng + 1, 0);
  for (Index t = 0; t < m.num_tets(); ++t) ++nc[g.cell_group[t] + 1];
  for (Index f = 0; f < m.num_faces(); ++f)
    if (g.internal(m, f)) ++nfc[g.cell_group[m.face_tets(f, 0)] + 1];
  for (Index k = 0; k < ng; ++k) {
    nc[k + 1] += nc[k];
    nfc[k + 1] += nfc[k];
  }
  L.cell_start = nc;
  L.face_start = nfc;
  L.cells.resize(nc[ng]);
  L.faces.resize(nfc[ng]);
  for (Index t = 0; t < m.num_tets(); ++t) L.cells[nc[g.cell_group[t]]++] = t;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (g.internal(m, f)) L.faces[nfc[g.cell_group[m.face_tets(f, 0)]]++] = f;
  return L;
}

}  // namespace

Index apply_pressure_gradient(const TetMesh& m, const VecX& d_eff, const PressureGroups& groups,
                              const VecX& q, const VecX& q_open, VecX& u, const VecX* cell_source) {
  const Index nt = m.num_tets(), nf = m.num_faces();
  const Index ng = groups.count;
  TETFSI_CHECK(q.size() == nt && u.size() == nf,
               "apply_pressure_gradient: q has {} of {}, u {} of {}", q.size(), nt, u.size(), nf);
  const bool has_q_open = q_open.size() == nf;
  Index internal = 0;

  // u = u* − G q on the faces between groups and on Open faces [Chentanez06, Eq. (8)];
  // the least-squares gradient of each group from those faces (A_f n nᵀ g = A_f n (Gq)_f).
  std::vector<Mat3> nn(static_cast<size_t>(ng), Mat3::Zero());
  MatX3 rhs = MatX3::Zero(ng, 3);
  for (Index f = 0; f < nf; ++f) {
    const Index t1 = m.face_tets(f, 0), t2 = m.face_tets(f, 1);
    double gq;
    if (t2 >= 0) {
      if (groups.cell_group[t1] == groups.cell_group[t2]) continue;
      gq = (q[t2] - q[t1]) / d_eff[f];
    } else if (m.face_kind[f] == FaceKind::Open) {
      gq = ((has_q_open ? q_open[f] : 0.0) - q[t1]) / d_eff[f];
    } else {
      continue;
    }
    u[f] -= gq;
    const Vec3 n = m.face_normals.row(f).transpose();
    const Mat3 a_nn = m.face_areas[f] * n * n.transpose();
    const Vec3 a_n = m.face_areas[f] * gq * n;
    for (const Index t : {t1, t2}) {
      if (t < 0) continue;
      nn[groups.cell_group[t]] += a_nn;
      rhs.row(groups.cell_group[t]) += a_n.transpose();
    }
  }
  // Internal faces of groups: u_f −= n_f · ∇q_g, then the smallest correction that makes each
  // cell of the group divergence-free (operators.hpp).
  const GroupLists L = group_lists(m, groups);
  VecX cell_flux = net_flux(m, u);  // updated below per group
  std::vector<Index> local(static_cast<size_t>(nt), -1);
  for (Index k = 0; k < ng; ++k) {
    const Index c0 = L.cell_start[k], c1 = L.cell_start[k + 1];
    const Index f0 = L.face_start[k], f1 = L.face_start[k + 1];
    if (f1 == f0) continue;
    internal += f1 - f0;
    // Least-squares gradient (pseudo-inverse over the well-determined directions).
    Eigen::SelfAdjointEigenSolver<Mat3> es(nn[k]);
    Vec3 grad = Vec3::Zero();
    const double tr = nn[k].trace();
    for (int i = 0; i < 3; ++i)
      if (tr > 0 && es.eigenvalues()[i] > 1e-6 * tr)
        grad += es.eigenvectors().col(i) *
                (es.eigenvectors().col(i).dot(rhs.row(k).transpose()) / es.eigenvalues()[i]);
    for (Index i = f0; i < f1; ++i) {
      const Index f = L.faces[i];
      const double du = m.face_normals.row(f).dot(grad.transpose());
      u[f] -= du;
      cell_flux[m.face_tets(f, 0)] -= m.face_areas[f] * du;
      cell_flux[m.face_tets(f, 1)] += m.face_areas[f] * du;
    }
    // Correction δ_f = λ_t2 − λ_t1 with K λ = r (K: Laplacian of the group with weights A_f,
    // r: each cell's net outward flux); λ of the group's first cell pinned to 0.
    const Index n = c1 - c0;
    for (Index i = c0; i < c1; ++i) local[L.cells[i]] = i - c0;
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd r(n);
    for (Index i = c0; i < c1; ++i)
      r[i - c0] = cell_flux[L.cells[i]] - (cell_source ? (*cell_source)[L.cells[i]] : 0.0);
    for (Index i = f0; i < f1; ++i) {
      const Index f = L.faces[i];
      const Index a = local[m.face_tets(f, 0)], c = local[m.face_tets(f, 1)];
      const double w = m.face_areas[f];
      K(a, a) += w;
      K(c, c) += w;
      K(a, c) -= w;
      K(c, a) -= w;
    }
    Eigen::VectorXd lambda = Eigen::VectorXd::Zero(n);
    if (n > 1) lambda.tail(n - 1) = K.bottomRightCorner(n - 1, n - 1).ldlt().solve(r.tail(n - 1));
    for (Index i = f0; i < f1; ++i) {
      const Index f = L.faces[i];
      u[f] += lambda[local[m.face_tets(f, 1)]] - lambda[local[m.face_tets(f, 0)]];
    }
    for (Index i = c0; i < c1; ++i) local[L.cells[i]] = -1;
  }
  return internal;
}

ProjectionReport project(const TetMesh& m, double min_dual_fraction, const VecX& q_open, VecX& u,
                         VecX& q, LinearSolver& solver) {
  ProjectionReport rep;
  const Index nt = m.num_tets(), nf = m.num_faces();
  TETFSI_CHECK(u.size() == nf, "u has {} entries for {} faces", u.size(), nf);
  const bool has_q_open = q_open.size() == nf;
  double t0 = now_seconds();
  const VecX d_eff = effective_dual_lengths(m, min_dual_fraction);
  const Regions regions = fluid_regions(m);
  const PressureGroups groups = pressure_groups(m, min_dual_fraction);
  const Index ng = groups.count;
  rep.groups = ng;
  const SparseMatrix M = pressure_matrix(m, d_eff, groups, regions);
  // D u = 0 [Chentanez06, Eq. (2)] for u = u* − G q: M q = −V D u* + Σ_open (A/d̃) q_open,
  // summed over each group's cells
  // (the fluxes of its internal faces cancel).
  const VecX flux = net_flux(m, u);
  rep.divergence_before = nt > 0 ? flux.cwiseQuotient(m.volumes).cwiseAbs().maxCoeff() : 0.0;
  VecX b = VecX::Zero(ng);
  for (Index t = 0; t < nt; ++t) b[groups.cell_group[t]] -= flux[t];
  if (has_q_open)
    for (Index f = 0; f < nf; ++f)
      if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open)
        b[groups.cell_group[m.face_tets(f, 0)]] += m.face_areas[f] / d_eff[f] * q_open[f];
  // A closed region's net boundary flux cannot be absorbed: remove it in proportion to volume.
  {
    const Index nr = regions.count();
    std::vector<double> sum(nr, 0.0), abs_sum(nr, 0.0), vol(nr, 0.0);
    VecX gvol = VecX::Zero(ng);
    VecXi greg = VecXi::Zero(ng);
    for (Index t = 0; t < nt; ++t) {
      gvol[groups.cell_group[t]] += m.volumes[t];
      greg[groups.cell_group[t]] = regions.cell_region[t];
    }
    for (Index k = 0; k < ng; ++k) {
      sum[greg[k]] += b[k];
      abs_sum[greg[k]] += std::abs(b[k]);
      vol[greg[k]] += gvol[k];
    }
    for (Index r = 0; r < nr; ++r) {
      if (regions.has_open[r]) continue;
      ++rep.pinned_regions;
      if (abs_sum[r] > 0)
        rep.incompatibility = std::max(rep.incompatibility, std::abs(sum[r]) / abs_sum[r]);
    }
    for (Index k = 0; k < ng; ++k)
      if (!regions.has_open[greg[k]]) b[k] -= sum[greg[k]] * gvol[k] / vol[greg[k]];
  }
  rep.assembly_s = now_seconds() - t0;

  t0 = now_seconds();
  solver.setup(M);
  rep.setup_s = now_seconds() - t0;
  VecX qg = VecX::Zero(ng);
  if (q.size() == nt)
    for (Index t = 0; t < nt; ++t) qg[groups.cell_group[t]] = q[t];
  const SolveReport sr = solver.solve(b, qg);
  rep.solve_s = sr.solve_s;
  rep.converged = sr.converged;
  rep.iterations = sr.iterations;
  rep.residual = sr.residual;
  TETFSI_REQUIRE(SolverError, qg.allFinite(),
                 "pressure solve ({}) returned a non-finite pressure after {} iterations",
                 sr.backend, sr.iterations);
  t0 = now_seconds();
  q.resize(nt);
  for (Index t = 0; t < nt; ++t) q[t] = qg[groups.cell_group[t]];
  rep.internal_faces = apply_pressure_gradient(m, d_eff, groups, q, q_open, u);
  rep.assembly_s += now_seconds() - t0;
  rep.divergence_after = nt > 0 ? divergence(m, u).cwiseAbs().maxCoeff() : 0.0;
  return rep;
}

}  // namespace tetfsi::fluid
