#pragma once
/// @file interface.hpp
/// The fluid–solid interface operators of the tet fluid [Chentanez06, §3.3–3.4], built once
/// per mesh and used by every consumer: the fluid's own boundary values (one-way), the
/// coupled solve, time splitting's held forces and the iterated schemes' residuals.
///
///  - H (#F × 3N): solid node velocities → normal velocities of the fluid's Solid faces,
///    (H u)_f = n_f · Σ_k w_k u_{a_k} over the vertices a_k of the body triangle the face lies
///    on, w the barycentric weights of the face centroid (TetMesh::face_bary)
///    [docs/method/tet_fluid.md]; rows of the other faces are empty;
///  - J (3N × #T): cell pressures → solid nodal forces, the pressure of the cell t next to
///    face f pushing node a_k with w_k A_f p_t n_f (n_f points from the fluid into the solid);
///  - D1 (#T × #F): the boundary part of the divergence, (D1 u)_t = (1/V_t) Σ_{f ∈ t, Solid}
///    A_f u_f.
/// Built from the same faces and weights, J = (V D1 H)ᵀ exactly (V = diag of cell volumes):
/// the power the fluid does on the solid, pᵀ Jᵀ u, equals the power the solid does on the
/// fluid, pᵀ V D1 H u — the interface neither makes nor destroys energy.
///
/// Solid DOFs: the bodies' nodes stacked in body order, 3 per node (interleaved), so body b's
/// node i is DOF block `node_offsets()[b] + i`. A second fluid discretisation (a MAC grid)
/// provides the same three operators for its own cells and faces (docs/dev/architecture.md).
#include <vector>

#include "core/types.hpp"
#include "fluid/body_interface.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// One Solid face of the mesh with the body nodes its triangle's vertices are.
struct InterfaceFace {
  Index face = -1;
  Index body = -1;
  Index node[3] = {-1, -1, -1};  ///< body-local node indices
  Index dof[3] = {-1, -1, -1};   ///< 3 × the stacked node index (first DOF of the node)
  double weight[3] = {0, 0, 0};  ///< barycentric weights of the face centroid
};

class InterfaceOperators {
 public:
  /// @param m the fluid mesh; it must outlive the operators
  /// @param bodies every body the mesh's Solid faces refer to (TetMesh::face_body indexes it)
  /// @throws MeshError naming the face if a Solid face refers to a body, triangle or surface
  ///   vertex that does not exist.
  InterfaceOperators(const mesh::TetMesh& m, std::vector<BodyInterface> bodies);

  const mesh::TetMesh& mesh() const { return *m_mesh; }
  const std::vector<BodyInterface>& bodies() const { return m_bodies; }
  /// Every Solid face, in face order.
  const std::vector<InterfaceFace>& faces() const { return m_faces; }
  /// First stacked node of each body (size #bodies + 1; last = total nodes N).
  const std::vector<Index>& node_offsets() const { return m_offsets; }
  Index num_dofs() const { return 3 * m_offsets.back(); }

  /// Eq. (8)'s Solid faces: u_face[f] = (H u)_f for the faces of every body b whose u[b] is
  /// not empty (3 n_b node velocities, m/s); the other faces keep their value.
  /// @param u_face #F
  void apply_H(const std::vector<VecX>& u, VecX& u_face) const;
  /// H (#F × 3N) as a matrix.
  SparseMatrix H() const;

  /// Visit J's entries in face order: visit(face f, its cell t, body b, body-local DOF l,
  /// stacked DOF, w_k A_f n_f,d) — the force on DOF l per unit pressure of cell t.
  template <class Visit>
  void for_each_J_entry(Visit&& visit) const;
  /// J (3N × #T) as a matrix.
  SparseMatrix J() const;
  /// The nodal forces of a pressure given per Solid face, per body (3 n_b each, N):
  /// F_{a_k} += w_k (A_f p_f n_f). J p is `face_pressure(i) = p[face_tets(i.face, 0)]`; a
  /// pressure evaluated at the face centroid makes a linear field (hydrostatics) exact.
  /// @param face_pressure p_f (Pa) of an InterfaceFace
  template <class FacePressure>
  std::vector<VecX> apply_J(FacePressure&& face_pressure) const;

  /// D1 (#T × #F) as a matrix.
  SparseMatrix D1() const;

 private:
  const mesh::TetMesh* m_mesh = nullptr;
  std::vector<BodyInterface> m_bodies;
  std::vector<Index> m_offsets;
  std::vector<InterfaceFace> m_faces;
};

/// Stack per-body vectors (body order) into one (3N).
VecX stack_bodies(const std::vector<VecX>& per_body);

template <class Visit>
void InterfaceOperators::for_each_J_entry(Visit&& visit) const {
  const mesh::TetMesh& m = *m_mesh;
  for (const InterfaceFace& i : m_faces) {
    const Index f = i.face, t = m.face_tets(f, 0);
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d)  // force on node a: w_a A_f p_t n_f [docs/method/tet_fluid.md]
        visit(f, t, i.body, 3 * i.node[k] + d, i.dof[k] + d,
              i.weight[k] * m.face_areas[f] * m.face_normals(f, d));
  }
}

template <class FacePressure>
std::vector<VecX> InterfaceOperators::apply_J(FacePressure&& face_pressure) const {
  const mesh::TetMesh& m = *m_mesh;
  std::vector<VecX> F(m_bodies.size());
  for (size_t b = 0; b < m_bodies.size(); ++b) F[b] = VecX::Zero(3 * m_bodies[b].num_nodes);
  for (const InterfaceFace& i : m_faces) {
    const Vec3 an =
        m.face_areas[i.face] * face_pressure(i) * m.face_normals.row(i.face).transpose();
    for (int k = 0; k < 3; ++k) F[i.body].segment<3>(3 * i.node[k]) += i.weight[k] * an;
  }
  return F;
}

}  // namespace tetfsi::fluid
