#pragma once
/// @file remesh_stages.hpp
/// Internal to tetfsi::mesh (not installed, not API; the entry point is remesh.hpp): the
/// stages of mesh::remesh as member functions of one context struct, RemeshContext, and the
/// plain types they share. No CGAL here: the Delaunay is behind delaunay.hpp.
///
/// Files (all CGAL-free, each compiles in seconds):
///  - remesh.cpp:          the driver (stage order, timings) and stage 0, the inputs;
///  - remesh_surface.cpp:  the refined solid surfaces (RefinedSurface, refine_surface);
///  - remesh_lattice.cpp:  stages 1–2, vertex placement (octree BCC lattice, exclusion near
///                         the surfaces, cell budget) and the Delaunay's coordinates;
///  - remesh_recovery.cpp: stage 4, conformity recovery, slivers, and the cell predicates;
///  - remesh_classify.cpp: stage 5, cells inside solids, and stage 6, the TetMesh and tags.
#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <set>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/types.hpp"
#include "mesh/delaunay.hpp"
#include "mesh/geometry.hpp"
#include "mesh/remesh.hpp"
#include "mesh/tet_mesh.hpp"
#include "mesh/triple_map.hpp"

namespace tetfsi::mesh::detail {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------
// Geometry helpers and keys
// ---------------------------------------------------------------------------------------

/// Circumcentre of triangle abc in its plane (the centre of its diametral sphere).
Vec3 triangle_circumcentre(const Vec3& a, const Vec3& b, const Vec3& c);

/// Generalised winding number of a closed, outward-oriented triangle surface at p: 1 inside,
/// 0 outside [van Oosterom & Strackee 1983 solid angle].
/// @param V surface vertices (#V × 3, m)
/// @param T triangles (#T × 3, outward normals)
double winding_number(const Vec3& p, const MatX3& V, const MatX3i& T);

inline std::uint64_t pack3(std::uint64_t i, std::uint64_t j, std::uint64_t k) {
  return i | (j << 21) | (k << 42);
}
inline std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}
inline TripleKey sorted_key(int a, int b, int c) {
  sort3(a, b, c);
  return {a, b, c};
}

/// Uniform hash grid of integer items registered by boxes.
class HashGrid {
 public:
  explicit HashGrid(double cell) : m_inv(1.0 / cell) {}
  void add_box(const Vec3& lo, const Vec3& hi, int item) {
    const Eigen::Vector3i a = cell_of(lo), b = cell_of(hi);
    for (int k = a.z(); k <= b.z(); ++k)
      for (int j = a.y(); j <= b.y(); ++j)
        for (int i = a.x(); i <= b.x(); ++i) m_cells[key(i, j, k)].push_back(item);
  }
  void add_point(const Vec3& p, int item) {
    const Eigen::Vector3i c = cell_of(p);
    m_cells[key(c.x(), c.y(), c.z())].push_back(item);
  }
  /// Items of the cell containing p (nullptr if none).
  const std::vector<int>* at(const Vec3& p) const {
    const Eigen::Vector3i c = cell_of(p);
    auto it = m_cells.find(key(c.x(), c.y(), c.z()));
    return it == m_cells.end() ? nullptr : &it->second;
  }
  /// Call f(item) for every item of every cell overlapping [lo, hi] (items may repeat).
  template <class F>
  void for_box(const Vec3& lo, const Vec3& hi, F&& f) const {
    const Eigen::Vector3i a = cell_of(lo), b = cell_of(hi);
    for (int k = a.z(); k <= b.z(); ++k)
      for (int j = a.y(); j <= b.y(); ++j)
        for (int i = a.x(); i <= b.x(); ++i) {
          auto it = m_cells.find(key(i, j, k));
          if (it != m_cells.end())
            for (int item : it->second) f(item);
        }
  }

 private:
  Eigen::Vector3i cell_of(const Vec3& p) const { return (p * m_inv).array().floor().cast<int>(); }
  static std::uint64_t key(int i, int j, int k) {
    const std::uint64_t o = 1u << 20;
    return pack3(static_cast<std::uint64_t>(i + o) & 0x1FFFFF,
                 static_cast<std::uint64_t>(j + o) & 0x1FFFFF,
                 static_cast<std::uint64_t>(k + o) & 0x1FFFFF);
  }
  double m_inv;
  std::unordered_map<std::uint64_t, std::vector<int>> m_cells;
};

// ---------------------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------------------

