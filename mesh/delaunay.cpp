/// @file delaunay.cpp
/// CGAL Delaunay_triangulation_3 with vertex ids, and the triangle intersection search
/// (box_intersection_d + exact do_intersect). The remesher's only CGAL translation unit.
#include "mesh/delaunay.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <numeric>
#include <unordered_set>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Spatial_lock_grid_3.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <boost/container_hash/hash.hpp>
#include <boost/iterator/function_output_iterator.hpp>
#include <boost/unordered_map.hpp>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/triple_map.hpp"

namespace tetfsi::mesh {
namespace {
/// Tag (in the place of CGAL's lock data structure, unused when sequential) that selects the
/// Triangulation_3 base below: vertex removal that does not depend on memory addresses.
struct AddressFreeRemoval {};

/// Hash of an oriented vertex triple by the vertices' ids (info), the same for its three
/// rotations: Triangulation_3::make_canonical_oriented_triple picks the rotation by address.
/// remove_3D also hashes triples with null handles (of the hole's temporary triangulation's
/// infinite vertex when it is planar): id −2.
struct IdTripleHash {
  template <class Handle>
  static int id(const Handle& v) {
    return v == Handle() ? -2 : v->info();
  }
  template <class Triple>
  std::size_t operator()(const Triple& t) const {
    std::array<int, 3> k = {id(t.first), id(t.second), id(t.third)};
    std::rotate(k.begin(), std::min_element(k.begin(), k.end()), k.end());
    return boost::hash_range(k.begin(), k.end());
  }
};
}  // namespace
}  // namespace tetfsi::mesh

namespace CGAL {
/// Triangulation_3::remove_3D fills the hole of a removed vertex cell by cell, taking the next
/// boundary facet from the front of a hash map keyed by vertex handles, i.e. by addresses:
/// the new cells were created, stored and later iterated in an order that changed from run
/// to run (the same triangulation, numbered differently). Keyed by vertex ids instead, the
/// order depends only on the operations. The rest is CGAL's sequential base. Checked against
/// CGAL 5.5; the test "remesh: the same input gives the same mesh" fails if this stops working.
template <>
class Triangulation_3_base<Sequential_tag, tetfsi::mesh::AddressFreeRemoval>
    : public Triangulation_3_base<Sequential_tag, Default> {
 protected:
  Triangulation_3_base() = default;
  explicit Triangulation_3_base(void*) {}

  template <typename Vertex_triple, typename Facet>
  struct Vertex_triple_Facet_map_generator {
    using type = boost::unordered_map<Vertex_triple, Facet, tetfsi::mesh::IdTripleHash>;
  };
};
}  // namespace CGAL

namespace tetfsi::mesh {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int, K>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int, K>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
// Sequential: CGAL's parallel insertion measured slower on this machine (docs/dev/architecture.md,
// measured facts); it is an option of Delaunay::build (ParallelDT below). Vertex ids must be set
// before a removal: the infinite vertex has id −1.
using DT = CGAL::Delaunay_triangulation_3<K, Tds, CGAL::Default, AddressFreeRemoval>;
using Point = K::Point_3;
/// CGAL's concurrent triangulation (TBB; a lock grid over the points' box): its range
/// insertion inserts the points in parallel. Only for Delaunay::build's option; the result is
/// copied into a DT.
using ParallelTds = CGAL::Triangulation_data_structure_3<Vb, Cb, CGAL::Parallel_tag>;
using ParallelDT =
    CGAL::Delaunay_triangulation_3<K, ParallelTds, CGAL::Default,
                                   CGAL::Spatial_lock_grid_3<CGAL::Tag_priority_blocking>>;
/// The hole's triangulation in remove_clusters: each vertex knows the one it stands for.
using HoleVb = CGAL::Triangulation_vertex_base_with_info_3<DT::Vertex_handle, K>;
using HoleCb = CGAL::Triangulation_cell_base_with_info_3<int, K>;
using HoleDT =
    CGAL::Delaunay_triangulation_3<K, CGAL::Triangulation_data_structure_3<HoleVb, HoleCb>>;

/// The ids (id_of(vertex)) of facet (c, k), oriented as CGAL's make_vertex_triple (seen from
/// c) and rotated to start at the smallest; `flip` reverses the orientation.
template <class Cell, class IdOf>
detail::TripleKey oriented_ids(const Cell& c, int k, bool flip, IdOf id_of) {
  std::array<int, 3> t;
  for (int j = 0; j < 3; ++j) t[j] = id_of(c->vertex(DT::vertex_triple_index(k, j)));
  if (flip) std::swap(t[1], t[2]);
  std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  return {t[0], t[1], t[2]};
}

inline Point to_point(const Vec3& p) {
  return Point(p.x(), p.y(), p.z());
}

/// The points whose `skip` flag is 0 (every point if null), each with its index as id: a range
/// insertion's input.
std::vector<std::pair<Point, int>> with_ids(const std::vector<Vec3>& points,
                                            const std::vector<char>* skip) {
  std::vector<std::pair<Point, int>> in;
  in.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!skip || !(*skip)[i]) in.emplace_back(to_point(points[i]), static_cast<int>(i));
  return in;
}

