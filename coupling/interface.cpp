#include "coupling/interface.hpp"

#include "core/error.hpp"

namespace tetfsi::coupling {

using mesh::FaceKind;
using mesh::TetMesh;

std::vector<Index> node_offsets(const std::vector<BodyInterface>& bodies) {
  std::vector<Index> off(bodies.size() + 1, 0);
  for (size_t b = 0; b < bodies.size(); ++b) off[b + 1] = off[b] + bodies[b].num_nodes;
  return off;
}

namespace {

/// Visit every Solid face with its three (node DOF block, weight) pairs.
template <class F>
void for_each_solid_face(const TetMesh& m, const std::vector<BodyInterface>& bodies, F&& visit) {
  const std::vector<Index> off = node_offsets(bodies);
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.face_kind[f] != FaceKind::Solid) continue;
    const Index b = m.face_body[f], tri = m.face_triangle[f];
    TETFSI_REQUIRE(MeshError, b >= 0 && b < static_cast<Index>(bodies.size()),
                   "interface: Solid face {} refers to body {}, but there are {} bodies", f, b,
                   bodies.size());
    const BodyInterface& bi = bodies[b];
    TETFSI_REQUIRE(MeshError, tri >= 0 && tri < bi.triangles.rows(),
                   "interface: Solid face {} refers to triangle {} of body {}, which has {}", f,
                   tri, b, bi.triangles.rows());
    Index node[3];
    double w[3];
    for (int k = 0; k < 3; ++k) {
      const Index sv = bi.triangles(tri, k);
      TETFSI_REQUIRE(MeshError, sv >= 0 && sv < bi.surface_node.size(),
                     "interface: triangle {} of body {} has surface vertex {} of {}", tri, b, sv,
                     bi.surface_node.size());
      node[k] = off[b] + bi.surface_node[sv];
      w[k] = m.face_bary(f, k);
    }
    visit(f, node, w);
  }
}

}  // namespace

std::vector<InterfaceFace> interface_faces(const TetMesh& m,
                                           const std::vector<BodyInterface>& bodies) {
  std::vector<InterfaceFace> out;
  for_each_solid_face(m, bodies, [&](Index f, const Index* node, const double* w) {
    InterfaceFace i;
    i.face = f;
    for (int k = 0; k < 3; ++k) {
      i.node[k] = node[k];
      i.weight[k] = w[k];
    }
    out.push_back(i);
  });
  return out;
}

SparseMatrix build_H(const TetMesh& m, const std::vector<BodyInterface>& bodies) {
  const Index n3 = 3 * node_offsets(bodies).back();
  Triplets tr;
  for_each_solid_face(m, bodies, [&](Index f, const Index* node, const double* w) {
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d)
        tr.emplace_back(f, 3 * node[k] + d,
                        w[k] * m.face_normals(f, d));  // (H u)_f = n_f·Σ w_a u_a
  });
  SparseMatrix H(m.num_faces(), n3);
  H.setFromTriplets(tr.begin(), tr.end());
  return H;
}

SparseMatrix build_J(const TetMesh& m, const std::vector<BodyInterface>& bodies) {
  const Index n3 = 3 * node_offsets(bodies).back();
  Triplets tr;
  for_each_solid_face(m, bodies, [&](Index f, const Index* node, const double* w) {
    const Index t = m.face_tets(f, 0);
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d)  // force on node a: w_a A_f p_t n_f
        tr.emplace_back(3 * node[k] + d, t, w[k] * m.face_areas[f] * m.face_normals(f, d));
  });
  SparseMatrix J(n3, m.num_tets());
  J.setFromTriplets(tr.begin(), tr.end());
  return J;
}

SparseMatrix build_D1(const TetMesh& m) {
  Triplets tr;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.face_kind[f] == FaceKind::Solid) {
      const Index t = m.face_tets(f, 0);
      tr.emplace_back(t, f, m.face_areas[f] / m.volumes[t]);
    }
  SparseMatrix D1(m.num_tets(), m.num_faces());
  D1.setFromTriplets(tr.begin(), tr.end());
  return D1;
}

}  // namespace tetfsi::coupling