/// The solid triangles of every body in one list ("global" triangle ids).
struct SolidSet {
  const std::vector<SolidSurface>* solids = nullptr;
  std::vector<int> tri_offset;  ///< per body, first global triangle id (size #bodies + 1)
  std::vector<int> tri_body;    ///< per global triangle
  std::vector<std::array<Vec3, 3>> corners;
  std::vector<Vec3> box_lo, box_hi;  ///< per global triangle
  std::vector<Vec3> body_lo, body_hi;
  double area(int g) const {
    return 0.5 * (corners[g][1] - corners[g][0]).cross(corners[g][2] - corners[g][0]).norm();
  }
  int local(int g) const { return g - tri_offset[tri_body[g]]; }
};

/// Size requested at x (m): graded from the surface, capped at far, and the refinement field.
struct SizeField {
  const Sizing* sizing;
  double scale = 1.0;  ///< > 1 when the cell budget coarsens everything
  double surface() const { return scale * sizing->surface_size; }
  double far() const { return scale * sizing->far_size; }
  double at(const Vec3& x, double dist) const {
    double s = std::min(far(), surface() + sizing->grading * dist);
    if (sizing->refine) {
      const double r = sizing->refine(x);
      if (r > 0 && std::isfinite(r)) s = std::min(s, scale * r);
    }
    return s;
  }
};

// ---------------------------------------------------------------------------------------
// The solid surfaces, refined: points with their triangles and barycentric positions
// (remesh_surface.cpp)
// ---------------------------------------------------------------------------------------

struct SurfacePoint {
  Vec3 x;
  int body = 0;
  std::vector<std::pair<int, Vec3>> on;  ///< (global triangle, barycentric weights on it)
};

struct SubTri {
  int v[3];
  int tri;  ///< global triangle it lies on
  bool alive = true;
};

/// The solid surfaces as a refinable set of sub-triangles: every body vertex once, plus
/// Steiner points, each knowing the global triangles it lies on and its barycentric weights
/// there; sub-triangles keep their edge adjacency for Rivara (LEPP) bisection.
class RefinedSurface {
 public:
  /// One point per body vertex and one sub-triangle per solid triangle.
  explicit RefinedSurface(const SolidSet& set);

  std::vector<SurfacePoint> points;
  std::vector<int> body_vertex;  ///< per point: the body's vertex index, −1 for Steiner points
  std::vector<SubTri> subs;

  const Vec3& x(int p) const { return points[p].x; }
  /// Barycentric weights of point p on global triangle g (it must lie on it).
  Vec3 bary(int p, int g) const {
    for (const auto& [t, w] : points[p].on)
      if (t == g) return w;
    throw InternalError("remesh: surface point not on its triangle");
  }
  /// Longest edge of sub s as (a, b); ties broken by the edge key, so that "longest" is a
  /// strict order and LEPP paths end.
  std::pair<int, int> longest_edge(const SubTri& s, double* len = nullptr) const;
  /// Centre c and squared radius r2 (m²) of sub s's diametral sphere.
  void diametral(const SubTri& s, Vec3& c, double& r2) const {
    c = triangle_circumcentre(x(s.v[0]), x(s.v[1]), x(s.v[2]));
    r2 = (x(s.v[0]) - c).squaredNorm();
  }
  /// Split edge (a, b) at the fraction t from its lexicographically smaller end (the midpoint
  /// by default), and the (one or two) sub-triangles on it. Returns the new point, or −1 if
  /// the edge no longer exists.
  int split_edge(int a, int b, std::vector<int>* new_subs = nullptr, double t = 0.5);
  /// Refine each listed sub-triangle (if still alive) by Rivara's longest-edge propagation
  /// path: walk to the neighbour across the longest edge until the edge is the longest of both
  /// triangles, split it there, repeat until the sub-triangle itself is split. Angles stay
  /// bounded below (no ever-thinner triangles). Edges are split at `at` (split_edge). Returns
  /// the number of points added.
  int refine_subs(const std::vector<int>& list, std::vector<int>* new_subs = nullptr,
                  double at = 0.5);
  /// The alive sub-triangles on the edge between points a and b (−1 for none).
  std::array<int, 2> subs_on_edge(int a, int b) const {
    auto it = m_edges.find(edge_key(a, b));
    return it == m_edges.end() ? std::array<int, 2>{-1, -1} : it->second;
  }
  /// The alive sub-triangle with points a, b, c, or −1.
  int sub_with(int a, int b, int c) const {
    for (int s : subs_on_edge(a, b))
      if (s >= 0 && (subs[s].v[0] == c || subs[s].v[1] == c || subs[s].v[2] == c)) return s;
    return -1;
  }
  /// The alive sub-triangles of global triangle g, in increasing order.
  const std::vector<int>& subs_of(int g) const { return m_by_tri[g]; }