[[noreturn]] void throw_duplicate(const std::vector<Vec3>& pts) {
  std::vector<int> order(pts.size());
  std::iota(order.begin(), order.end(), 0);
  auto less = [&](int a, int b) {
    return std::lexicographical_compare(pts[a].data(), pts[a].data() + 3, pts[b].data(),
                                        pts[b].data() + 3);
  };
  std::sort(order.begin(), order.end(), less);
  for (std::size_t i = 1; i < order.size(); ++i) {
    if (pts[order[i]] == pts[order[i - 1]]) {
      const Vec3& p = pts[order[i]];
      throw MeshError(fmt::format(
          "delaunay: points {} and {} coincide at ({:.9g}, {:.9g}, {:.9g}); two vertices at one "
          "position (touching or duplicated solid vertices): separate them",
          std::min(order[i], order[i - 1]), std::max(order[i], order[i - 1]), p.x(), p.y(), p.z()));
    }
  }
  throw InternalError("delaunay: fewer vertices than points but no duplicate found");
}

/// Cell c's ids in the canonical order (canonical_order); `perm`, if given, gets the order.
inline std::array<int, 4> canonical_ids(const DT::Cell_handle& c,
                                        std::array<int, 4>* perm = nullptr) {
  const int ids[4] = {c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(),
                      c->vertex(3)->info()};
  const std::array<int, 4> p = canonical_order(ids);
  if (perm) *perm = p;
  return {ids[p[0]], ids[p[1]], ids[p[2]], ids[p[3]]};
}

/// Exact coordinates as a hash key (−0 as +0, so that equal points have equal keys).
struct PointKey {
  double x, y, z;
  explicit PointKey(const Point& p) : x(p.x() + 0.0), y(p.y() + 0.0), z(p.z() + 0.0) {}
  bool operator==(const PointKey&) const = default;
};
struct PointKeyHash {
  std::size_t operator()(const PointKey& k) const {
    std::size_t h = 0;
    boost::hash_combine(h, std::bit_cast<std::uint64_t>(k.x));
    boost::hash_combine(h, std::bit_cast<std::uint64_t>(k.y));
    boost::hash_combine(h, std::bit_cast<std::uint64_t>(k.z));
    return h;
  }
};
}  // namespace

