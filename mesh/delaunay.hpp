#pragma once
/// @file delaunay.hpp
/// The CGAL pieces of the remesher behind plain types (CGAL stays in delaunay.cpp): an
/// incremental 3D Delaunay tetrahedralisation whose vertices carry caller ids, and the
/// triangle–triangle intersection search used to reject bad solid geometry. Internal to
/// tetfsi::mesh (remesh.cpp, the benchmark); the public entry point is remesh.hpp.
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "core/types.hpp"

namespace tetfsi::mesh {

/// Delaunay_triangulation_3 (Epick: exact predicates, so the combinatorics are exactly
/// Delaunay) with an integer id per vertex. Deterministic: the cells and their order in
/// `extract` depend only on the points, ids and sequence of calls, never on memory addresses
/// (vertex removal is keyed by ids, delaunay.cpp). Every cell handed out lists its vertices in
/// the canonical order (canonical_order): the same whatever the history that made the cell.
class Delaunay {
 public:
  Delaunay();
  ~Delaunay();
  Delaunay(const Delaunay&) = delete;
  Delaunay& operator=(const Delaunay&) = delete;
  Delaunay(Delaunay&&) noexcept;
  Delaunay& operator=(Delaunay&&) noexcept;

  /// Insert points with ids 0..n−1 by range insertion (spatially sorted). Replaces any
  /// previous content. `parallel`: with more than one thread (and 1000 points), by CGAL's
  /// parallel range insertion (Parallel_tag, a lock grid over the points' box), copied into the
  /// sequential triangulation: the same triangulation, its cells and vertices in another
  /// order in memory (which nothing handed out depends on).
  /// @throws MeshError naming both ids if two points coincide.
  void build(const std::vector<Vec3>& points, bool parallel = false);
  /// Make this the triangulation of `points` with ids 0..n−1 from the current one: a vertex at
  /// one of the points (exactly) takes its index as id, the other vertices are removed and the
  /// points not present inserted (spatially sorted). The result is the triangulation `build`
  /// gives: CGAL's Delaunay is unique under its symbolic perturbation [DevillersTeillaud03],
  /// whatever the order of insertions and removals. If the update's estimated cost, kRemovalCost ×
  /// removed + inserted, passes `max_cost` × n (a rebuild inserts n), it rebuilds instead. Returns
  /// true if it updated, false if it rebuilt; `removed` and `inserted` count the vertices the
  /// update removes and inserts (also when it rebuilt).
  /// @throws MeshError naming both ids if two points coincide.
  bool update(const std::vector<Vec3>& points, double max_cost, Index& removed, Index& inserted);
  /// A vertex removal costs about this many insertions (remove_many against the range
  /// insertion of `build`, measured on remesh_sheet's moving sheet; 4 with CGAL's
  /// remove_cluster).
  static constexpr Index kRemovalCost = 2;
  /// Insert one point with the given id (incremental, hinted by the last insertion).
  /// @throws MeshError if it coincides with an existing vertex.
  void insert(const Vec3& p, int id);
  /// Remove the vertex with this id (no-op if absent).
  void remove(int id);
  /// Remove the vertices with these ids (absent ones skipped), all at once: each connected
  /// cluster's hole is refilled once (as CGAL's remove_cluster, with hashed ids for its
  /// ordered maps of addresses), cheaper than one by one. The same triangulation as removing
  /// them one by one.
  void remove_many(const std::vector<int>& ids);
  /// From now on (or no longer), record the ids of the vertices whose star an insert or a
  /// remove changes: the vertex inserted or removed and its neighbours. Every cell created or
  /// destroyed has all four vertices among them (an insertion's conflict region has no vertex
  /// inside it [Bowyer–Watson]; a removal refills the removed vertex's star from its link).
  void track_changes(bool on);
  /// The ids recorded since the last call (unsorted, may repeat); clears the record.
  std::vector<int> take_changed();
  Index num_vertices() const;
  Index num_finite_cells() const;

  /// Finite cells as ids (#T × 4, positively oriented) and, for local vertex k, the cell
  /// index across the opposite face (−1 for the convex hull).
  void extract(MatX4i& tets, MatX4i& neighbours) const;

  /// The finite cells (as ids) incident to any of the given vertex ids, each once (absent
  /// ids are skipped).
  void cells_around(const std::vector<int>& ids, MatX4i& tets) const;

  /// As cells_around, in the order the stars are walked (deterministic, without the sort by
  /// vertex ids): cheaper when the caller does not depend on the order.
  void cells_around_unsorted(const std::vector<int>& ids, MatX4i& tets) const;

  /// As cells_around, in an order that varies from run to run (the cells' addresses): only
  /// for what does not depend on the order at all, such as a minimum over the cells. The
  /// cheapest of the three.
  void cells_around_any_order(const std::vector<int>& ids, MatX4i& tets) const;

  /// The finite cells (as ids, positively oriented, canonical order) with at least
  /// `min_count` vertices of id ≥ min_id and, if `marked` is given, every vertex v marked
  /// ((*marked)[v] != 0), each once, in the container's order: with min_count 3, every face
  /// whose three vertices have such ids is a face of one of them. One pass, no neighbours:
  /// cheaper than `extract`. `keep`, if given, must accept a cell too (called in parallel).
  void cells_touching(int min_id, MatX4i& tets, int min_count = 1,
                      const std::vector<char>* marked = nullptr,
                      const std::function<bool(const std::array<int, 4>&)>* keep = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// The vertex order of a positively oriented cell that depends on its ids only: the smallest
/// id first, then the next smallest, and the last two in the order that keeps the orientation
/// (an even permutation of the cell's). Returns the permutation p (new k = old p[k]).
inline std::array<int, 4> canonical_order(const int ids[4]) {
  // A sorting network of five compare-exchanges, without branches (the ids' order is random:
  // an insertion sort's branches cost a remesh 1 %); each exchange is a transposition, so
  // their parity is the permutation's.
  int k[4] = {ids[0], ids[1], ids[2], ids[3]}, p[4] = {0, 1, 2, 3};
  int parity = 0;
  const auto cx = [&](int i, int j) {
    const bool s = k[j] < k[i];
    const int ki = s ? k[j] : k[i], kj = s ? k[i] : k[j];
    const int pi = s ? p[j] : p[i], pj = s ? p[i] : p[j];
    k[i] = ki, k[j] = kj, p[i] = pi, p[j] = pj;
    parity ^= static_cast<int>(s);
  };
  cx(0, 1), cx(2, 3), cx(0, 2), cx(1, 3), cx(1, 2);
  return {p[0], p[1], parity ? p[3] : p[2], parity ? p[2] : p[3]};
}

/// Plain Delaunay tets of a point set with ids = row indices (the benchmark floor).
MatX4i delaunay_of(const std::vector<Vec3>& points);

/// A triangle for the intersection search: corner positions, the group it belongs to
/// (body) and the corner vertex ids within the group.
struct TriangleRef {
  Vec3 p[3];
  int group = 0;
  int v[3] = {0, 0, 0};
};

/// The first pair (i, j), i < j, of triangles that intersect, skipping pairs of the same
/// group that share a vertex id (neighbours on one surface). Exact predicates. Boxes of the
/// triangles are intersected first (CGAL box_intersection_d).
std::optional<std::pair<int, int>> find_intersecting_triangles(
    const std::vector<TriangleRef>& triangles);

}  // namespace tetfsi::mesh
