#include "fluid/tet/interface.hpp"

#include "core/error.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;
using mesh::TetMesh;

InterfaceOperators::InterfaceOperators(const TetMesh& m, std::vector<BodyInterface> bodies)
    : m_mesh(&m), m_bodies(std::move(bodies)), m_offsets(m_bodies.size() + 1, 0) {
  for (size_t b = 0; b < m_bodies.size(); ++b)
    m_offsets[b + 1] = m_offsets[b] + m_bodies[b].num_nodes;
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.face_kind[f] != FaceKind::Solid) continue;
    const Index b = m.face_body[f], tri = m.face_triangle[f];
    TETFSI_REQUIRE(MeshError, b >= 0 && b < static_cast<Index>(m_bodies.size()),
                   "interface: Solid face {} refers to body {}, but there are {} bodies", f, b,
                   m_bodies.size());
    const BodyInterface& bi = m_bodies[b];
    TETFSI_REQUIRE(MeshError, tri >= 0 && tri < bi.triangles.rows(),
                   "interface: Solid face {} refers to triangle {} of body {}, which has {}", f,
                   tri, b, bi.triangles.rows());
    InterfaceFace i;
    i.face = f;
    i.body = b;
    for (int k = 0; k < 3; ++k) {
      const Index sv = bi.triangles(tri, k);
      TETFSI_REQUIRE(MeshError, sv >= 0 && sv < bi.surface_node.size(),
                     "interface: triangle {} of body {} has surface vertex {} of {}", tri, b, sv,
                     bi.surface_node.size());
      i.node[k] = bi.surface_node[sv];
      TETFSI_REQUIRE(MeshError, i.node[k] >= 0 && i.node[k] < bi.num_nodes,
                     "interface: surface vertex {} of body {} is node {} of {}", sv, b, i.node[k],
                     bi.num_nodes);
      i.dof[k] = 3 * (m_offsets[b] + i.node[k]);
      i.weight[k] = m.face_bary(f, k);
    }
    m_faces.push_back(i);
  }
}

void InterfaceOperators::apply_H(const std::vector<VecX>& u, VecX& u_face) const {
  const TetMesh& m = *m_mesh;
  TETFSI_CHECK(u.size() == m_bodies.size() && u_face.size() == m.num_faces(),
               "apply_H: {} bodies' velocities for {} bodies, {} face values for {} faces",
               u.size(), m_bodies.size(), u_face.size(), m.num_faces());
  for (const InterfaceFace& i : m_faces) {
    const VecX& ub = u[i.body];
    if (ub.size() == 0) continue;
    Vec3 v = Vec3::Zero();
    for (int k = 0; k < 3; ++k) v += i.weight[k] * ub.segment<3>(3 * i.node[k]);
    u_face[i.face] = m.face_normals.row(i.face).dot(v.transpose());  // (H u)_f
  }
}

SparseMatrix InterfaceOperators::H() const {
  const TetMesh& m = *m_mesh;
  Triplets tr;
  for (const InterfaceFace& i : m_faces)
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d)  // (H u)_f = n_f·Σ w_a u_a
        tr.emplace_back(i.face, i.dof[k] + d, i.weight[k] * m.face_normals(i.face, d));
  SparseMatrix H(m.num_faces(), num_dofs());
  H.setFromTriplets(tr.begin(), tr.end());
  return H;
}

SparseMatrix InterfaceOperators::J() const {
  Triplets tr;
  for_each_J_entry(
      [&](Index, Index t, Index, Index, Index dof, double w) { tr.emplace_back(dof, t, w); });
  SparseMatrix J(num_dofs(), m_mesh->num_tets());
  J.setFromTriplets(tr.begin(), tr.end());
  return J;
}

SparseMatrix InterfaceOperators::D1() const {
  const TetMesh& m = *m_mesh;
  Triplets tr;
  for (const InterfaceFace& i : m_faces) {
    const Index t = m.face_tets(i.face, 0);
    tr.emplace_back(t, i.face, m.face_areas[i.face] / m.volumes[t]);  // (D1 u)_t, s_tf = +1
  }
  SparseMatrix D1(m.num_tets(), m.num_faces());
  D1.setFromTriplets(tr.begin(), tr.end());
  return D1;
}

VecX stack_bodies(const std::vector<VecX>& per_body) {
  Index n = 0;
  for (const VecX& v : per_body) n += v.size();
  VecX out(n);
  n = 0;
  for (const VecX& v : per_body) {
    out.segment(n, v.size()) = v;
    n += v.size();
  }
  return out;
}

}  // namespace tetfsi::fluid