struct Delaunay::Impl {
  DT dt;
  std::vector<DT::Vertex_handle> handles;  ///< by id (null if absent)
  DT::Cell_handle hint;
  bool tracking = false;
  std::vector<int> changed;  ///< track_changes: ids whose star changed
  /// Record v and its finite neighbours.
  void record(DT::Vertex_handle v) {
    changed.push_back(v->info());
    dt.finite_adjacent_vertices(v, boost::iterators::make_function_output_iterator(
                                       [&](DT::Vertex_handle w) { changed.push_back(w->info()); }));
  }
  /// The finite cells incident to the vertices with these ids (absent ids skipped), star
  /// after star: a cell shared by several stars comes once per star.
  std::vector<DT::Cell_handle> stars(const std::vector<int>& ids) const {
    std::vector<DT::Cell_handle> cells;
    for (int id : ids)
      if (const DT::Vertex_handle v = handle(id); v != DT::Vertex_handle())
        dt.finite_incident_cells(v, std::back_inserter(cells));
    return cells;
  }
  /// The vertex with this id, null if absent.
  DT::Vertex_handle handle(int id) const {
    return id >= 0 && static_cast<std::size_t>(id) < handles.size() ? handles[id]
                                                                    : DT::Vertex_handle();
  }
  void remove_clusters(const std::vector<DT::Vertex_handle>& gone, std::size_t id_bound);
  /// One hole of remove_clusters: its cells, the facets around it (the cell outside and its
  /// index there), the vertices removed with it and the other vertices of its cells.
  struct Hole {
    std::vector<DT::Cell_handle> cells;
    std::vector<std::pair<DT::Cell_handle, int>> boundary;
    std::vector<DT::Vertex_handle> cluster, link;
  };
  /// remove_clusters' vertex states, by id + 1 (the infinite vertex has id −1); all kClear
  /// between calls. kLink: a vertex of the current hole's cells that stays.
  enum : std::uint8_t { kClear, kRemove, kDone, kLink };
  std::vector<std::uint8_t> vstate;
  /// The hole around v: every cell with a vertex to remove (st: kRemove, or kDone once
  /// reached), connected through facets (CGAL's _make_big_hole_3D); its cells are marked
  /// processed, its removed vertices kDone, the others kLink. False if it holds an infinite
  /// cell (the whole hole is gathered anyway, so its cluster is deferred as one).
  template <class State>
  bool collect_hole(const DT::Vertex_handle& v, const State& st, Hole& h) {
    bool finite = true;
    v->cell()->tds_data().mark_processed();
    h.cells.push_back(v->cell());
    for (std::size_t i = 0; i < h.cells.size(); ++i) {
      const DT::Cell_handle c = h.cells[i];
      finite &= !dt.is_infinite(c);
      for (int k = 0; k < 4; ++k) {
        const DT::Vertex_handle w = c->vertex(k);
        std::uint8_t& sw = st(w);
        if (sw == kClear) {
          sw = kLink;
          h.link.push_back(w);
        } else if (sw == kRemove) {
          sw = kDone;
          h.cluster.push_back(w);
        }
        const DT::Cell_handle o = c->neighbor(k);
        bool inside = false;
        for (int j = 0; j < 4 && !inside; ++j) {
          const std::uint8_t so = st(o->vertex(j));
          inside = so == kRemove || so == kDone;
        }
        if (!inside) {
          h.boundary.emplace_back(o, dt.mirror_index(c, k));
        } else if (o->tds_data().is_clear()) {
          o->tds_data().mark_processed();
          h.cells.push_back(o);
        }
      }
    }
    return finite;
  }
  bool refill_hole(const Hole& h);
  /// handles[id] = the vertex with that id, for ids 0..n−1; no hint.
  void index_handles(std::size_t n) {
    handles.assign(n, DT::Vertex_handle());
    for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
      handles[v->info()] = v;
    hint = DT::Cell_handle();
  }
  /// Into an empty dt: the points (ids = indices) inserted by CGAL's parallel range insertion
  /// into a ParallelDT, whose vertices and cells are then copied into dt (copy_tds). The same
  /// triangulation as insert_points (the Delaunay of the points is unique under CGAL's
  /// symbolic perturbation), its cells and vertices in another order in the containers.
  void insert_points_in_parallel(const std::vector<Vec3>& points) {
    const std::vector<std::pair<Point, int>> in = with_ids(points, nullptr);
    CGAL::Bbox_3 box;
    for (const auto& [p, id] : in) box += p.bbox();
    CGAL::Spatial_lock_grid_3<CGAL::Tag_priority_blocking> locks(box, 50);
    ParallelDT pdt(K(), &locks);
    pdt.insert(in.begin(), in.end());
    if (pdt.number_of_vertices() != points.size()) throw_duplicate(points);
    pdt.infinite_vertex()->info() = -1;
    struct CopyVertex {
      DT::Vertex operator()(const ParallelDT::Vertex& v) const { return DT::Vertex(v.point()); }
      void operator()(const ParallelDT::Vertex& from, DT::Vertex& to) const {
        to.info() = from.info();
      }
    };
    struct CopyCell {
      DT::Cell operator()(const ParallelDT::Cell&) const { return DT::Cell(); }
      void operator()(const ParallelDT::Cell&, DT::Cell&) const {}
    };
    dt.set_infinite_vertex(
        dt.tds().copy_tds(pdt.tds(), pdt.infinite_vertex(), CopyVertex(), CopyCell()));
    index_handles(points.size());
  }
  /// Insert the points whose `skip` flag is 0 (every point if null), ids = indices, by range
  /// insertion (spatial sort + hinted insertion); the triangulation must then hold exactly
  /// `points`. Re-indexes the handles.
  /// @throws MeshError naming both ids if two points coincide.
  void insert_points(const std::vector<Vec3>& points, const std::vector<char>* skip) {
    const std::vector<std::pair<Point, int>> in = with_ids(points, skip);
    dt.insert(in.begin(), in.end());
    if (dt.number_of_vertices() != points.size()) throw_duplicate(points);
    index_handles(points.size());
  }
};

