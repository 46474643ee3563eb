#pragma once
/// @file interface.hpp
/// The fluid–solid interface operators of the simultaneous coupling [Chentanez06, §3.3–3.4]:
///  - H (#F × 3N): solid node velocities → normal velocities of the fluid's Solid faces,
///    (H u)_f = n_f · Σ_a w_a u_a over the vertices a of the body triangle the face lies on,
///    w the barycentric weights of the face centroid (TetMesh::face_bary) [DESIGN.md §3];
///    rows of the other faces are empty;
///  - J (3N × #T): cell pressures → solid nodal forces, the pressure of the tet t1 next to
///    face f pushing node a with w_a A_f p_t n_f (n_f points from the fluid into the solid).
/// Built from the same faces and weights, J = (V D1 H)ᵀ exactly (V = diag of tet volumes,
/// D1 the divergence's boundary part): the power the fluid does on the solid, pᵀ Jᵀ u,
/// equals the power the solid does on the fluid, pᵀ V D1 H u — the interface neither makes
/// nor destroys energy.
///
/// Solid DOFs: the bodies' nodes stacked in body order, 3 per node (interleaved), so body b's
/// node i is DOF block `offset[b] + i`.
#include <vector>

#include "core/types.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::coupling {

/// How the fluid mesh's Solid faces refer to the bodies: for body b, the surface the mesh
/// was built from (triangles in its compact vertex numbering, as in mesh::SolidSurface) and
/// the body node of each compact vertex.
struct BodyInterface {
  MatX3i triangles;     ///< #Ts × 3, compact surface vertex indices
  VecXi surface_node;   ///< #Vs: body node of each compact surface vertex
  Index num_nodes = 0;  ///< nodes of the body (its DOF block is 3 × this)
};

/// First node of each body in the stacked numbering (size #bodies + 1; last = total nodes).
std::vector<Index> node_offsets(const std::vector<BodyInterface>& bodies);

/// H (#F × 3N), see the file comment. [Chentanez06, Eq. (8)]
/// @throws MeshError naming the face if a Solid face refers to a body or triangle that does
///   not exist.
SparseMatrix build_H(const mesh::TetMesh& m, const std::vector<BodyInterface>& bodies);

/// J (3N × #T), see the file comment. [Chentanez06, Eq. (6)]
SparseMatrix build_J(const mesh::TetMesh& m, const std::vector<BodyInterface>& bodies);

/// Nodal forces (3N) of a pressure field given as a function, evaluated at the Solid faces'
/// centroids: F_a = Σ_f w_a A_f p(x_f) n_f. For a pressure linear in x (hydrostatics,
/// p = −ρ g·x + c) this is exact on flat triangles: the buoyancy of a body comes out as ρ g V
/// to round-off, whereas J applied to that pressure sampled at the circumcentres is only
/// first order (measured 16 % at 0.06 m cells, 6.6 % at 0.03 m on a 0.15 m sphere). The
/// coupled solve should apply the hydrostatic part ρ g·x of a liquid's pressure this way and
/// J to the rest.
/// @param pressure p(x) (Pa) at a point (m)
template <class Pressure>
VecX face_pressure_forces(const mesh::TetMesh& m, const std::vector<BodyInterface>& bodies,
                          Pressure&& pressure);

/// D1 (#T × #F): the boundary part of the divergence, (D1 u)_t = (1/V_t) Σ_{f ∈ t, Solid}
/// A_f u_f (s_tf = +1: boundary normals point out of the fluid). [Chentanez06, Eq. (7)]
SparseMatrix build_D1(const mesh::TetMesh& m);

/// The Solid faces with their body-node DOF blocks and weights (for face_pressure_forces).
struct InterfaceFace {
  Index face = -1;
  Index node[3] = {-1, -1, -1};  ///< stacked node indices
  double weight[3] = {0, 0, 0};
};
std::vector<InterfaceFace> interface_faces(const mesh::TetMesh& m,
                                           const std::vector<BodyInterface>& bodies);

template <class Pressure>
VecX face_pressure_forces(const mesh::TetMesh& m, const std::vector<BodyInterface>& bodies,
                          Pressure&& pressure) {
  VecX F = VecX::Zero(3 * node_offsets(bodies).back());
  for (const InterfaceFace& i : interface_faces(m, bodies)) {
    const Vec3 x = m.face_centroids.row(i.face).transpose();
    const Vec3 an = m.face_areas[i.face] * pressure(x) * m.face_normals.row(i.face).transpose();
    for (int k = 0; k < 3; ++k) F.segment<3>(3 * i.node[k]) += i.weight[k] * an;
  }
  return F;
}

}  // namespace tetfsi::coupling
