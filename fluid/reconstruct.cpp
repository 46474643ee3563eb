#include "fluid/reconstruct.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "core/error.hpp"

namespace tetfsi::fluid {

using mesh::TetMesh;

MatX3 vertex_least_squares(const TetMesh& m, const VecX& u) {
  const Index nv = m.num_vertices(), nf = m.num_faces();
  TETFSI_CHECK(u.size() == nf, "u has {} entries for {} faces", u.size(), nf);
  std::vector<Mat3> normal(static_cast<size_t>(nv), Mat3::Zero());
  MatX3 rhs = MatX3::Zero(nv, 3);
  for (Index f = 0; f < nf; ++f) {
    const Vec3 n = m.face_normals.row(f).transpose();
    const double a = m.face_areas[f];
    const Mat3 nn = a * n * n.transpose();
    const Vec3 r = a * u[f] * n;
    for (int k = 0; k < 3; ++k) {
      const Index v = m.faces(f, k);
      normal[v] += nn;
      rhs.row(v) += r.transpose();
    }
  }
  MatX3 U = MatX3::Zero(nv, 3);
  for (Index v = 0; v < nv; ++v) {
    const Mat3& N = normal[v];
    const double tr = N.trace();
    if (!(tr > 0)) continue;  // a vertex of no face (not in the mesh)
    Eigen::SelfAdjointEigenSolver<Mat3> es(N);
    const Vec3 ev = es.eigenvalues();
    if (ev[0] > 1e-6 * tr) {
      U.row(v) = N.ldlt().solve(rhs.row(v).transpose()).transpose();
    } else {  // the faces around v do not span 3D (cannot happen inside a tet mesh): pseudo-inverse
      Vec3 x = Vec3::Zero();
      for (int i = 0; i < 3; ++i)
        if (ev[i] > 1e-6 * tr)
          x += es.eigenvectors().col(i) * (es.eigenvectors().col(i).dot(rhs.row(v).transpose()) / ev[i]);
      U.row(v) = x.transpose();
    }
  }
  return U;
}

VecX cell_to_vertex(const TetMesh& m, const VecX& c) {
  const Index nv = m.num_vertices(), nt = m.num_tets();
  VecX sum = VecX::Zero(nv), w = VecX::Zero(nv);
  for (Index t = 0; t < nt; ++t)
    for (int k = 0; k < 4; ++k) {
      sum[m.tets(t, k)] += m.volumes[t] * c[t];
      w[m.tets(t, k)] += m.volumes[t];
    }
  for (Index v = 0; v < nv; ++v) sum[v] = w[v] > 0 ? sum[v] / w[v] : 0.0;
  return sum;
}

Eigen::Matrix<double, 4, 3> barycentric_gradients(const TetMesh& m, Index t) {
  const Vec3 x0 = m.vertices.row(m.tets(t, 0)).transpose();
  Mat3 E;
  for (int i = 0; i < 3; ++i) E.col(i) = m.vertices.row(m.tets(t, i + 1)).transpose() - x0;
  // λ_{1..3} = E⁻¹ (x − x0): rows of E⁻¹ are ∇λ_1..3; ∇λ_0 = −Σ.
  const Mat3 Ei = E.inverse();
  Eigen::Matrix<double, 4, 3> g;
  g.row(1) = Ei.row(0);
  g.row(2) = Ei.row(1);
  g.row(3) = Ei.row(2);
  g.row(0) = -(g.row(1) + g.row(2) + g.row(3));
  return g;
}

MatX3 cell_vorticity(const TetMesh& m, const MatX3& U) {
  const Index nt = m.num_tets();
  MatX3 w(nt, 3);
  for (Index t = 0; t < nt; ++t) {
    const auto g = barycentric_gradients(m, t);
    Vec3 c = Vec3::Zero();
    for (int i = 0; i < 4; ++i)
      c += g.row(i).transpose().cross(U.row(m.tets(t, i)).transpose());
    w.row(t) = c.transpose();
  }
  return w;
}

VelocityField::VelocityField(const TetMesh& m, const VecX& u, Reconstruction kind)
    : m_mesh(&m), m_u(&u), m_kind(kind) {
  TETFSI_CHECK(u.size() == m.num_faces(), "u has {} entries for {} faces", u.size(),
               m.num_faces());
  if (kind == Reconstruction::VertexLeastSquares) {
    m_vertex = vertex_least_squares(m, u);
  } else {
    const Index nv = m.num_vertices();
    m_vertex = MatX3::Zero(nv, 3);
    VecX w = VecX::Zero(nv);
    for (Index t = 0; t < m.num_tets(); ++t)
      for (int i = 0; i < 4; ++i) {
        Vec4 b = Vec4::Zero();
        b[i] = 1.0;
        m_vertex.row(m.tets(t, i)) += m.volumes[t] * at(t, b).transpose();
        w[m.tets(t, i)] += m.volumes[t];
      }
    for (Index v = 0; v < nv; ++v)
      if (w[v] > 0) m_vertex.row(v) /= w[v];
  }
}

Vec3 VelocityField::at(Index t, const Vec4& bary) const {
  const TetMesh& m = *m_mesh;
  if (m_kind == Reconstruction::VertexLeastSquares) {
    Vec3 v = Vec3::Zero();
    for (int i = 0; i < 4; ++i) v += bary[i] * m_vertex.row(m.tets(t, i)).transpose();
    return v;
  }
  Vec3 x = Vec3::Zero();
  for (int i = 0; i < 4; ++i) x += bary[i] * m.vertices.row(m.tets(t, i)).transpose();
  // [Whitney / RT0] u(x) = Σ_k Φ_k (x − x_k) / (3 V), face k opposite vertex k.
  Vec3 v = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    const Index f = m.tet_faces(t, k);
    const double phi = m.tet_face_signs(t, k) * m.face_areas[f] * (*m_u)[f];
    v += phi * (x - m.vertices.row(m.tets(t, k)).transpose());
  }
  return v / (3.0 * m.volumes[t]);
}

MatX3 VelocityField::cell_velocities() const {
  const Index nt = m_mesh->num_tets();
  MatX3 c(nt, 3);
  const Vec4 centre = Vec4::Constant(0.25);
  for (Index t = 0; t < nt; ++t) c.row(t) = at(t, centre).transpose();
  return c;
}

}  // namespace tetfsi::fluid