/// Removes the vertices `gone` (finite, distinct, ids in [0, id_bound)) as CGAL's
/// remove_cluster does [DevillersTeillaud03]: the cells with a removed vertex,
/// connected through their facets, make a hole, and the Delaunay of the hole's other
/// vertices, where it lies within the hole's boundary, refills it. CGAL's version keeps its
/// vertex states and facet maps in ordered trees keyed by addresses (most of its time); this
/// one indexes states by id and hashes facets by ids. The cells are the same: the Delaunay of
/// a point set is unique under CGAL's symbolic perturbation. A hole that reaches the infinite
/// vertex, or whose refill does not match its boundary, goes to CGAL's version.
void Delaunay::Impl::remove_clusters(const std::vector<DT::Vertex_handle>& gone,
                                     std::size_t id_bound) {
  if (gone.empty()) return;
  if (dt.dimension() < 3 || dt.number_of_vertices() < gone.size() + 16) {
    dt.remove_cluster(gone.begin(), gone.end());
    return;
  }
  if (vstate.size() < id_bound + 1) vstate.resize(id_bound + 1, kClear);
  const auto st = [&](const DT::Vertex_handle& v) -> std::uint8_t& {
    return vstate[static_cast<std::size_t>(v->info() + 1)];
  };
  for (const DT::Vertex_handle& v : gone) st(v) = kRemove;
  std::vector<DT::Vertex_handle> deferred, done;
  for (const DT::Vertex_handle& v : gone) {
    if (st(v) != kRemove) continue;  // in a hole already
    Hole h;
    const bool ok = collect_hole(v, st, h) && refill_hole(h);
    for (const DT::Vertex_handle& w : h.link) st(w) = kClear;
    std::vector<DT::Vertex_handle>& into = ok ? done : deferred;
    into.insert(into.end(), h.cluster.begin(), h.cluster.end());
    if (!ok)
      for (const DT::Cell_handle& c : h.cells) c->tds_data().clear();
  }
  for (const DT::Vertex_handle& v : gone) st(v) = kClear;  // vstate is all clear between calls
  for (const DT::Vertex_handle& v : done) dt.tds().delete_vertex(v);
  if (!deferred.empty()) dt.remove_cluster(deferred.begin(), deferred.end());
}

