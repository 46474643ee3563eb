#pragma once
/// @file tet_mesh.hpp
/// The fluid's tetrahedral mesh with everything the fluid and the coupling read from it:
/// unique oriented faces, tet–face incidence with signs, neighbours, circumcentres, dual
/// lengths, volumes and boundary tags [KFCO06, §3], [Chentanez06, §3.3].
///
/// Conventions (every module relies on them):
///  - tets are positively oriented (signed volume > 0);
///  - each face f has a fixed unit normal n_f = (v1 − v0) × (v2 − v0) / |…| of its stored
///    vertex order `faces(f, :)`;
///  - `face_tets(f, 0)` = t1 is the tet n_f points *out of*; `face_tets(f, 1)` = t2 the tet it
///    points *into*, or −1 on the boundary. So on the boundary n_f points out of the fluid —
///    for a solid-interface face, from the fluid into the solid;
///  - `tet_face_signs(t, k)` = +1 if n_f of face `tet_faces(t, k)` points out of t, −1 if into
///    it: the divergence is (D u)_t = (1/V_t) Σ_k s_tk A_f u_f [docs/method/tet_fluid.md];
///  - dual length d_f = (c_t2 − c_t1) · n_f for interior faces (≥ 0 on a Delaunay mesh), and
///    d_f = (x_f − c_t1) · n_f for boundary faces (x_f the face centroid): the signed distance
///    from the tet's circumcentre to the face plane, used for Dirichlet (open) faces;
///  - local face k of a tet is the face opposite its local vertex k.
#include <cstdint>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "core/enum_names.hpp"
#include "core/types.hpp"

namespace tetfsi::mesh {

/// What a face is. Interior faces separate two fluid tets; the others are on the boundary
/// of the fluid domain.
enum class FaceKind : std::uint8_t {
  Interior = 0,
  Wall = 1,    ///< zero normal flux (box walls)
  Inflow = 2,  ///< prescribed normal velocity (jets)
  Open = 3,    ///< prescribed pressure
  Solid = 4,   ///< on a solid body's boundary triangle (moves with the solid)
};

inline constexpr EnumNames<FaceKind, 5> k_face_kind_names{"face kind",
                                                          {{{FaceKind::Interior, "interior"},
                                                            {FaceKind::Wall, "wall"},
                                                            {FaceKind::Inflow, "inflow"},
                                                            {FaceKind::Open, "open"},
                                                            {FaceKind::Solid, "solid"}}}};
/// "interior", "wall", "inflow", "open", "solid".
const char* to_string(FaceKind k);

using MatX2i = Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>;
using MatX4s = Eigen::Matrix<std::int8_t, Eigen::Dynamic, 4, Eigen::RowMajor>;

struct TetMesh {
  // ---- cells ----
  MatX3 vertices;         ///< #V × 3 positions (m)
  MatX4i tets;            ///< #T × 4 vertex indices, positively oriented
  MatX4i tet_faces;       ///< #T × 4: face opposite local vertex k
  MatX4s tet_face_signs;  ///< #T × 4: +1 if n_f points out of the tet, −1 if into it
  MatX4i neighbours;      ///< #T × 4: tet across local face k, −1 on the boundary
  VecX volumes;           ///< #T (m³)
  MatX3 circumcentres;    ///< #T × 3 (m)

  // ---- faces ----
  MatX3i faces;        ///< #F × 3 vertex indices; the order defines n_f
  MatX2i face_tets;    ///< #F × 2: (t1, t2), n_f points from t1 into t2; t2 = −1 on the boundary
  VecX face_areas;     ///< #F (m²)
  MatX3 face_normals;  ///< #F × 3 unit normals
  MatX3 face_centroids;  ///< #F × 3 (m)
  VecX dual_lengths;     ///< #F d_f (m), see the conventions above

  // ---- boundary tags (filled by the remesher; build_tet_mesh sets Wall / −1 / 0) ----
  std::vector<FaceKind> face_kind;  ///< #F
  VecXi face_patch;     ///< #F: index into FluidDomain::patches, −1 if not from a patch
  VecXi face_body;      ///< #F: solid body index for Solid faces, −1 otherwise
  VecXi face_triangle;  ///< #F: triangle of that body's SolidSurface, −1 otherwise
  MatX3 face_bary;      ///< #F × 3: barycentric weights of the face centroid on that triangle
                        ///< (Solid faces; each in [0, 1], summing to 1), 0 otherwise