 private:
  int add_sub(const SubTri& st);
  void remove_sub(int s);
  const SolidSet& m_set;
  std::unordered_map<std::uint64_t, std::array<int, 2>> m_edges;
  std::vector<std::vector<int>> m_by_tri;  ///< per global triangle: its alive subs
};

/// Refine the surfaces: split sub-triangles longer than the surface size, then until every
/// sub-triangle's diametral sphere holds no other surface point (Gabriel: then each is a
/// Delaunay face of any superset that keeps the spheres empty).
void refine_surface(RefinedSurface& surf, const SizeField& size, int max_rounds);

// ---------------------------------------------------------------------------------------
// Vertex placement (remesh_lattice.cpp)
// ---------------------------------------------------------------------------------------

/// The points of the graded BCC lattice (Octree in remesh_lattice.cpp).
struct Lattice {
  std::vector<Vec3> points;
  std::vector<double> size;  ///< local spacing of each point (m)
  /// If the octree is isotropic (one root size in every axis), the Delaunay is computed in
  /// lattice units y = (x − lo) / unit, where lattice points have exact integer coordinates
  /// (`y`): x = lo + q·unit is rounded, which turns exactly coplanar lattice points (many, at
  /// octree transitions) into nearly flat cells. Delaunay is invariant under this similarity.
  bool isotropic = false;
  double unit = 1.0;
  std::vector<Vec3> y;
};

// ---------------------------------------------------------------------------------------
// The stages
// ---------------------------------------------------------------------------------------

/// What a Remesher keeps between calls: the last triangulation (after its recovery) and the
/// frame of its coordinates (RemeshContext::to_dt), valid only if the new one is the same.
struct IncrementalState {
  Delaunay dt;
  bool valid = false;
  /// After an update that cost too much (a rebuild), the next `skip` remeshes rebuild without
  /// trying (the try costs a hash of every point); `backoff` doubles at each such rebuild, up
  /// to 8, and is 0 after an update. Only the path depends on them, never the mesh.
  int skip = 0, backoff = 0;
  bool isotropic = false;
  double unit = 0.0;
  Vec3 lo = Vec3::Zero();
};

/// Everything the stages of one mesh::remesh call share. The driver (remesh.cpp) runs
/// check_inputs, place_vertices, collect_points, build_delaunay, recover_conformity,
/// classify_cells, collect_fluid_cells, check_fluid_volume and build_fluid_mesh in that
/// order; each stage's comment says what it reads and writes here. Vertex ids: the Delaunay
/// and `pts` number lattice points 0..nL−1, then surface point p as nL + p.
struct RemeshContext {
  RemeshContext(const FluidDomain& domain_, const std::vector<SolidSurface>& solids_,
                const Sizing& sizing_, const RemeshOptions& options_)
      : domain(domain_), solids(solids_), sizing(sizing_), options(options_), size{&sizing_} {}
  RemeshContext(const RemeshContext&) = delete;
  RemeshContext& operator=(const RemeshContext&) = delete;

  // ---- inputs (read by every stage) ----
  const FluidDomain& domain;
  const std::vector<SolidSurface>& solids;
  const Sizing& sizing;
  const RemeshOptions& options;
  SolidSet set;  ///< the solids' triangles (check_inputs)

  // ---- stages 1–2: placement ----
  SizeField size;                        ///< scaled by the cell budget (place_vertices)
  Lattice lat;                           ///< all lattice points (place_vertices)
  std::vector<char> keep;                ///< per lattice point, 1 = kept (place_vertices)
  std::unique_ptr<RefinedSurface> surf;  ///< refined in place_vertices and recovery
  std::vector<Vec3> pts;        ///< every vertex (m): kept lattice points, then surface points
  std::vector<Vec3> dt_pts;     ///< the same points in the Delaunay's coordinates (to_dt)
  std::vector<double> pt_size;  ///< lattice points: their local spacing (m)
  int nL = 0;                   ///< number of kept lattice points

  // ---- stage 3: Delaunay ----
  Delaunay dt;  ///< vertex ids = indices into pts (removed lattice points are absent)