/// Refills hole h (remove_clusters) with the Delaunay of its link's vertices where it lies
/// inside the hole's boundary; false, changing nothing, if that does not match the boundary.
bool Delaunay::Impl::refill_hole(const Hole& h) {
  HoleDT tmp;
  std::vector<std::pair<Point, DT::Vertex_handle>> in;
  in.reserve(h.link.size());
  for (const DT::Vertex_handle& w : h.link) in.emplace_back(w->point(), w);
  tmp.insert(in.begin(), in.end());
  if (tmp.dimension() < 3) return false;
  const auto id = [](const DT::Vertex_handle& w) { return w->info(); };
  const auto hole_id = [](const HoleDT::Vertex_handle& w) { return w->info()->info(); };
  detail::TripleMap<int> outer;  // boundary facet (seen from outside) -> its index
  for (std::size_t b = 0; b < h.boundary.size(); ++b) {
    const detail::TripleKey k = oriented_ids(h.boundary[b].first, h.boundary[b].second, false, id);
    if (outer.contains(k)) return false;
    outer[k] = static_cast<int>(b);
  }
  // Number the finite cells; a facet seen from inside the hole names its boundary facet.
  std::vector<HoleDT::Cell_handle> cells;
  std::vector<std::array<int, 4>> bnd;  // per cell and facet: the boundary facet, or −1
  std::vector<int> region_of, region;   // cell -> its place in region (−1: outside)
  std::size_t matched = 0;
  for (auto c = tmp.finite_cells_begin(); c != tmp.finite_cells_end(); ++c) {
    std::array<int, 4> f;
    for (int j = 0; j < 4; ++j) {
      const int* b = outer.find(oriented_ids(c, j, true, hole_id));
      f[j] = b ? *b : -1;
    }
    const bool seed = f[0] >= 0 || f[1] >= 0 || f[2] >= 0 || f[3] >= 0;
    matched += (f[0] >= 0) + (f[1] >= 0) + (f[2] >= 0) + (f[3] >= 0);
    c->info() = static_cast<int>(cells.size());
    region_of.push_back(seed ? static_cast<int>(region.size()) : -1);
    if (seed) region.push_back(c->info());
    cells.push_back(c);
    bnd.push_back(f);
  }
  if (matched != h.boundary.size()) return false;
  // The cells inside: reached from the boundary without crossing it.
  for (std::size_t r = 0; r < region.size(); ++r)
    for (int j = 0; j < 4; ++j) {
      if (bnd[region[r]][j] >= 0) continue;
      const HoleDT::Cell_handle n = cells[region[r]]->neighbor(j);
      if (tmp.is_infinite(n)) return false;
      if (region_of[n->info()] < 0) {
        region_of[n->info()] = static_cast<int>(region.size());
        region.push_back(n->info());
      }
    }
  // Commit: the boundary's vertices point outside, the new cells are glued to each other and
  // to the cells around the hole, and the hole's cells go.
  for (const auto& [o, oi] : h.boundary)
    for (int j = 0; j < 4; ++j) o->vertex(j)->set_cell(o);
  std::vector<DT::Cell_handle> made(region.size());
  for (std::size_t r = 0; r < region.size(); ++r) {
    const HoleDT::Cell_handle& t = cells[region[r]];
    made[r] = dt.tds().create_cell(t->vertex(0)->info(), t->vertex(1)->info(), t->vertex(2)->info(),
                                   t->vertex(3)->info());
    for (int j = 0; j < 4; ++j) made[r]->vertex(j)->set_cell(made[r]);
  }
  for (std::size_t r = 0; r < region.size(); ++r)
    for (int j = 0; j < 4; ++j) {
      const int b = bnd[region[r]][j];
      if (b >= 0) {
        const auto& [o, oi] = h.boundary[static_cast<std::size_t>(b)];
        made[r]->set_neighbor(j, o);
        o->set_neighbor(oi, made[r]);
      } else {
        made[r]->set_neighbor(j, made[region_of[cells[region[r]]->neighbor(j)->info()]]);
      }
    }
  dt.tds().delete_cells(h.cells.begin(), h.cells.end());
  return true;
}

Delaunay::Delaunay() : m_impl(std::make_unique<Impl>()) {
  m_impl->dt.infinite_vertex()->info() = -1;
}
Delaunay::~Delaunay() = default;
Delaunay::Delaunay(Delaunay&&) noexcept = default;
Delaunay& Delaunay::operator=(Delaunay&&) noexcept = default;

