#pragma once
/// @file remesh.hpp
/// The fluid remesher: every time step a new Delaunay tet mesh of the fluid domain around
/// the current solid boundary triangles (docs/method/dynamic_mesh.md). The implementation is
/// in mesh/remesh*.cpp, one function per stage of the internal RemeshContext
/// (remesh_stages.hpp); CGAL only in delaunay.cpp.
///
/// Steps:
///  1. vertex placement: a graded BCC lattice (corners and centres of the leaves of a
///     2:1-balanced octree; 60° minimum dihedral in uniform regions) whose spacing follows the
///     sizing field; lattice points closer to a solid than half their spacing, or inside a
///     solid sub-triangle's diametral sphere, are dropped; box-face points are jittered within
///     the face where the octree is uniform; on a commensurate box the Delaunay runs in lattice
///     units (exact integer lattice coordinates);
///  2. surface vertices: every solid boundary vertex, plus Steiner points (Rivara longest-edge
///     bisection) until sub-triangles are at most 1.5 × surface_size long and Gabriel (empty
///     diametral spheres, down to 0.1 × surface_size);
///  3. Delaunay tetrahedralisation with CGAL (range insertion, spatially sorted);
///  4. conformity recovery: every solid boundary triangle must be exactly a union of mesh
///     faces. A triangle that is not is split by Steiner points inserted on the solid surface
///     (recording triangle and barycentric position), and the check repeats; flat cells over
///     two coplanar triangles are split away the same way, and so are flat cells of surface
///     points across an edge of a cavity (in the fluid); slivers touching a solid lose a
///     lattice vertex, cells away from the solids under 10° get one perturbed; cells whose
///     volume in metres is round-off (coplanar points, e.g. a co-circular trapezoid of a
///     lattice edge and a sheet's edge; positive only in the Delaunay's lattice units) keep
///     losing a lattice vertex after that, so no fluid cell has V ≤ 0;
///  5. cells inside any solid are removed by a flood fill between solid faces and one winding
///     number per region (a fluid region enclosed by a solid stays fluid); the fluid volume is
///     checked against box − solids;
///  6. faces are tagged: walls / inflow / open patches of the box, solid interface faces with
///     body, triangle and barycentric weights of the centroid (normal from fluid into solid).
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::mesh {

/// A rectangle on one side of the domain box with its own boundary kind.
struct DomainPatch {
  std::string name;
  FaceKind kind = FaceKind::Open;  ///< Wall, Inflow or Open
  int side = 0;                    ///< 0..5 = −x, +x, −y, +y, −z, +z
  /// Rectangle in the side's two other coordinates, in increasing axis order (for side ±y:
  /// (x, z)). A face belongs to the patch if its centroid is inside (1e-9 m tolerance).
  Vec2 lo = Vec2::Zero(), hi = Vec2::Zero();
};

/// The fluid domain: an axis-aligned box; faces not on a patch get `default_kind`.
struct FluidDomain {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Ones();
  FaceKind default_kind = FaceKind::Wall;
  std::vector<DomainPatch> patches;  ///< later patches win where they overlap
};

/// A solid body's boundary at its current position: a closed, outward-oriented triangle
/// surface (e.g. mesh::boundary_triangles of the body's tets with the deformed positions).
struct SolidSurface {
  int body = 0;      ///< body index, copied to TetMesh::face_body / vertex_body
  MatX3 vertices;    ///< #Vs × 3 (m)
  MatX3i triangles;  ///< #Ts × 3, outward normals
};

/// Target edge length of the fluid mesh.
struct Sizing {
  double surface_size = 0.05;  ///< m, at solid surfaces
  double far_size = 0.2;       ///< m, the largest spacing
  /// Size grows away from solids as surface_size + grading × distance (capped at far_size).
  double grading = 0.5;
  /// Optional refinement field from the fluid (smoke, vorticity): the desired size at x (m),
  /// or ≤ 0 / +inf for "no request". The size used is the minimum of all requests.
  std::function<double(const Vec3&)> refine;
  /// Cell budget: if > 0 and the placement would exceed it, all sizes are scaled up so the
  /// mesh stays within the budget (logged).
  Index max_cells = 0;
  /// Each conformity recovery round re-examines only the cells the last round changed
  /// (true), or every cell touching a solid (false: the reference; the same mesh, slower).
  bool local_recovery = true;
  /// With a Remesher: start from the last remesh's triangulation, removing the vertices that
  /// are not in the new vertex set and inserting the new ones, instead of a new Delaunay
  /// (false: always a full rebuild). The same mesh either way, bit for bit.
  bool incremental = true;
  /// The incremental path is taken while its estimated cost, (2 × removed + inserted) /
  /// vertices (a removal costs about 2 insertions, Delaunay::kRemovalCost), is at most this;
  /// a full rebuild costs 1 (it inserts every vertex).
  double incremental_max_cost = 1.0;
  /// A full Delaunay (the first remesh, or a rebuild) inserts its points with CGAL's
  /// parallel range insertion on the threads (Delaunay::build). The same mesh, bit for bit.
  bool parallel_insertion = false;
};

struct RemeshOptions {
  int max_recovery_rounds = 30;  ///< rounds of Steiner insertion before giving up
};

struct RemeshReport {
  Index lattice_points = 0;         ///< fluid samples kept
  Index surface_points = 0;         ///< solid boundary vertices inserted
  Index steiner_points = 0;         ///< points added on solid triangles (placement + recovery)
  Index sliver_points_removed = 0;  ///< lattice points deleted to remove slivers at the surface
  Index sliver_points_moved = 0;    ///< lattice points perturbed to remove slivers away from it
  Index cells_delaunay = 0;         ///< finite Delaunay cells before removal
  Index cells_removed = 0;          ///< cells inside solids
  Index flat_cells_removed = 0;     ///< of those: flat cells lying on a solid surface (remesh.cpp)
  /// Solid faces of flat cells that straddle two coplanar solid triangles, left when the round
  /// budget ran out before they were split away: each is attributed to the triangle holding
  /// its centroid, so those two triangles are tiled only together (0 in every test).
  Index straddling_faces = 0;
  int recovery_rounds = 0;  ///< rounds that added Steiner points after the Delaunay
  int cleanup_rounds = 0;   ///< sliver passes (perturbation, deletion) after conformity
  /// Of seconds_recovery: the conformity checks (surface faces, missing triangles, flat
  /// cells), the Steiner insertions, and the sliver passes.
  double seconds_recovery_check = 0, seconds_recovery_insert = 0, seconds_recovery_slivers = 0;
  /// The Delaunay came from the last remesh's (Remesher, Sizing::incremental) by removing
  /// vertices_removed and inserting vertices_inserted; a full rebuild inserts every vertex.
  bool incremental = false;
  Index vertices_removed = 0, vertices_inserted = 0;
  double size_scale = 1.0;  ///< factor the cell budget (Sizing::max_cells) scaled all sizes by
  double seconds_placement = 0, seconds_delaunay = 0, seconds_recovery = 0, seconds_classify = 0,
         seconds_build = 0, seconds_total = 0;
};

/// Build the fluid mesh. The result satisfies: every solid triangle is a union of Solid
/// faces; Σ V_t = box volume − solid volumes (+ enclosed fluid regions) to round-off;
/// interior faces have d_f ≥ 0 (Delaunay); face_bary in [0, 1] and summing to 1.
/// @throws InputError for bad sizing (≤ 0, non-finite) or a solid not inside the box.
/// @throws MeshError naming body and triangle if conformity is not reached in
///   `max_recovery_rounds`, or if surfaces intersect.
TetMesh remesh(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
               const Sizing& sizing, RemeshReport* report = nullptr,
               const RemeshOptions& options = {});

namespace detail {
struct IncrementalState;
}

/// A remesher that keeps the last triangulation it made, so that the next remesh can start
/// from it (Sizing::incremental): the fluid solver's one per run. Its meshes are those of
/// mesh::remesh, bit for bit, whatever the path (the cells are put in a canonical order, and
/// CGAL's Delaunay does not depend on the order of insertions and removals). The first call,
/// a call after one that failed past its Delaunay, after reset(), or one whose lattice frame
/// changed (box or spacing; the cell budget rescaled the sizes) rebuilds in full, and so does
/// a call whose update would cost more than Sizing::incremental_max_cost; after such a call
/// the next 1, 2, 4, then 8 calls rebuild without trying (the try hashes every point).
class Remesher {
 public:
  Remesher();
  ~Remesher();
  Remesher(Remesher&&) noexcept;
  Remesher& operator=(Remesher&&) noexcept;
  /// As mesh::remesh.
  TetMesh remesh(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
                 const Sizing& sizing, RemeshReport* report = nullptr,
                 const RemeshOptions& options = {});
  /// Forget the kept triangulation (the next remesh rebuilds in full).
  void reset();

 private:
  std::unique_ptr<detail::IncrementalState> m_state;
};

/// The checks remesh() makes on the solids before it meshes, for a fluid that is not meshed
/// (the grid): each surface closed and strictly inside the box, no surface intersecting
/// itself or another, no body inside another. Messages start with `stage`.
/// @throws MeshError naming the body (by SolidSurface::body) and the triangles.
void check_solid_surfaces(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
                          const std::string& stage);

/// The bare CGAL Delaunay tetrahedralisation of a point set (finite cells, positively
/// oriented): the floor `tetfsi bench remesh` compares the remesher against.
MatX4i delaunay_tets(const MatX3& points);

}  // namespace tetfsi::mesh