  // ---- stage 4: conformity recovery ----
  std::vector<double> tri_area;  ///< per global triangle (m²)
  /// Lattice points near the solids, to drop those inside new sub-triangles' spheres.
  HashGrid lattice_grid{1.0};
  std::vector<char> lattice_removed;  ///< per lattice point: deleted from the Delaunay
  MatX4i tets, nbrs;                  ///< the final Delaunay cells and their neighbours
  /// The Delaunay cells with at least three surface vertices (ids, positively oriented),
  /// each in the list of its smallest surface vertex (index v − nL): every face of three
  /// surface vertices is a face of one of them. Kept up to date from the Delaunay's changes
  /// (sync_surface_cells), so a recovery round costs what changed, not a pass over every cell.
  std::vector<std::vector<std::array<int, 4>>> surface_cells;
  /// The surface_cells that are flat (is_flat_cell: four surface vertices of one body,
  /// coplanar up to round-off), kept with them: what flat_cell_subs looks at.
  std::set<std::array<int, 4>> flat_surface_cells;
  /// A surface facet of the Delaunay: the global triangle holding it, −2 if it lies in the
  /// surface across coplanar triangles (in_surface), −1 if it is not on the surface; and the
  /// number of surface_cells holding it (1 or 2).
  struct SurfaceFacet {
    int tri = -1;
    int cells = 0;
  };
  /// Surface facet (sorted surface vertex ids) -> its SurfaceFacet.
  TripleMap<SurfaceFacet> facet_tri;
  std::vector<double> covered;     ///< per global triangle: area (m²) of the facets on it
  std::vector<char> changed_mark;  ///< per vertex id: scratch of sync_surface_cells
  /// Per global triangle: a facet on it or one of its sub-triangles changed since the last
  /// missing_triangles (tri_dirty), and the list of those triangles.
  std::vector<char> tri_dirty;
  std::vector<int> dirty_tris;
  std::vector<int> last_missing;  ///< missing_triangles' last answer
  int cleanup_rounds = 0;         ///< sliver / degenerate-cell deletion passes done
  int perturb_rounds = 0;         ///< sliver perturbation passes done
  /// The cells that may be slivers (maybe_flat at 0.5, ids in canonical order, sorted) at the
  /// last cleanup pass, and per vertex id whether its star changed since (filled from the
  /// Delaunay's changes by sync_surface_cells; the list of those ids): a later pass screens
  /// only the cells with every vertex changed (local_recovery).
  std::vector<std::array<int, 4>> sliver_candidates;
  bool candidates_valid = false;
  std::vector<char> changed_since_cleanup;
  std::vector<int> changed_since_cleanup_ids;

  // ---- stage 5: classification ----
  std::vector<char> flat;          ///< per cell: is_flat_surface_cell (belongs to the solid)
  std::vector<int> region;         ///< per cell: flood-fill region
  std::vector<char> region_fluid;  ///< per region: 1 = fluid
  std::vector<int> old_id;         ///< per fluid mesh vertex: its id in pts
  MatX4i ftets;                    ///< fluid cells in fluid mesh vertex ids
  MatX4i fnbrs;                    ///< their neighbours as fluid cell rows (−1: none / solid)

  RemeshReport report;

  // ---- stage 0 (remesh.cpp) ----
  /// Validate sizing, domain and solids (closed, inside the box, no intersections or
  /// nesting). Writes set.
  void check_inputs();

  // ---- stages 1–2 (remesh_lattice.cpp) ----
  /// Refine the surfaces, build the lattice and drop its points near the surfaces; if the
  /// cell estimate exceeds sizing.max_cells, scale all sizes up and start again (up to 6
  /// times). Reads set, sizing; writes size.scale, surf, lat, keep, report.size_scale.
  void place_vertices();
  /// The Delaunay's input: kept lattice points, then every surface point. Reads lat, keep,
  /// surf; writes pts, dt_pts, pt_size, nL, report.lattice_points, report.surface_points.
  void collect_points();
  /// x (m) in the Delaunay's coordinates: lattice units on an isotropic lattice, with
  /// coordinates within 1e-7 of a lattice plane put on it; x itself otherwise. Reads lat.
  Vec3 to_dt(const Vec3& x) const;

  // ---- stage 3 (remesh.cpp) ----
  /// Delaunay of dt_pts with ids = indices: from `state`'s triangulation if it is valid, in
  /// the same frame, sizing.incremental and not in a backoff (Delaunay::update), else built
  /// anew. Writes dt,
  /// report.incremental, vertices_removed, vertices_inserted; invalidates state.
  void build_delaunay(IncrementalState* state);