void Delaunay::build(const std::vector<Vec3>& points, bool parallel) {
  Impl& d = *m_impl;
  d.dt.clear();
  d.tracking = false;
  d.changed.clear();
  d.dt.infinite_vertex()->info() = -1;  // clear() made a new one
  if (parallel && thread_count() > 1 && points.size() >= 1000)
    d.insert_points_in_parallel(points);
  else
    d.insert_points(points, nullptr);
}

bool Delaunay::update(const std::vector<Vec3>& points, double max_cost, Index& removed,
                      Index& inserted) {
  Impl& d = *m_impl;
  d.tracking = false;
  d.changed.clear();
  std::unordered_map<PointKey, int, PointKeyHash> index;
  index.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!index.emplace(PointKey(to_point(points[i])), static_cast<int>(i)).second)
      throw_duplicate(points);
  std::vector<char> present(points.size(), 0);
  std::vector<std::pair<DT::Vertex_handle, int>> kept;
  std::vector<DT::Vertex_handle> gone;
  kept.reserve(points.size());
  for (auto v = d.dt.finite_vertices_begin(); v != d.dt.finite_vertices_end(); ++v) {
    auto it = index.find(PointKey(v->point()));
    if (it == index.end()) {
      gone.push_back(v);
    } else {
      kept.emplace_back(v, it->second);
      present[it->second] = 1;
    }
  }
  removed = static_cast<Index>(gone.size());
  inserted = static_cast<Index>(points.size() - kept.size());
  if (kept.empty() || static_cast<double>(kRemovalCost * removed + inserted) >
                          max_cost * static_cast<double>(points.size())) {
    build(points);
    return false;
  }
  // Ids first (removal hashes the link's triples by ids): kept vertices take their point's
  // index, the ones to remove distinct ids past the end.
  for (const auto& [v, i] : kept) v->info() = i;
  int extra = static_cast<int>(points.size());
  for (const DT::Vertex_handle& v : gone) v->info() = extra++;
  // All at once: one hole per connected cluster of removed vertices, refilled once (CGAL's
  // remove_cluster measured 25 % faster than one by one on smoke_sheets; remove_clusters
  // about twice as fast again). The remesher depends only on the triangulation, not on the
  // cells' order in the container (canonical orders everywhere).
  d.remove_clusters(gone, static_cast<std::size_t>(extra));
  d.insert_points(points, &present);
  return true;
}

void Delaunay::insert(const Vec3& p, int id) {
  Impl& d = *m_impl;
  const std::size_t before = d.dt.number_of_vertices();
  DT::Vertex_handle v = d.dt.insert(to_point(p), d.hint);
  if (d.dt.number_of_vertices() == before) {
    throw MeshError(fmt::format(
        "delaunay: point {} at ({:.9g}, {:.9g}, {:.9g}) coincides with vertex {}; separate them",
        id, p.x(), p.y(), p.z(), v->info()));
  }
  v->info() = id;
  if (static_cast<std::size_t>(id) >= d.handles.size()) d.handles.resize(id + 1);
  d.handles[id] = v;
  d.hint = v->cell();
  if (d.tracking) d.record(v);
}

void Delaunay::remove(int id) {
  Impl& d = *m_impl;
  const DT::Vertex_handle v = d.handle(id);
  if (v == DT::Vertex_handle()) return;
  if (d.tracking) d.record(v);
  d.remove_clusters({v}, d.handles.size());
  d.handles[id] = DT::Vertex_handle();
  d.hint = DT::Cell_handle();
}

void Delaunay::remove_many(const std::vector<int>& ids) {
  Impl& d = *m_impl;
  std::vector<DT::Vertex_handle> gone;
  for (int id : ids) {
    if (d.handle(id) == DT::Vertex_handle()) continue;
    gone.push_back(d.handles[id]);
    d.handles[id] = DT::Vertex_handle();
  }
  if (gone.empty()) return;
  // Every new cell's vertices lie in the link of the cluster: neighbours of removed vertices.
  if (d.tracking)
    for (const DT::Vertex_handle& v : gone) d.record(v);
  d.remove_clusters(gone, d.handles.size());
  d.hint = DT::Cell_handle();
}

