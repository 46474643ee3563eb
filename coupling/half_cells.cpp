/// @file half_cells.cpp
/// The interface half cells' lengths with the spreading of the body's normals (half_cells.hpp).
#include "coupling/half_cells.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

namespace tetfsi::coupling {

using mesh::FaceKind;
using mesh::TetMesh;

TubeSpreading tube_spreading(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& n0,
                             const Vec3& n1, const Vec3& n2) {
  // The offset triangle's edges are e_k + s d_k; its area along the triangle's normal N̂ is
  // ½ N̂·((e1 + s d1) × (e2 + s d2)) = ½ (|N| + s N̂·(e1 × d2 + d1 × e2) + s² N̂·(d1 × d2)).
  const Vec3 e1 = p1 - p0, e2 = p2 - p0, d1 = n1 - n0, d2 = n2 - n0;
  const Vec3 N = e1.cross(e2);
  const double N2 = N.squaredNorm();
  if (!(N2 > 0)) return {};
  return {N.dot(e1.cross(d2) + d1.cross(e2)) / N2, N.dot(d1.cross(d2)) / N2};
}

double half_cell_spreading(const TubeSpreading& tube, double delta) {
  const double a = tube.c1 * delta, b = tube.c2 * delta * delta;
  if (std::abs(a) < 1e-12 && std::abs(b) < 1e-12) return 1.0;  // a plane: δ itself
  // 3 ∫₀¹ (1 − t)² (A(0)/A(tδ))² dt by 4-point Gauss–Legendre on [0, 1]
  constexpr std::array<double, 4> t = {0.0694318442029737, 0.3300094782075719, 0.6699905217924281,
                                       0.9305681557970263};
  constexpr std::array<double, 4> w = {0.1739274225687269, 0.3260725774312731, 0.3260725774312731,
                                       0.1739274225687269};
  double s = 0.0;
  for (int k = 0; k < 4; ++k) {
    const double ratio = std::max(1.0 + a * t[k] + b * t[k] * t[k], 0.5);
    s += w[k] * (1 - t[k]) * (1 - t[k]) / (ratio * ratio);
  }
  return 3 * s;
}

namespace {

/// Unit normals of a body's compact surface vertices, area-weighted over its interface
/// triangles, in the triangles' orientation.
MatX3 vertex_normals(const fluid::BodyInterface& bi, const MatX3& x) {
  MatX3 n = MatX3::Zero(bi.surface_node.size(), 3);
  for (Index t = 0; t < bi.triangles.rows(); ++t) {
    const Vec3 p0 = x.row(bi.surface_node[bi.triangles(t, 0)]),
               p1 = x.row(bi.surface_node[bi.triangles(t, 1)]),
               p2 = x.row(bi.surface_node[bi.triangles(t, 2)]);
    const Vec3 N = (p1 - p0).cross(p2 - p0);
    for (int k = 0; k < 3; ++k) n.row(bi.triangles(t, k)) += N.transpose();
  }
  for (Index v = 0; v < n.rows(); ++v) {
    const double l = n.row(v).norm();
    if (l > 0) n.row(v) /= l;
  }
  return n;
}

}  // namespace

VecX half_cell_lengths(const TetMesh& m, const std::vector<fluid::BodyInterface>& bodies,
                       const std::vector<MatX3>& x) {
  std::vector<MatX3> normals(bodies.size());
  for (size_t b = 0; b < bodies.size(); ++b)
    if (b < x.size() && x[b].rows() > 0) normals[b] = vertex_normals(bodies[b], x[b]);
  VecX delta = VecX::Zero(m.num_faces());
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.face_kind[f] != FaceKind::Solid || !(m.face_areas[f] > 0)) continue;
    double d = std::max(m.dual_lengths[f], 0.0);
    const Index b = m.face_body[f];
    if (d > 0 && normals[b].rows() > 0) {
      const fluid::BodyInterface& bi = bodies[b];
      const MatX3& xb = x[b];
      Index sv[3];
      Vec3 p[3], n[3];
      for (int k = 0; k < 3; ++k) {
        sv[k] = bi.triangles(m.face_triangle[f], k);
        p[k] = xb.row(bi.surface_node[sv[k]]);
        n[k] = normals[b].row(sv[k]);
      }
      // the offset runs into the fluid: against n_f, which points from the fluid into the body
      const double into_fluid = -(p[1] - p[0]).cross(p[2] - p[0]).dot(m.face_normals.row(f));
      const double s = into_fluid >= 0 ? 1.0 : -1.0;
      d *= half_cell_spreading(tube_spreading(p[0], p[1], p[2], s * n[0], s * n[1], s * n[2]), d);
    }
    delta[f] = d;
  }
  return delta;
}

}  // namespace tetfsi::coupling