  // ---- stage 4 (remesh_recovery.cpp) ----
  /// Insert Steiner points on the solid surface until every solid triangle is a union of
  /// Delaunay faces, split flat cells straddling coplanar triangles, then remove slivers
  /// (perturb or delete lattice vertices) and degenerate cells, re-checking conformity.
  /// Reads/writes surf, pts, dt_pts, dt, lattice_removed; writes tri_area, lattice_grid,
  /// near, facet_tri, tets, nbrs and report (recovery_rounds, sliver_points_*, steiner_points,
  /// cells_delaunay).
  /// @throws MeshError if a triangle is not recovered in options.max_recovery_rounds.
  void recover_conformity();
  /// Put the final cells (tets, nbrs) in the order of their vertex ids (canonical_order
  /// within a cell, then rows by their ids): the mesh then depends on the triangulation, not
  /// on the history of insertions and removals that made it.
  void sort_cells();
  /// Set up the recovery: tri_area, lattice_grid, lattice_removed.
  void prepare_recovery();
  /// Bring surface_cells, facet_tri and covered up to date: from every cell at
  /// the first call (`full`), then from the vertices whose stars the Delaunay reports changed
  /// (Delaunay::take_changed): the cells all of whose vertices changed are dropped and the
  /// current cells around the changed surface vertices with every vertex changed added.
  void sync_surface_cells(bool full);
  /// Adds the cells (rows) that `use` accepts and that have three or more surface vertices:
  /// surface_cells, flat_surface_cells, facet_tri (each facet's triangle on its first
  /// cell), covered and the dirty triangles.
  void add_surface_cells(const MatX4i& cells,
                         const std::function<bool(const std::array<int, 4>&)>& use);
  /// Remove cell c's surface facets that no other cell holds (c leaves surface_cells).
  void remove_surface_facets(const std::array<int, 4>& c);
  /// Mark the triangles the surface points of facet (a, b, c) lie on dirty.
  void mark_dirty(int a, int b, int c);
  /// Mark global triangle g dirty (tri_dirty, dirty_tris), once.
  void mark_triangle_dirty(int g);
  /// The flat_surface_cells, in increasing order.
  MatX4i flat_cells() const;
  /// Of the dirty triangles and the last missing ones (every triangle if !local_recovery),
  /// in increasing order, those neither tiled by faces (area covered) nor with every sub-triangle a
  /// face.
  std::vector<int> missing_triangles();
  /// Sub-triangles of the `missing` triangles that are not Delaunay faces (facet_tri).
  std::vector<int> unrecovered_subs(const std::vector<int>& missing) const;
  [[noreturn]] void throw_unrecovered(const std::vector<int>& missing, int round) const;
  /// Refine the listed sub-triangles (edges split at `at`), delete the lattice points inside
  /// the new sub-triangles' diametral spheres and insert the new surface points.
  void insert_steiner_points(const std::vector<int>& split, double at);
  /// One cleanup pass on the conforming triangulation (extracted into tets, nbrs): perturb
  /// slivers away from the solids (kPerturbRounds passes), delete a lattice vertex of each
  /// sliver at them (kSliverRounds) and then of each degenerate cell (kDegenerateRounds).
  /// Returns whether the triangulation changed (conformity must be checked again).
  bool clean_up_slivers();
  /// The cells of the triangulation now that may be slivers (maybe_flat at 0.5): from one
  /// pass over every cell, or (local_recovery, after a first pass) the last candidates whose
  /// vertices did not all change and the cells whose vertices all did. Updates
  /// sliver_candidates and resets the changes.
  MatX4i screen_sliver_candidates();
  /// Lattice vertices to delete, one per sliver (min dihedral < kSliverDeg; only degenerate
  /// cells if `degenerate_only`) that has one: the lattice vertex nearest to the sliver's
  /// surface vertices (or its first), never a box point.
  std::vector<int> sliver_vertices(const MatX4i& T, bool degenerate_only) const;
  /// Perturb the lattice vertices of slivers away from the solids (see remesh_recovery.cpp).
  /// Returns the number moved.
  int perturb_away_slivers(const MatX4i& T);
  /// The vertices of cells of T with no solid vertex and min dihedral < kAwayDeg, not on the
  /// box, sorted, each once. Fills P (#pts × 3) with pts.
  std::vector<int> away_sliver_targets(const MatX4i& T, MatX3& P) const;
  /// The smallest min dihedral angle (degrees) of the cells with no solid vertex around the
  /// vertices `ring`; updates their rows of P.
  double worst_around(const std::vector<int>& ring, MatX3& P) const;
  /// The smallest dihedral angle (degrees) of cell t of `cells` from the positions P, +inf
  /// for a cell with a solid vertex (worst_around and raises_worst_around leave those out).
  double away_min_dihedral(const MatX4i& cells, Index t, const MatX3& P) const;
  /// Whether worst_around(ring, P) > above, v a vertex of the ring: v's cells first, stopping
  /// at the first cell at or below `above` (the same answer; most trial moves fail at v's
  /// own cells). Updates the ring's rows of P.
  bool raises_worst_around(const std::vector<int>& ring, int v, double above, MatX3& P) const;
  /// Try up to 12 moves of lattice vertex v; keep the first that raises worst_around of its
  /// star's vertices. Returns whether it moved.
  bool perturb_vertex(int v, MatX3& P);
  /// Sub-triangles to split under the flat cells among `cells` (see remesh_recovery.cpp).
  std::vector<int> flat_cell_subs(const MatX4i& cells) const;
  /// Side of the solid a flat off-surface cell c lies on: −1 inside, 1 in the fluid.
  int flat_cell_side(const int c[4]) const;