void Delaunay::track_changes(bool on) {
  m_impl->tracking = on;
  m_impl->changed.clear();
}

std::vector<int> Delaunay::take_changed() {
  std::vector<int> out;
  out.swap(m_impl->changed);
  return out;
}

Index Delaunay::num_vertices() const {
  return static_cast<Index>(m_impl->dt.number_of_vertices());
}
Index Delaunay::num_finite_cells() const {
  return static_cast<Index>(m_impl->dt.number_of_finite_cells());
}

void Delaunay::extract(MatX4i& tets, MatX4i& neighbours) const {
  DT& dt = m_impl->dt;
  // One serial pass numbers the finite cells (the container's order; infinite ones −1) and
  // keeps their handles, then the rows are filled in parallel (each writes its own row).
  std::vector<DT::Cell_handle> cells;
  cells.reserve(dt.number_of_finite_cells());
  const DT::Vertex_handle inf = dt.infinite_vertex();
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
    if (c->has_vertex(inf)) {
      c->info() = -1;
    } else {
      c->info() = static_cast<int>(cells.size());
      cells.push_back(c);
    }
  }
  const Index n = static_cast<Index>(cells.size());
  tets.resize(n, 4);
  neighbours.resize(n, 4);
  // Cells of Triangulation_3 are positively oriented; neighbor(k) is opposite vertex(k).
  parallel_for_each(n, 16384, [&](Index t) {
    std::array<int, 4> p;
    const std::array<int, 4> ids = canonical_ids(cells[t], &p);
    for (int k = 0; k < 4; ++k) {
      tets(t, k) = ids[k];
      neighbours(t, k) = cells[t]->neighbor(p[k])->info();
    }
  });
}