  // ---- vertex provenance (filled by the remesher; build_tet_mesh sets −1 / 0) ----
  VecXi vertex_body;      ///< #V: body whose surface the vertex lies on, −1 for fluid samples
  VecXi vertex_triangle;  ///< #V: a triangle of that body's surface containing the vertex
  MatX3 vertex_bary;      ///< #V × 3: its barycentric position on that triangle

  Index num_vertices() const { return static_cast<Index>(vertices.rows()); }
  Index num_tets() const { return static_cast<Index>(tets.rows()); }
  Index num_faces() const { return static_cast<Index>(faces.rows()); }
  bool is_boundary(Index f) const { return face_tets(f, 1) < 0; }
};

/// Build faces, incidence, neighbours and geometry from positions and positively oriented
/// tets. Interior faces are oriented from the tet with the smaller index to the larger;
/// boundary faces outward. Boundary faces are tagged Wall, every provenance field −1 / 0.
/// Linear time (hash of sorted vertex triples).
/// Faces are numbered in order of first appearance (tet 0's faces first), which keeps them
/// as spatially coherent as the tets. Measured (one core): 0.29 s for a 1M-tet make_box mesh
/// (about 40 % of it allocating and filling the geometry arrays), 0.5 s with its vertex and
/// tet numbering shuffled.
/// @throws MeshError naming the tet or face if a vertex index is out of range, a tet is not
///   positively oriented (signed volume ≤ 0), a face has more than two tets, or two tets lie
///   on the same side of their common face (overlap).
TetMesh build_tet_mesh(MatX3 vertices, MatX4i tets);

/// build_tet_mesh with the neighbours known (tet across local face k, the face opposite
/// vertex k; −1 on the boundary), e.g. from a Delaunay: no face hashing, the same TetMesh as
/// build_tet_mesh(vertices, tets) gives, face numbering included. Less memory and time
/// (the remesher's TetMesh phase at 245k cells: docs/results/performance.md).
/// @throws MeshError naming the tets if a neighbour is out of range, does not name the tet
///   back or does not share the face; as build_tet_mesh for the tets themselves.
TetMesh build_tet_mesh(MatX3 vertices, MatX4i tets, const MatX4i& neighbours);

/// Recompute volumes, circumcentres, face areas, normals, centroids and dual lengths from
/// `vertices` (connectivity unchanged). Checks nothing: a tet the move inverted gets a
/// negative volume (summarize_quality counts them), a flat one non-finite circumcentre and
/// dual lengths.
void update_geometry(TetMesh& m);

/// Circumcentre of a tet (m). For a degenerate tet the result is not finite.
Vec3 circumcentre(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Centroid of tet t, the mean of its 4 vertices (m).
inline Vec3 tet_centroid(const TetMesh& m, Index t) {
  Vec3 x = Vec3::Zero();
  for (int i = 0; i < 4; ++i) x += 0.25 * m.vertices.row(m.tets(t, i)).transpose();
  return x;
}

/// Total volume Σ V_t (m³).
/// A mesh as checkpoint records under `prefix` (core/checkpoint.hpp): the vertices, tets, face
/// tags and vertex provenance; everything else is rebuilt by build_tet_mesh, which is how the
/// remesher made it, so load_mesh(save_mesh(m)) equals m in every array, bit for bit.
void save_mesh(const TetMesh& m, CheckpointWriter& w, const std::string& prefix);
/// @throws CheckpointError naming the record if the tags do not fit the mesh.
TetMesh load_mesh(const CheckpointReader& r, const std::string& prefix);

double total_volume(const TetMesh& m);

/// Σ over boundary faces of A_f n_f: zero for a closed mesh (a consistency check).
Vec3 boundary_area_vector(const TetMesh& m);

/// Groups of co-spherical cells: cells joined through interior faces whose dual length is
/// |d_f| ≤ rel_tol × (mean edge of the face) share one id (0..#groups−1, by first cell).
/// Such cells have the same circumcentre, i.e. one Voronoi vertex: the circumcentric
/// pressures of a group are one unknown, and the faces inside a group (A_f/d_f = ∞) drop
/// out of the pressure Laplacian. A Delaunay mesh of points in special position (lattices)
/// has many; the remesher's octree transitions leave about 8 % of the interior faces so.
/// @return #T group ids; `num_groups` (optional) receives their number
VecXi cospherical_groups(const TetMesh& m, double rel_tol = 1e-9, Index* num_groups = nullptr);

}  // namespace tetfsi::mesh