  // ---- cell and face predicates (remesh_recovery.cpp; also used by stages 5–6) ----
  int surface_id(int v) const { return v - nL; }
  /// A global triangle holding the surface vertices a, b, c (ids into pts), or −1.
  int common_triangle(int a, int b, int c) const;
  bool on_box(const Vec3& x) const;
  /// Cheap screen for small dihedral angles of cell t of T (shape measure below `shape`).
  bool maybe_flat(const MatX4i& T, Index t, double shape) const {
    return maybe_flat({T(t, 0), T(t, 1), T(t, 2), T(t, 3)}, shape);
  }
  bool maybe_flat(const std::array<int, 4>& c, double shape) const;
  /// Cell t of T has a signed volume (m³) of at most kFlat × (longest edge)³.
  bool is_degenerate(const MatX4i& T, Index t) const;
  /// A face of surface vertices with no common triangle that lies in the surface.
  bool in_surface(int a, int b, int c) const;
  /// Four surface vertices of one body, coplanar up to round-off.
  bool is_flat_cell(int v0, int v1, int v2, int v3) const;
  /// A flat cell in the plane of a triangle of one of its points.
  bool is_flat_surface_cell(int v0, int v1, int v2, int v3) const;

  // ---- stage 5 (remesh_classify.cpp) ----
  /// Flood fill between solid faces (facet_tri, flat cells), one winding number per region.
  /// Reads tets, nbrs, facet_tri, pts; writes flat, region, region_fluid,
  /// report.flat_cells_removed.
  void classify_cells();
  /// Whether face k of cell t separates fluid from solid (no flood across it).
  bool is_barrier(Index t, int k) const;
  /// Whether the region seeded at cell `seed` is fluid (0 for a flat cell).
  bool region_is_fluid(Index seed);
  /// The fluid cells with their vertices renumbered compactly, and their neighbours. Writes
  /// ftets, fnbrs, old_id, report.cells_removed. @throws MeshError if none is left.
  void collect_fluid_cells();
  /// Safety net: no fluid cell is degenerate and the fluid volume is box − solids.
  /// @throws MeshError otherwise.
  void check_fluid_volume() const;

  // ---- stage 6 (remesh_classify.cpp) ----
  /// The TetMesh of the fluid cells with vertex provenance and face tags. Reads ftets,
  /// old_id, pts, surf, set, domain; writes report.straddling_faces. Moves ftets out.
  TetMesh build_fluid_mesh();
  /// Tag boundary face f (vertices a, b, c as ids into pts) Solid if a triangle holds it.
  bool tag_solid_face(TetMesh& m, Index f, int a, int b, int c) const;
  /// Tag a face straddling coplanar triangles Solid on the triangle holding its centroid.
  bool tag_straddling_face(TetMesh& m, Index f, int a, int b, int c);
  /// Tag a face on the box: the default kind or the last patch holding its centroid.
  void tag_box_face(TetMesh& m, Index f, int a, int b, int c) const;
};

/// The stages of one remesh in order, timed (mesh::remesh, Remesher::remesh). `state` (may be
/// null): the Remesher's, read by build_delaunay and given this remesh's triangulation.
TetMesh run_stages(RemeshContext& ctx, IncrementalState* state);

}  // namespace tetfsi::mesh::detail