void Delaunay::cells_around(const std::vector<int>& ids, MatX4i& tets) const {
  std::vector<DT::Cell_handle> cells = m_impl->stars(ids);
  // Order by the cells' sorted vertex ids, not by handle (an address): the remesher acts on
  // these cells in this order, and the same input must give the same mesh in every run.
  std::vector<std::pair<std::array<int, 4>, std::array<int, 4>>> keyed;  // sorted, canonical
  keyed.reserve(cells.size());
  for (const DT::Cell_handle& c : cells) {
    const std::array<int, 4> ids = canonical_ids(c);
    std::array<int, 4> k = ids;
    std::sort(k.begin(), k.end());
    keyed.emplace_back(k, ids);
  }
  std::sort(keyed.begin(), keyed.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  keyed.erase(std::unique(keyed.begin(), keyed.end(),
                          [](const auto& a, const auto& b) { return a.first == b.first; }),
              keyed.end());
  tets.resize(static_cast<Index>(keyed.size()), 4);
  for (std::size_t t = 0; t < keyed.size(); ++t)
    for (int k = 0; k < 4; ++k) tets(static_cast<Index>(t), k) = keyed[t].second[k];
}

void Delaunay::cells_around_unsorted(const std::vector<int>& ids, MatX4i& tets) const {
  const Impl& d = *m_impl;
  std::vector<DT::Cell_handle> star;
  std::unordered_set<const void*> seen;  // membership only: the output is in walk order
  std::vector<int> out;
  for (int id : ids) {
    const DT::Vertex_handle v = d.handle(id);
    if (v == DT::Vertex_handle()) continue;
    star.clear();
    d.dt.finite_incident_cells(v, std::back_inserter(star));
    for (const DT::Cell_handle& c : star) {
      if (!seen.insert(&*c).second) continue;
      const std::array<int, 4> ids = canonical_ids(c);
      out.insert(out.end(), ids.begin(), ids.end());
    }
  }
  tets = Eigen::Map<MatX4i>(out.data(), static_cast<Index>(out.size() / 4), 4);
}

void Delaunay::cells_around_any_order(const std::vector<int>& ids, MatX4i& tets) const {
  std::vector<DT::Cell_handle> cells = m_impl->stars(ids);
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  tets.resize(static_cast<Index>(cells.size()), 4);
  for (std::size_t t = 0; t < cells.size(); ++t) {
    const std::array<int, 4> k = canonical_ids(cells[t]);
    for (int j = 0; j < 4; ++j) tets(static_cast<Index>(t), j) = k[j];
  }
}

void Delaunay::cells_touching(int min_id, MatX4i& tets, int min_count,
                              const std::vector<char>* marked,
                              const std::function<bool(const std::array<int, 4>&)>* keep) const {
  // One pass over the cells (walking the incident cells of each surface vertex and sorting
  // the handles measured slower): a serial one gathers the handles (the container allows
  // nothing else), then the cells' vertices are read and tested in parallel chunks, joined
  // in chunk order. In the container's order, which depends on the history of insertions
  // and removals: the caller's sums of facet areas may differ in the last bit, far below its
  // 1e-9 tolerance (sorting cost 3 % of a remesh).
  const DT& dt = m_impl->dt;
  std::vector<DT::Cell_handle> all;
  all.reserve(dt.tds().number_of_cells());
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) all.push_back(c);
  constexpr Index kGrain = 16384;
  const Index n = static_cast<Index>(all.size());
  std::vector<std::vector<int>> parts(static_cast<std::size_t>(num_chunks(n, kGrain)));
  parallel_for_chunks(n, kGrain, [&](Index begin, Index end) {
    std::vector<int>& ids = parts[static_cast<std::size_t>(begin / kGrain)];
    for (Index t = begin; t < end; ++t) {
      const DT::Cell_handle& c = all[t];
      const int v[4] = {c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(),
                        c->vertex(3)->info()};
      const int count = (v[0] >= min_id) + (v[1] >= min_id) + (v[2] >= min_id) + (v[3] >= min_id);
      if (count < min_count) continue;
      if (marked && !((*marked)[v[0]] && (*marked)[v[1]] && (*marked)[v[2]] && (*marked)[v[3]]))
        continue;
      const std::array<int, 4> k = canonical_ids(c);
      if (keep && !(*keep)(k)) continue;
      ids.insert(ids.end(), k.begin(), k.end());
    }
  });
  std::size_t total = 0;
  for (const auto& part : parts) total += part.size();
  tets.resize(static_cast<Index>(total / 4), 4);
  int* out = tets.data();  // row-major: the parts' quadruples back to back
  for (const auto& part : parts) out = std::copy(part.begin(), part.end(), out);
}

MatX4i delaunay_of(const std::vector<Vec3>& points) {
  Delaunay d;
  d.build(points);
  MatX4i tets, nb;
  d.extract(tets, nb);
  return tets;
}

std::optional<std::pair<int, int>> find_intersecting_triangles(
    const std::vector<TriangleRef>& triangles) {
  using Box = CGAL::Box_intersection_d::Box_with_handle_d<double, 3, const TriangleRef*>;
  std::vector<Box> boxes;
  boxes.reserve(triangles.size());
  for (const TriangleRef& t : triangles) {
    CGAL::Bbox_3 b = to_point(t.p[0]).bbox() + to_point(t.p[1]).bbox() + to_point(t.p[2]).bbox();
    boxes.emplace_back(b, &t);
  }
  std::optional<std::pair<int, int>> found;
  const TriangleRef* base = triangles.data();
  auto callback = [&](const Box& a, const Box& b) {
    const TriangleRef& s = *a.handle();
    const TriangleRef& t = *b.handle();
    if (s.group == t.group) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (s.v[i] == t.v[j]) return;  // neighbours on one surface
    }
    const K::Triangle_3 ts(to_point(s.p[0]), to_point(s.p[1]), to_point(s.p[2]));
    const K::Triangle_3 tt(to_point(t.p[0]), to_point(t.p[1]), to_point(t.p[2]));
    if (!CGAL::do_intersect(ts, tt)) return;
    int i = static_cast<int>(&s - base), j = static_cast<int>(&t - base);
    if (i > j) std::swap(i, j);
    if (!found || std::make_pair(i, j) < *found) found = std::make_pair(i, j);
  };
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), callback);
  return found;
}

}  // namespace tetfsi::mesh
