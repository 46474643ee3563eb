#pragma once
/// @file tetrahedralize.hpp
/// Tetrahedralise the inside of a closed triangle surface with CGAL Mesh_3; which points lie
/// inside one.
#include <string>
#include <vector>

#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

struct TetrahedralizeParams {
  double cell_size = 0.0;         ///< target tet circumradius bound (m); > 0 required
  double facet_distance = 0.0;    ///< surface approximation error (m); 0 → cell_size / 10
  double facet_angle_deg = 25.0;  ///< lower bound on surface triangle angles
  double cell_radius_edge = 3.0;  ///< upper bound on tet radius-edge ratio
  bool lloyd = false;             ///< run Lloyd optimisation (slower, better shapes)
  bool exude = true;              ///< run sliver exudation
};

/// Mesh the region bounded by `surface` (validated closed first).
/// @param source name used in error messages
/// @throws MeshError if the surface is not closed or meshing yields no tets.
VolumeMesh tetrahedralize_surface(const SurfaceMesh& surface, const TetrahedralizeParams& params,
                                  const std::string& source);

/// For each point, whether it lies strictly inside `surface` (validated closed and free of
/// self-intersections first; CGAL's Side_of_triangle_mesh over an AABB tree, exact predicates):
/// 1 inside, 0 outside or on the surface.
/// @param source name used in error messages
/// @throws MeshError if the surface is open, not manifold or intersects itself.
std::vector<char> inside_surface(const SurfaceMesh& surface, const std::vector<Vec3>& points,
                                 const std::string& source);

}  // namespace tetfsi::mesh
