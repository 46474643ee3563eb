#pragma once
/// @file volume_mesh.hpp
/// Plain tetrahedral and triangle meshes as they come from files or generators, plus the
/// geometric checks every solid body passes before it is simulated.
#include <string>
#include <vector>

#include <Eigen/Geometry>  // cross()

#include "core/types.hpp"

namespace tetfsi::mesh {

/// A tetrahedral mesh: positions and positively oriented tets.
struct VolumeMesh {
  MatX3 vertices;  ///< #V × 3 positions (m)
  MatX4i tets;     ///< #T × 4 zero-based vertex indices; signed volume > 0
  Index num_vertices() const { return static_cast<Index>(vertices.rows()); }
  Index num_tets() const { return static_cast<Index>(tets.rows()); }
};

/// A triangle surface mesh (for closed surfaces: outward normals by the right-hand rule).
struct SurfaceMesh {
  MatX3 vertices;    ///< #V × 3 positions (m)
  MatX3i triangles;  ///< #F × 3 zero-based vertex indices
  Index num_vertices() const { return static_cast<Index>(vertices.rows()); }
  Index num_triangles() const { return static_cast<Index>(triangles.rows()); }
};

/// Signed volume of tet (a, b, c, d): (b − a) · ((c − a) × (d − a)) / 6.
inline double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

/// Signed volume of tet t of `m`.
double tet_volume(const VolumeMesh& m, Index t);

/// Total (signed) volume of the mesh (m³).
double total_volume(const VolumeMesh& m);

/// Check a tet mesh: finite coordinates, indices in range, four distinct vertices per tet,
/// every tet positively oriented and not degenerate (volume > 1e-12 · (mean edge)³, the
/// mean of the tet's own six edge lengths, so the test does not depend on units or grading).
/// @param source file name or description used in the message ("data/meshes/bar.msh")
/// @throws MeshError naming `source`, the first bad tet (index and vertices) and the fix,
///   e.g. "bar.msh: tet 17 (vertices 3 9 12 40) is inverted (signed volume -1.2e-06 m^3);
///   fix the element's vertex order or remesh" (one line). An empty mesh is an error too.
void validate_volume_mesh(const VolumeMesh& m, const std::string& source);

/// The ids a file uses for the vertices and tets of a mesh (Gmsh node/element tags, TetGen
/// numbers), so that error messages point at what the user sees in the file.
struct MeshLabels {
  std::vector<long long> vertex_ids;  ///< #V file id of each vertex (empty: zero-based index)
  std::vector<long long> tet_ids;     ///< #T file id of each tet (empty: zero-based index)
};

/// validate_volume_mesh, but messages say "element <tet_ids[t]> (nodes <vertex_ids[..]>)"
/// instead of zero-based indices where `labels` provides ids.
void validate_volume_mesh(const VolumeMesh& m, const std::string& source, const MeshLabels& labels);

/// If every tet is negatively oriented (a file written with the opposite convention), swap
/// two vertices of each so that all are positive. Mixed orientations are left alone (and
/// `validate_volume_mesh` then reports the first inverted tet), and so is a mesh with an
/// out-of-range index. Swaps columns 2 and 3. Returns true if flipped.
bool fix_global_orientation(VolumeMesh& m);

/// Remove vertices no tet uses and renumber (keeping the order of the rest). Returns the
/// number removed. A mesh with an out-of-range index is left unchanged (0 returned).
/// @param old_index optional output (#V_new): the index each kept vertex had before.
Index remove_unused_vertices(VolumeMesh& m, VecXi* old_index = nullptr);

/// The boundary triangles of a tet mesh: faces that belong to exactly one tet, oriented with
/// outward normals, as indices into `m.vertices` (#B × 3), in order of (tet, local face).
/// Expects positively oriented tets (validate_volume_mesh). Linear time (hash of the sorted
/// vertex triple).
/// @param owner_tet optional output (#B): for each boundary triangle, the tet it belongs to.
/// @throws MeshError if a face belongs to more than two tets (non-manifold).
MatX3i boundary_triangles(const VolumeMesh& m, VecXi* owner_tet = nullptr);

/// Check a triangle surface is closed and consistently oriented (every edge shared by
/// exactly two triangles, once in each direction), has no degenerate triangle and encloses
/// positive volume.
/// @throws MeshError naming `source` and the first offending edge or triangle.
void validate_closed_surface(const SurfaceMesh& s, const std::string& source);

}  // namespace tetfsi::mesh
