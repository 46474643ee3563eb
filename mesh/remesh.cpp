/// @file remesh.cpp
/// The fluid remesher (remesh.hpp): graded BCC vertex placement on a balanced octree, solid
/// surface vertices refined until their triangles are Gabriel (empty diametral spheres),
/// Delaunay with CGAL (delaunay.cpp), conformity recovery by Steiner points on the solid
/// surface, removal of the cells inside solids by flood fill + winding number, face tagging.
/// No CGAL here: this file compiles in seconds.
#include "mesh/remesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "mesh/delaunay.hpp"
#include "mesh/geometry.hpp"
#include "mesh/quality.hpp"
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Lattice points closer to a solid than this fraction of their local spacing are dropped:
/// the surface vertices take their place (fewer short edges and slivers at the surface).
constexpr double kProtection = 0.5;
/// A solid sub-triangle whose longest edge exceeds this multiple of the surface size is split.
constexpr double kSurfaceEdgeFactor = 1.5;
/// Smallest circumradius, as a fraction of the surface size, that Gabriel refinement splits.
constexpr double kGabrielFloor = 0.1;
/// Points on the box faces are moved within the face by up to this fraction of their
/// spacing (deterministic). A square grid of wall points under the BCC centres makes
/// co-spherical pyramids, each with an interior face of d_f = 0 (458 in a 10³ box); the
/// jitter removes them (0) and keeps the minimum dihedral at 40° (45° without). The same
/// jitter on the faces between octree levels removed most d_f = 0 faces there too but made
/// slivers (min dihedral 0.4°), so those stay exact: the octree transitions keep ~15% of
/// their faces co-spherical (d_f = 0 up to round-off) and no sliver.
constexpr double kWallJitter = 0.1;
/// Cells with a smaller minimum dihedral angle (degrees) lose a lattice vertex, in up to
/// kSliverRounds rounds.
constexpr double kSliverDeg = 5.0;
/// Cells with no solid vertex and a smaller minimum dihedral angle (degrees) get a lattice
/// vertex perturbed.
constexpr double kAwayDeg = 10.0;
constexpr int kPerturbRounds = 4;
constexpr int kSliverRounds = 2;
/// Further rounds, after the kSliverRounds, that delete a lattice vertex of each degenerate
/// cell only (is_degenerate below): a cell made by a later perturbation or deletion.
constexpr int kDegenerateRounds = 6;
/// A cell of four surface vertices of one body with |6V| below this times (longest edge)³ is
/// flat (coplanar up to round-off).
constexpr double kFlat = 1e-9;
/// Where the shared edge under a flat cell straddling two triangles is split.
constexpr double kStraddleSplitAt = 0.45;

// ---------------------------------------------------------------------------------------
// Geometry helpers
// ---------------------------------------------------------------------------------------

/// Circumcentre of triangle abc in its plane (the centre of its diametral sphere).
Vec3 triangle_circumcentre(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, n = ab.cross(ac);
  return a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) /
                 (2.0 * n.squaredNorm());
}

/// Generalised winding number of a closed, outward-oriented triangle surface at p: 1 inside,
/// 0 outside [van Oosterom & Strackee 1983 solid angle].
double winding_number(const Vec3& p, const MatX3& V, const MatX3i& T) {
  double sum = 0.0;
  for (Index t = 0; t < T.rows(); ++t) {
    const Vec3 a = V.row(T(t, 0)).transpose() - p, b = V.row(T(t, 1)).transpose() - p,
               c = V.row(T(t, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    sum += 2.0 * std::atan2(num, den);
  }
  return sum / (4.0 * M_PI);
}

inline std::uint64_t pack3(std::uint64_t i, std::uint64_t j, std::uint64_t k) {
  return i | (j << 21) | (k << 42);
}
inline std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}
struct TripleKey {
  int a, b, c;
  bool operator==(const TripleKey&) const = default;
};
inline TripleKey sorted_key(int a, int b, int c) {
  sort3(a, b, c);
  return {a, b, c};
}
struct TripleHash {
  std::size_t operator()(const TripleKey& k) const { return hash_triple(k.a, k.b, k.c); }
};

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

void check_sizing(const Sizing& s) {
  TETFSI_REQUIRE(InputError, std::isfinite(s.surface_size) && s.surface_size > 0,
                 "remesh: sizing.surface_size must be a positive number of metres, got {}",
                 s.surface_size);
  TETFSI_REQUIRE(InputError, std::isfinite(s.far_size) && s.far_size >= s.surface_size,
                 "remesh: sizing.far_size must be finite and at least surface_size ({}), got {}",
                 s.surface_size, s.far_size);
  TETFSI_REQUIRE(InputError, std::isfinite(s.grading) && s.grading > 0,
                 "remesh: sizing.grading must be a positive number, got {}", s.grading);
  TETFSI_REQUIRE(InputError, s.max_cells >= 0, "remesh: sizing.max_cells must be >= 0, got {}",
                 s.max_cells);
}

void check_domain(const FluidDomain& d) {
  TETFSI_REQUIRE(InputError,
                 d.lo.allFinite() && d.hi.allFinite() && (d.lo.array() < d.hi.array()).all(),
                 "remesh: fluid domain needs finite lo < hi in every axis, got [{} {} {}]..[{} {} "
                 "{}]",
                 d.lo.x(), d.lo.y(), d.lo.z(), d.hi.x(), d.hi.y(), d.hi.z());
  TETFSI_REQUIRE(InputError,
                 d.default_kind != FaceKind::Interior && d.default_kind != FaceKind::Solid,
                 "remesh: the domain's default kind must be wall, inflow or open");
  for (std::size_t i = 0; i < d.patches.size(); ++i) {
    const DomainPatch& p = d.patches[i];
    TETFSI_REQUIRE(InputError, p.side >= 0 && p.side < 6,
                   "remesh: patch {} '{}': side must be 0..5 (-x +x -y +y -z +z), got {}", i,
                   p.name, p.side);
    TETFSI_REQUIRE(InputError, p.kind != FaceKind::Interior && p.kind != FaceKind::Solid,
                   "remesh: patch {} '{}': kind must be wall, inflow or open", i, p.name);
    TETFSI_REQUIRE(InputError,
                   p.lo.allFinite() && p.hi.allFinite() && (p.lo.array() < p.hi.array()).all(),
                   "remesh: patch {} '{}': rectangle needs lo < hi, got [{} {}]..[{} {}]", i,
                   p.name, p.lo.x(), p.lo.y(), p.hi.x(), p.hi.y());
  }
}

/// Validate the solids (closed, inside the box, no intersections, no nesting) and gather
/// their triangles.
SolidSet gather_solids(const FluidDomain& domain, const std::vector<SolidSurface>& solids) {
  SolidSet set;
  set.solids = &solids;
  set.tri_offset.push_back(0);
  for (std::size_t b = 0; b < solids.size(); ++b) {
    const SolidSurface& s = solids[b];
    const std::string who = fmt::format("remesh: body {}", s.body);
    validate_closed_surface(SurfaceMesh{s.vertices, s.triangles}, who);
    Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
    for (Index t = 0; t < s.triangles.rows(); ++t) {
      std::array<Vec3, 3> c;
      for (int k = 0; k < 3; ++k) {
        const int v = s.triangles(t, k);
        c[k] = s.vertices.row(v).transpose();
        if (!((c[k].array() > domain.lo.array()).all() &&
              (c[k].array() < domain.hi.array()).all())) {
          throw MeshError(fmt::format(
              "{}: vertex {} of triangle {} at ({:.6g}, {:.6g}, {:.6g}) is not inside the fluid "
              "domain [{:.6g} {:.6g} {:.6g}]..[{:.6g} {:.6g} {:.6g}]: move the body inside or "
              "enlarge the domain",
              who, v, t, c[k].x(), c[k].y(), c[k].z(), domain.lo.x(), domain.lo.y(), domain.lo.z(),
              domain.hi.x(), domain.hi.y(), domain.hi.z()));
        }
      }
      const Vec3 tlo = c[0].cwiseMin(c[1]).cwiseMin(c[2]), thi = c[0].cwiseMax(c[1]).cwiseMax(c[2]);
      lo = lo.cwiseMin(tlo);
      hi = hi.cwiseMax(thi);
      set.corners.push_back(c);
      set.box_lo.push_back(tlo);
      set.box_hi.push_back(thi);
      set.tri_body.push_back(static_cast<int>(b));
    }
    set.body_lo.push_back(lo);
    set.body_hi.push_back(hi);
    set.tri_offset.push_back(static_cast<int>(set.corners.size()));
  }

  // Intersections: self-intersections and overlapping bodies.
  std::vector<TriangleRef> refs(set.corners.size());
  for (std::size_t g = 0; g < refs.size(); ++g) {
    const int b = set.tri_body[g];
    refs[g].group = b;
    for (int k = 0; k < 3; ++k) {
      refs[g].p[k] = set.corners[g][k];
      refs[g].v[k] = solids[b].triangles(set.local(static_cast<int>(g)), k);
    }
  }
  if (auto hit = find_intersecting_triangles(refs)) {
    const int g = hit->first, h = hit->second;
    const int bg = set.tri_body[g], bh = set.tri_body[h];
    if (bg == bh) {
      throw MeshError(fmt::format(
          "remesh: body {}: its surface intersects itself (triangles {} and {}): fix the solid "
          "(a fold or an inverted element) or take a smaller time step",
          solids[bg].body, set.local(g), set.local(h)));
    }
    throw MeshError(fmt::format(
        "remesh: bodies {} and {} overlap: triangle {} of body {} intersects triangle {} of body "
        "{}; separate them (or add collisions between the bodies)",
        solids[bg].body, solids[bh].body, set.local(g), solids[bg].body, set.local(h),
        solids[bh].body));
  }
  // Nesting without intersection: one body wholly inside another.
  for (std::size_t b = 0; b < solids.size(); ++b) {
    const Vec3 p = solids[b].vertices.row(solids[b].triangles(0, 0)).transpose();
    for (std::size_t c = 0; c < solids.size(); ++c) {
      if (c == b || !((p.array() >= set.body_lo[c].array()).all() &&
                      (p.array() <= set.body_hi[c].array()).all()))
        continue;
      if (winding_number(p, solids[c].vertices, solids[c].triangles) > 0.5) {
        throw MeshError(fmt::format(
            "remesh: body {} lies inside body {} (vertex {} is enclosed by it): bodies may not "
            "overlap; move it out (a body inside another's fluid-filled cavity is fine)",
            solids[b].body, solids[c].body, solids[b].triangles(0, 0)));
      }
    }
  }
  return set;
}

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

class RefinedSurface {
 public:
  explicit RefinedSurface(const SolidSet& set) : m_set(set) {
    const auto& solids = *set.solids;
    for (std::size_t b = 0; b < solids.size(); ++b) {
      const SolidSurface& s = solids[b];
      std::unordered_map<int, int> id;  // body vertex -> point
      for (Index t = 0; t < s.triangles.rows(); ++t) {
        const int g = set.tri_offset[b] + t;
        SubTri st{};
        st.tri = g;
        for (int k = 0; k < 3; ++k) {
          const int v = s.triangles(t, k);
          auto [it, fresh] = id.try_emplace(v, static_cast<int>(points.size()));
          if (fresh) {
            SurfacePoint p;
            p.x = s.vertices.row(v).transpose();
            p.body = static_cast<int>(b);
            points.push_back(std::move(p));
            body_vertex.push_back(v);
          }
          Vec3 w = Vec3::Zero();
          w(k) = 1.0;
          points[it->second].on.emplace_back(g, w);
          st.v[k] = it->second;
        }
        add_sub(st);
      }
    }
  }

  std::vector<SurfacePoint> points;
  std::vector<int> body_vertex;  ///< per point: the body's vertex index, −1 for Steiner points
  std::vector<SubTri> subs;

  const Vec3& x(int p) const { return points[p].x; }
  Vec3 bary(int p, int g) const {
    for (const auto& [t, w] : points[p].on)
      if (t == g) return w;
    throw InternalError("remesh: surface point not on its triangle");
  }
  /// Longest edge of sub s as (a, b); ties broken by the edge key, so that "longest" is a
  /// strict order and LEPP paths end.
  std::pair<int, int> longest_edge(const SubTri& s, double* len = nullptr) const {
    int best = 0;
    double l2 = -1;
    std::uint64_t best_key = 0;
    for (int k = 0; k < 3; ++k) {
      const int a = s.v[k], b = s.v[(k + 1) % 3];
      const double d = (x(a) - x(b)).squaredNorm();
      const std::uint64_t key = edge_key(a, b);
      if (d > l2 || (d == l2 && key > best_key)) l2 = d, best = k, best_key = key;
    }
    if (len) *len = std::sqrt(l2);
    return {s.v[best], s.v[(best + 1) % 3]};
  }
  Vec3 normal(const SubTri& s) const {
    return (x(s.v[1]) - x(s.v[0])).cross(x(s.v[2]) - x(s.v[0])).normalized();
  }
  void diametral(const SubTri& s, Vec3& c, double& r2) const {
    c = triangle_circumcentre(x(s.v[0]), x(s.v[1]), x(s.v[2]));
    r2 = (x(s.v[0]) - c).squaredNorm();
  }
  /// Split edge (a, b) at the fraction t from its lexicographically smaller end (the midpoint
  /// by default), and the (one or two) sub-triangles on it. Returns the new point, or −1 if
  /// the edge no longer exists.
  int split_edge(int a, int b, std::vector<int>* new_subs = nullptr, double t = 0.5) {
    auto it = m_edges.find(edge_key(a, b));
    if (it == m_edges.end()) return -1;
    // Off-centre splits count from the lexicographically smaller end, so that they do not
    // depend on the orientation of the triangles.
    if (std::lexicographical_compare(x(b).data(), x(b).data() + 3, x(a).data(), x(a).data() + 3))
      std::swap(a, b);
    const std::array<int, 2> on = it->second;
    const int m = static_cast<int>(points.size());
    SurfacePoint mp;
    mp.x = (1.0 - t) * x(a) + t * x(b);
    mp.body = points[a].body;
    points.push_back(std::move(mp));
    body_vertex.push_back(-1);
    for (int s : on) {
      if (s < 0) continue;
      const SubTri old = subs[s];
      remove_sub(s);
      int k = 0;  // rotate so that the edge is (v[k], v[k+1])
      for (; k < 3; ++k) {
        const int p = old.v[k], q = old.v[(k + 1) % 3];
        if ((p == a && q == b) || (p == b && q == a)) break;
      }
      const int p = old.v[k], q = old.v[(k + 1) % 3], r = old.v[(k + 2) % 3];
      const Vec3 w = (1.0 - t) * bary(a, old.tri) + t * bary(b, old.tri);
      bool known = false;
      for (const auto& e : points[m].on) known |= e.first == old.tri;
      if (!known) points[m].on.emplace_back(old.tri, w);
      const int s1 = add_sub(SubTri{{p, m, r}, old.tri});
      const int s2 = add_sub(SubTri{{m, q, r}, old.tri});
      if (new_subs) new_subs->insert(new_subs->end(), {s1, s2});
    }
    return m;
  }
  /// Refine each listed sub-triangle (if still alive) by Rivara's longest-edge propagation
  /// path: walk to the neighbour across the longest edge until the edge is the longest of both
  /// triangles, split it there, repeat until the sub-triangle itself is split. Angles stay
  /// bounded below (no ever-thinner triangles). Edges are split at `at` (split_edge). Returns
  /// the number of points added.
  int refine_subs(const std::vector<int>& list, std::vector<int>* new_subs = nullptr,
                  double at = 0.5) {
    int added = 0;
    for (int s : list) {
      while (subs[s].alive) {
        int t = s;
        for (;;) {
          const auto e = longest_edge(subs[t]);
          const auto& on = m_edges.at(edge_key(e.first, e.second));
          const int n = on[0] == t ? on[1] : on[0];
          if (n < 0) throw InternalError("remesh: open solid surface in refinement");
          const auto en = longest_edge(subs[n]);
          if (edge_key(en.first, en.second) == edge_key(e.first, e.second)) {
            split_edge(e.first, e.second, new_subs, at);
            ++added;
            break;
          }
          t = n;
        }
      }
    }
    return added;
  }
  /// The sub-triangle across edge (v[k], v[k+1]) of sub s (−1 if none).
  int neighbour(int s, int k) const {
    const auto& on = m_edges.at(edge_key(subs[s].v[k], subs[s].v[(k + 1) % 3]));
    return on[0] == s ? on[1] : on[0];
  }
  /// Alive sub-triangles of each global triangle.
  std::vector<std::vector<int>> subs_by_triangle() const {
    std::vector<std::vector<int>> out(m_set.corners.size());
    for (std::size_t s = 0; s < subs.size(); ++s)
      if (subs[s].alive) out[subs[s].tri].push_back(static_cast<int>(s));
    return out;
  }

 private:
  int add_sub(const SubTri& st) {
    const int id = static_cast<int>(subs.size());
    subs.push_back(st);
    for (int k = 0; k < 3; ++k) {
      auto& slot =
          m_edges.try_emplace(edge_key(st.v[k], st.v[(k + 1) % 3]), std::array<int, 2>{-1, -1})
              .first->second;
      if (slot[0] < 0)
        slot[0] = id;
      else if (slot[1] < 0)
        slot[1] = id;
      else
        throw InternalError("remesh: surface edge with more than two triangles");
    }
    return id;
  }
  void remove_sub(int s) {
    subs[s].alive = false;
    for (int k = 0; k < 3; ++k) {
      auto it = m_edges.find(edge_key(subs[s].v[k], subs[s].v[(k + 1) % 3]));
      for (int& e : it->second)
        if (e == s) e = -1;
      if (it->second[0] < 0 && it->second[1] < 0) m_edges.erase(it);
    }
  }
  const SolidSet& m_set;
  std::unordered_map<std::uint64_t, std::array<int, 2>> m_edges;
};

/// Refine the surfaces: split sub-triangles longer than the surface size, then until every
/// sub-triangle's diametral sphere holds no other surface point (Gabriel: then each is a
/// Delaunay face of any superset that keeps the spheres empty).
void refine_surface(RefinedSurface& surf, const SizeField& size, int max_rounds) {
  for (int round = 0; round < max_rounds; ++round) {
    std::vector<int> split;
    for (std::size_t s = 0; s < surf.subs.size(); ++s) {
      const SubTri& st = surf.subs[s];
      if (!st.alive) continue;
      double len = 0;
      surf.longest_edge(st, &len);
      const Vec3 g = (surf.x(st.v[0]) + surf.x(st.v[1]) + surf.x(st.v[2])) / 3.0;
      if (len > kSurfaceEdgeFactor * size.at(g, 0.0)) split.push_back(static_cast<int>(s));
    }
    if (split.empty()) break;
    surf.refine_subs(split);
  }
  // No Gabriel splits below this circumradius: at a concave crease (a fold of the surface
  // past 180°) the other face's points stay inside every diametral sphere along the edge, and
  // splitting cascaded to 2e-6 m edges. Those triangles are left to the recovery, which asks
  // only for a Delaunay face, not an empty diametral sphere.
  const double floor2 = std::pow(kGabrielFloor * size.surface(), 2);
  for (int round = 0; round < max_rounds; ++round) {
    HashGrid grid(2.0 * size.surface());
    std::vector<Vec3> cs(surf.subs.size());
    std::vector<double> r2s(surf.subs.size());
    for (std::size_t s = 0; s < surf.subs.size(); ++s) {
      if (!surf.subs[s].alive) continue;
      surf.diametral(surf.subs[s], cs[s], r2s[s]);
      const double r = std::sqrt(r2s[s]);
      grid.add_box(cs[s] - Vec3::Constant(r), cs[s] + Vec3::Constant(r), static_cast<int>(s));
    }
    std::vector<int> split;
    std::vector<char> marked(surf.subs.size(), 0);
    for (std::size_t p = 0; p < surf.points.size(); ++p) {
      const auto* items = grid.at(surf.points[p].x);
      if (!items) continue;
      for (int s : *items) {
        const SubTri& st = surf.subs[s];
        if (marked[s] || st.v[0] == static_cast<int>(p) || st.v[1] == static_cast<int>(p) ||
            st.v[2] == static_cast<int>(p) || r2s[s] < floor2)
          continue;
        if ((surf.points[p].x - cs[s]).squaredNorm() < r2s[s] * (1.0 - 1e-9)) {
          marked[s] = 1;
          split.push_back(s);
        }
      }
    }
    if (split.empty()) return;
    surf.refine_subs(split);
  }
}

// ---------------------------------------------------------------------------------------
// Vertex placement: graded BCC lattice on a balanced octree
// ---------------------------------------------------------------------------------------

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

class Octree {
 public:
  Octree(const FluidDomain& domain, const SolidSet& set, const SizeField& size)
      : m_domain(domain), m_set(set), m_size(size) {
    const Vec3 L = domain.hi - domain.lo;
    for (int a = 0; a < 3; ++a) {
      m_n[a] = std::max(1, static_cast<int>(std::ceil(L(a) / size.far() - 1e-9)));
      m_root(a) = L(a) / m_n[a];
    }
    // One root size for all axes if the box allows it (the box's sides commensurate with a
    // size ≤ far_size, e.g. 1.4 × 1.4 × 0.8 with 0.2): an isotropic lattice (see Lattice).
    double best = 0;
    int best_n[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a)
      for (int N = m_n[a]; N <= 4 * m_n[a]; ++N) {
        const double r = L(a) / N;
        int n[3];
        bool ok = true;
        for (int b = 0; b < 3 && ok; ++b) {
          n[b] = static_cast<int>(std::lround(L(b) / r));
          ok = n[b] >= 1 && std::abs(L(b) / r - n[b]) <= 1e-9 * n[b];
        }
        if (ok && r > best) best = r, std::copy(n, n + 3, best_n);
      }
    if (best > 0) {
      m_isotropic = true;
      for (int a = 0; a < 3; ++a) m_n[a] = best_n[a];
      m_root = Vec3::Constant(best);
    }
    const double rmax = m_root.maxCoeff();
    m_levels = std::max(0, static_cast<int>(std::ceil(std::log2(rmax / size.surface()) - 1e-9)));
    if (size.sizing->refine) m_levels += 3;  // the refinement field may ask for finer cells
    const long long span = static_cast<long long>(*std::max_element(m_n, m_n + 3))
                           << (m_levels + 1);
    TETFSI_REQUIRE(InputError, span < (1LL << 21),
                   "remesh: the sizes span too many levels (domain {:.4g} m, surface size {:.4g} "
                   "m): use a larger surface_size or far_size",
                   L.maxCoeff(), size.surface());
    m_leaves.resize(m_levels + 1);
  }

  Lattice build() {
    // Candidate triangles of each root cube (within the keep radius of subdivide, from the
    // triangle's box): binned, not by testing every triangle against every root.
    const double keep = std::max(0.0, cube_size(0) - m_size.surface()) / m_size.sizing->grading +
                        0.5 * extent(0).norm();
    const std::size_t nroots = static_cast<std::size_t>(m_n[0]) * m_n[1] * m_n[2];
    std::vector<std::vector<int>> cand(nroots);
    for (std::size_t g = 0; g < m_set.corners.size(); ++g) {
      int lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        const double u0 = (m_set.box_lo[g](a) - keep - m_domain.lo(a)) / m_root(a) - 0.5;
        const double u1 = (m_set.box_hi[g](a) + keep - m_domain.lo(a)) / m_root(a) - 0.5;
        lo[a] = std::max(0, static_cast<int>(std::ceil(u0)));
        hi[a] = std::min(m_n[a] - 1, static_cast<int>(std::floor(u1)));
      }
      for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
          for (int i = lo[0]; i <= hi[0]; ++i) {
            const Vec3 c = centre(0, i, j, k);
            const Vec3 d = (m_set.box_lo[g] - c).cwiseMax(c - m_set.box_hi[g]).cwiseMax(0.0);
            if (d.norm() < keep)
              cand[i +
                   static_cast<std::size_t>(m_n[0]) * (j + static_cast<std::size_t>(m_n[1]) * k)]
                  .push_back(static_cast<int>(g));
          }
    }
    for (int k = 0; k < m_n[2]; ++k)
      for (int j = 0; j < m_n[1]; ++j)
        for (int i = 0; i < m_n[0]; ++i)
          subdivide(0, i, j, k,
                    cand[i + static_cast<std::size_t>(m_n[0]) *
                                 (j + static_cast<std::size_t>(m_n[1]) * k)]);
    balance();
    return points();
  }

 private:
  Vec3 extent(int level) const { return m_root / static_cast<double>(1 << level); }
  Vec3 centre(int level, int i, int j, int k) const {
    return m_domain.lo + extent(level).cwiseProduct(Vec3(i + 0.5, j + 0.5, k + 0.5));
  }
  double cube_size(int level) const { return m_root.maxCoeff() / static_cast<double>(1 << level); }

  void subdivide(int level, int i, int j, int k, const std::vector<int>& cand) {
    const Vec3 c = centre(level, i, j, k);
    const double s = cube_size(level);
    // Split iff s > size(c) = min(far, surface + grading · dist, refine): the distance only
    // matters below (s − surface) / grading, so stop at the first triangle that close, and
    // skip triangles whose box is farther.
    const double reach = (s / (1.0 + 1e-9) - m_size.surface()) / m_size.sizing->grading;
    double dist = kInf;
    if (reach > 0) {
      for (int g : cand) {
        const Vec3 d = (m_set.box_lo[g] - c).cwiseMax(c - m_set.box_hi[g]).cwiseMax(0.0);
        if (d.squaredNorm() >= reach * reach) continue;
        const auto& t = m_set.corners[g];
        dist = std::min(dist, (closest_on_triangle(c, t[0], t[1], t[2]) - c).norm());
        if (dist < reach) break;
      }
    }
    const bool split = level < m_levels && s > m_size.at(c, dist) * (1.0 + 1e-9);
    if (!split) {
      m_leaves[level].insert(pack3(i, j, k));
      return;
    }
    const int cl = level + 1;
    const double cs = cube_size(cl);
    const double hd = 0.5 * extent(cl).norm();
    const double keep = std::max(0.0, cs - m_size.surface()) / m_size.sizing->grading + hd;
    std::vector<int> sub;
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const int ci = 2 * i + dx, cj = 2 * j + dy, ck = 2 * k + dz;
          const Vec3 cc = centre(cl, ci, cj, ck);
          sub.clear();
          for (int g : cand) {
            const Vec3 d = (m_set.box_lo[g] - cc).cwiseMax(cc - m_set.box_hi[g]).cwiseMax(0.0);
            if (d.norm() < keep) sub.push_back(g);
          }
          subdivide(cl, ci, cj, ck, sub);
        }
  }

  /// The leaf containing cube (level, i, j, k)'s region, as its level, or −1 if that cube
  /// is itself subdivided.
  int leaf_level_containing(int level, int i, int j, int k) const {
    for (int l = 0; l <= level; ++l) {
      const int sh = level - l;
      if (m_leaves[l].count(pack3(i >> sh, j >> sh, k >> sh))) return l;
    }
    return -1;
  }

  void split_leaf(int level, int i, int j, int k) {
    m_leaves[level].erase(pack3(i, j, k));
    for (int d = 0; d < 8; ++d)
      m_leaves[level + 1].insert(pack3(2 * i + (d & 1), 2 * j + ((d >> 1) & 1), 2 * k + (d >> 2)));
  }

  /// 2:1 balance across faces, edges and corners: neighbouring leaves differ by at most one
  /// level (graded spacing, no abrupt jumps).
  void balance() {
    for (int level = m_levels; level >= 2; --level) {
      std::vector<std::uint64_t> keys(m_leaves[level].begin(), m_leaves[level].end());
      const int n[3] = {m_n[0] << level, m_n[1] << level, m_n[2] << level};
      for (std::uint64_t key : keys) {
        const int i = key & 0x1FFFFF, j = (key >> 21) & 0x1FFFFF, k = (key >> 42) & 0x1FFFFF;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int a = i + dx, b = j + dy, c = k + dz;
              if ((dx | dy | dz) == 0 || a < 0 || b < 0 || c < 0 || a >= n[0] || b >= n[1] ||
                  c >= n[2])
                continue;
              for (;;) {
                const int l = leaf_level_containing(level, a, b, c);
                if (l < 0 || l >= level - 1) break;
                const int sh = level - l;
                split_leaf(l, a >> sh, b >> sh, c >> sh);
              }
            }
      }
    }
  }

  /// Whether every leaf around the lattice point q (units of half the finest spacing) has the
  /// same level and q is a corner of each: wall jitter only there, since jittered wall points
  /// where octree levels meet made slivers (min dihedral 3°).
  bool uniform_around(const std::uint64_t q[3], int fine) const {
    int level = -1;
    for (int d = 0; d < 8; ++d) {
      std::int64_t p[3];
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        p[a] = static_cast<std::int64_t>(q[a]) + ((d >> a & 1) ? 1 : -1);
        inside &= p[a] >= 0 && p[a] < (static_cast<std::int64_t>(m_n[a]) << fine);
      }
      if (!inside) continue;
      int l = 0;
      for (; l <= m_levels; ++l) {
        const int sh = fine - l;
        if (m_leaves[l].count(pack3(p[0] >> sh, p[1] >> sh, p[2] >> sh))) break;
      }
      if (l > m_levels || (level >= 0 && l != level)) return false;
      level = l;
    }
    const std::uint64_t step = 1ULL << (fine - level);
    return q[0] % step == 0 && q[1] % step == 0 && q[2] % step == 0;
  }

  /// Corners and centres of the leaves (BCC), deduplicated on the integer grid of half the
  /// finest spacing; points on the box faces get the exact face coordinate.
  Lattice points() const {
    struct Item {
      std::uint64_t key;
      double size;
    };
    std::vector<Item> items;
    const int fine = m_levels + 1;  // half-steps of the finest level
    for (int level = 0; level <= m_levels; ++level) {
      const std::uint64_t step = 1ULL << (fine - level);
      const double s = cube_size(level);
      for (std::uint64_t key : m_leaves[level]) {
        const std::uint64_t i = key & 0x1FFFFF, j = (key >> 21) & 0x1FFFFF,
                            k = (key >> 42) & 0x1FFFFF;
        for (int d = 0; d < 8; ++d)
          items.push_back(
              {pack3((i + (d & 1)) * step, (j + ((d >> 1) & 1)) * step, (k + (d >> 2)) * step), s});
        items.push_back({pack3(i * step + step / 2, j * step + step / 2, k * step + step / 2), s});
      }
    }
    // Points on the box faces are jittered within them (kWallJitter); 'fixed' holds the axes
    // they may not move along (the normals of the faces they lie on).
    std::unordered_map<std::uint64_t, std::uint8_t> fixed;
    for (int level = 0; level <= m_levels; ++level) {
      const std::uint64_t step = 1ULL << (fine - level);
      const int n[3] = {m_n[0] << level, m_n[1] << level, m_n[2] << level};
      for (std::uint64_t key : m_leaves[level]) {
        const int c[3] = {static_cast<int>(key & 0x1FFFFF),
                          static_cast<int>((key >> 21) & 0x1FFFFF),
                          static_cast<int>((key >> 42) & 0x1FFFFF)};
        for (int a = 0; a < 3; ++a)
          for (int side = 0; side < 2; ++side) {
            int nb[3] = {c[0], c[1], c[2]};
            nb[a] += side ? 1 : -1;
            if (nb[a] >= 0 && nb[a] < n[a]) continue;  // not on the box
            const int b1 = (a + 1) % 3, b2 = (a + 2) % 3;
            for (int d = 0; d < 4; ++d) {
              std::uint64_t q[3];
              q[a] = (c[a] + side) * step;
              q[b1] = (c[b1] + (d & 1)) * step;
              q[b2] = (c[b2] + (d >> 1)) * step;
              fixed[pack3(q[0], q[1], q[2])] |= static_cast<std::uint8_t>(1u << a);
            }
          }
      }
    }
    std::sort(items.begin(), items.end(), [](const Item& a, const Item& b) {
      return a.key < b.key || (a.key == b.key && a.size < b.size);
    });
    Lattice out;
    out.isotropic = m_isotropic;
    out.unit = m_root(0) / static_cast<double>(1ULL << fine);
    const std::uint64_t qmax[3] = {static_cast<std::uint64_t>(m_n[0]) << fine,
                                   static_cast<std::uint64_t>(m_n[1]) << fine,
                                   static_cast<std::uint64_t>(m_n[2]) << fine};
    const Vec3 unit = m_root / static_cast<double>(1ULL << fine);
    for (std::size_t n = 0; n < items.size(); ++n) {
      if (n > 0 && items[n].key == items[n - 1].key) continue;
      const std::uint64_t q[3] = {items[n].key & 0x1FFFFF, (items[n].key >> 21) & 0x1FFFFF,
                                  (items[n].key >> 42) & 0x1FFFFF};
      Vec3 x;
      for (int a = 0; a < 3; ++a)
        x(a) =
            q[a] == qmax[a] ? m_domain.hi(a) : m_domain.lo(a) + static_cast<double>(q[a]) * unit(a);
      auto fx = fixed.find(items[n].key);
      if (kWallJitter > 0 && fx != fixed.end() && uniform_around(q, fine)) {
        // Points on a patch's rectangle edge stay on it, so lattice-aligned patches are exact.
        for (const DomainPatch& dp : m_domain.patches) {
          int j = 0;
          for (int a = 0; a < 3; ++a) {
            if (a == dp.side / 2) continue;
            if (std::abs(x(a) - dp.lo(j)) < 1e-12 || std::abs(x(a) - dp.hi(j)) < 1e-12)
              fx->second |= static_cast<std::uint8_t>(1u << a);
            ++j;
          }
        }
        // Deterministic jitter (hash of the lattice key), tangential on the box faces.
        std::uint64_t h = items[n].key * 0x9E3779B97F4A7C15ULL;
        for (int a = 0; a < 3; ++a) {
          h ^= h >> 31;
          h *= 0xBF58476D1CE4E5B9ULL;
          h ^= h >> 29;
          const double u = static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0) * 2.0 - 1.0;
          if (!(fx->second >> a & 1) && q[a] != 0 && q[a] != qmax[a])
            x(a) += kWallJitter * items[n].size * u;
        }
      }
      if (m_isotropic) {
        Vec3 y;
        for (int a = 0; a < 3; ++a)
          y(a) = x(a) == (q[a] == qmax[a] ? m_domain.hi(a)
                                          : m_domain.lo(a) + static_cast<double>(q[a]) * unit(a))
                     ? static_cast<double>(q[a])
                     : (x(a) - m_domain.lo(a)) / unit(a);  // jittered
        out.y.push_back(y);
      }
      out.points.push_back(x);
      out.size.push_back(items[n].size);
    }
    return out;
  }

  const FluidDomain& m_domain;
  const SolidSet& m_set;
  const SizeField& m_size;
  int m_n[3];
  Vec3 m_root;
  int m_levels = 0;
  bool m_isotropic = false;
  std::vector<std::unordered_set<std::uint64_t>> m_leaves;  ///< per level
};

/// Drop lattice points inside (or on) a sub-triangle's diametral sphere, or closer to the
/// surface than kProtection × their spacing. Returns the flags (1 = keep).
std::vector<char> exclude_near_surface(const Lattice& lat, const RefinedSurface& surf,
                                       const SizeField& size) {
  std::vector<char> keep(lat.points.size(), 1);
  if (surf.subs.empty()) return keep;
  const double protect = kProtection * 4.0 * size.surface();  // bound on kProtection × spacing
  HashGrid grid(2.0 * size.surface());
  std::vector<Vec3> cs(surf.subs.size());
  std::vector<double> r2s(surf.subs.size());
  for (std::size_t s = 0; s < surf.subs.size(); ++s) {
    const SubTri& st = surf.subs[s];
    if (!st.alive) continue;
    surf.diametral(st, cs[s], r2s[s]);
    const Vec3 lo = surf.x(st.v[0]).cwiseMin(surf.x(st.v[1])).cwiseMin(surf.x(st.v[2]));
    const Vec3 hi = surf.x(st.v[0]).cwiseMax(surf.x(st.v[1])).cwiseMax(surf.x(st.v[2]));
    const double r = std::sqrt(r2s[s]);
    const Vec3 rr = Vec3::Constant(r * (1.0 + 1e-9));
    const Vec3 pp = Vec3::Constant(protect);
    grid.add_box(lo.cwiseMin(cs[s] - rr) - pp, hi.cwiseMax(cs[s] + rr) + pp, static_cast<int>(s));
  }
  for (std::size_t p = 0; p < lat.points.size(); ++p) {
    const Vec3& x = lat.points[p];
    const auto* items = grid.at(x);
    if (!items) continue;
    const double prot = std::min(protect, kProtection * lat.size[p]);
    for (int s : *items) {
      if ((x - cs[s]).squaredNorm() <= r2s[s] * (1.0 + 1e-9)) {
        keep[p] = 0;
        break;
      }
      const SubTri& st = surf.subs[s];
      if ((closest_on_triangle(x, surf.x(st.v[0]), surf.x(st.v[1]), surf.x(st.v[2])) - x)
              .squaredNorm() < prot * prot) {
        keep[p] = 0;
        break;
      }
    }
  }
  return keep;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// remesh
// ---------------------------------------------------------------------------------------

TetMesh remesh(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
               const Sizing& sizing, RemeshReport* report_out, const RemeshOptions& options) {
  RemeshReport report;
  const double t_start = now_seconds();
  check_sizing(sizing);
  check_domain(domain);
  const SolidSet set = gather_solids(domain, solids);

  // 1–2. Vertex placement and the refined surfaces; coarsen everything if over budget.
  SizeField size{&sizing};
  Lattice lat;
  std::vector<char> keep;
  std::unique_ptr<RefinedSurface> surf;
  double last_estimate = -1.0;
  for (int attempt = 0;; ++attempt) {
    surf = std::make_unique<RefinedSurface>(set);
    refine_surface(*surf, size, 40);
    lat = Octree(domain, set, size).build();
    keep = exclude_near_surface(lat, *surf, size);
    const Index kept = static_cast<Index>(std::count(keep.begin(), keep.end(), 1));
    // A BCC lattice has 6 tets per vertex; near surfaces a little more.
    const double estimate = 6.3 * static_cast<double>(kept + surf->points.size());
    if (sizing.max_cells <= 0 || estimate <= sizing.max_cells || attempt == 6) break;
    double f = 1.02 * std::cbrt(estimate / sizing.max_cells);
    // The octree's levels are a factor 2 apart: a scale that changed nothing must grow more.
    if (last_estimate > 0 && estimate >= 0.99 * last_estimate) f = std::max(f, 1.26);
    last_estimate = estimate;
    size.scale *= f;
    logger().debug(
        "remesh: about {:.0f} cells would exceed the budget of {}: sizes scaled by {:.3g}",
        estimate, sizing.max_cells, size.scale);
  }
  report.size_scale = size.scale;
  std::vector<Vec3> pts;
  std::vector<Vec3> dt_pts;     // the same points in the Delaunay's coordinates (see Lattice)
  std::vector<double> pt_size;  // lattice points: their local spacing (m)
  // Surface points within 1e-7 lattice units of a lattice plane are put on it: a solid whose
  // faces lie on lattice planes (round numbers) otherwise makes nearly flat cells with lattice
  // points, from round-off alone.
  const auto to_dt = [&](const Vec3& x) -> Vec3 {
    if (!lat.isotropic) return x;
    Vec3 y = (x - domain.lo) / lat.unit;
    for (int a = 0; a < 3; ++a)
      if (std::abs(y(a) - std::round(y(a))) <= 1e-7) y(a) = std::round(y(a));
    return y;
  };
  for (std::size_t p = 0; p < lat.points.size(); ++p)
    if (keep[p]) {
      pts.push_back(lat.points[p]);
      dt_pts.push_back(lat.isotropic ? lat.y[p] : lat.points[p]);
      pt_size.push_back(lat.size[p]);
    }
  const int nL = static_cast<int>(pts.size());
  report.lattice_points = nL;
  report.surface_points = 0;
  for (int b : surf->body_vertex) report.surface_points += b >= 0;
  for (const SurfacePoint& sp : surf->points) {
    pts.push_back(sp.x);
    dt_pts.push_back(to_dt(sp.x));
  }
  report.seconds_placement = now_seconds() - t_start;

  // 3. Delaunay.
  double t0 = now_seconds();
  Delaunay dt;
  dt.build(dt_pts);
  report.seconds_delaunay = now_seconds() - t0;

  // 4. Conformity: every solid triangle must be covered by Delaunay faces lying on it.
  t0 = now_seconds();
  const auto surface_id = [&](int v) { return v - nL; };
  std::vector<double> tri_area(set.corners.size());
  for (std::size_t g = 0; g < tri_area.size(); ++g) tri_area[g] = set.area(static_cast<int>(g));
  // Lattice points near the surface, to drop those inside new sub-triangles' spheres.
  HashGrid lattice_grid(2.0 * size.surface());
  for (int v = 0; v < nL; ++v) {
    for (std::size_t b = 0; b < set.body_lo.size(); ++b) {
      const double m = 4.0 * size.far();
      if ((pts[v].array() >= set.body_lo[b].array() - m).all() &&
          (pts[v].array() <= set.body_hi[b].array() + m).all()) {
        lattice_grid.add_point(pts[v], v);
        break;
      }
    }
  }
  std::vector<char> lattice_removed(nL, 0);
  MatX4i tets, nbrs;
  std::unordered_map<TripleKey, int, TripleHash> facet_tri;  // surface facet -> triangle or −1
  const auto common_triangle = [&](int a, int b, int c) {
    for (const auto& ea : surf->points[surface_id(a)].on) {
      bool in_b = false, in_c = false;
      for (const auto& eb : surf->points[surface_id(b)].on) in_b |= eb.first == ea.first;
      if (!in_b) continue;
      for (const auto& ec : surf->points[surface_id(c)].on) in_c |= ec.first == ea.first;
      if (in_c) return ea.first;
    }
    return -1;
  };
  const auto on_box = [&](const Vec3& x) {
    return (x.array() == domain.lo.array()).any() || (x.array() == domain.hi.array()).any();
  };
  // Cheap screen for small dihedral angles: the shape measure 6√2 V / l_rms³ below `shape`
  // (a small dihedral angle θ makes the tet flat, V ≤ c sin θ l³; 0.3 for 5°, 0.5 for 10°),
  // before the exact test by dihedral angles.
  const auto maybe_flat = [&](const MatX4i& T, Index t, double shape) {
    const Vec3& a = pts[T(t, 0)];
    const Vec3 e1 = pts[T(t, 1)] - a, e2 = pts[T(t, 2)] - a, e3 = pts[T(t, 3)] - a;
    const double l2 = e1.squaredNorm() + e2.squaredNorm() + e3.squaredNorm() +
                      (e2 - e1).squaredNorm() + (e3 - e1).squaredNorm() + (e3 - e2).squaredNorm();
    const double v6 = e1.dot(e2.cross(e3));  // √2 v6 < shape (l2/6)^1.5, without pow
    return v6 <= 0 || 2.0 * v6 * v6 < shape * shape * (l2 / 6.0) * (l2 / 6.0) * (l2 / 6.0);
  };
  // A degenerate cell: its signed volume in metres, in double precision, is at most
  // kFlat × (longest edge)³. The Delaunay's exact predicates see a positive cell, but in the
  // Delaunay's own coordinates (lattice units, surface points snapped to lattice planes, see
  // to_dt): four points coplanar in exact arithmetic (e.g. a lattice edge under a sheet's edge
  // across its thickness, both parallel to the sheet's normal and symmetric about its mid-plane:
  // a co-circular trapezoid) make a cell whose volume in metres is round-off of either sign.
  // In the fluid it has no volume (1/V in the operators; build_tet_mesh rejects V ≤ 0).
  const auto is_degenerate = [&](const MatX4i& T, Index t) {
    const Vec3& a = pts[T(t, 0)];
    const Vec3 e1 = pts[T(t, 1)] - a, e2 = pts[T(t, 2)] - a, e3 = pts[T(t, 3)] - a;
    const double l2 =
        std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm(), (e2 - e1).squaredNorm(),
                  (e3 - e1).squaredNorm(), (e3 - e2).squaredNorm()});
    return e1.dot(e2.cross(e3)) <= kFlat * l2 * std::sqrt(l2);
  };
  // Lattice vertices to delete, one per sliver (min dihedral < kSliverDeg; only degenerate
  // cells if `degenerate_only`) that has one: the lattice vertex nearest to the sliver's
  // surface vertices (or its first), never a box point.
  const auto sliver_vertices = [&](const MatX4i& T, bool degenerate_only) {
    std::vector<Index> cand;
    std::vector<char> degenerate;
    for (Index t = 0; t < T.rows(); ++t) {
      bool lattice = false;
      for (int k = 0; k < 4; ++k) lattice |= T(t, k) < nL;
      if (!lattice || !maybe_flat(T, t, 0.3)) continue;
      const bool d = is_degenerate(T, t);
      if (degenerate_only && !d) continue;
      cand.push_back(t);
      degenerate.push_back(d);
    }
    MatX4i sub(static_cast<Index>(cand.size()), 4);
    for (std::size_t i = 0; i < cand.size(); ++i) sub.row(i) = T.row(cand[i]);
    MatX3 P(static_cast<Index>(pts.size()), 3);
    for (std::size_t v = 0; v < pts.size(); ++v) P.row(v) = pts[v].transpose();
    const TetQuality q = tet_quality(P, sub);
    std::vector<int> drop;
    for (Index i = 0; i < sub.rows(); ++i) {
      if (!degenerate[i] && !(q.min_dihedral_deg(i) < kSliverDeg)) continue;
      int best = -1;
      double best_d = kInf;
      for (int k = 0; k < 4; ++k) {
        const int v = sub(i, k);
        if (v >= nL || on_box(pts[v])) continue;
        if (best < 0) best = v;
        for (int j = 0; j < 4; ++j) {
          if (sub(i, j) < nL) continue;
          const double d = (pts[v] - pts[sub(i, j)]).squaredNorm();
          if (d < best_d) best_d = d, best = v;
        }
      }
      if (best >= 0) drop.push_back(best);
    }
    std::sort(drop.begin(), drop.end());
    drop.erase(std::unique(drop.begin(), drop.end()), drop.end());
    return drop;
  };
  // A face of surface points with no common triangle that still lies in the surface: it
  // straddles coplanar triangles (the plane of a triangle of one vertex holds the other two).
  // It seals the solid like a triangle's own faces do.
  const auto in_surface = [&](int a, int b, int c) {
    const SurfacePoint &pa = surf->points[surface_id(a)], &pb = surf->points[surface_id(b)],
                       &pc = surf->points[surface_id(c)];
    if (pa.body != pb.body || pa.body != pc.body) return false;
    const double scale = (pa.x - pb.x).norm() + (pb.x - pc.x).norm() + (pc.x - pa.x).norm();
    for (const auto& e : pa.on) {
      const auto& T = set.corners[e.first];
      const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]).normalized();
      if (std::abs((pb.x - T[0]).dot(n)) <= 1e-9 * scale &&
          std::abs((pc.x - T[0]).dot(n)) <= 1e-9 * scale)
        return true;
    }
    return false;
  };
  // A flat cell: four surface points of one body with |6V| ≤ kFlat l³ (coplanar up to
  // round-off; a co-circular coplanar quad is a valid but flat Delaunay cell with a
  // meaningless circumcentre).
  const auto is_flat_cell = [&](int v0, int v1, int v2, int v3) {
    if (v0 < nL || v1 < nL || v2 < nL || v3 < nL) return false;
    const int body = surf->points[surface_id(v0)].body;
    if (surf->points[surface_id(v1)].body != body || surf->points[surface_id(v2)].body != body ||
        surf->points[surface_id(v3)].body != body)
      return false;
    const Vec3 e1 = pts[v1] - pts[v0], e2 = pts[v2] - pts[v0], e3 = pts[v3] - pts[v0];
    const double l = std::max(
        {e1.norm(), e2.norm(), e3.norm(), (e2 - e1).norm(), (e3 - e1).norm(), (e3 - e2).norm()});
    return std::abs(e1.dot(e2.cross(e3))) <= kFlat * l * l * l;
  };
  // A flat cell on a surface: its plane is that of a triangle of one of its points (a
  // co-circular quad of the surface, e.g. a square of a box face, once rotated and rounded).
  // A flat cell whose points lie on two faces meeting at a crease is not: an isosceles
  // trapezoid of points mirrored across the crease (the two sides of a cavity's edge, where
  // both faces are sampled alike) is co-circular, and its plane cuts through the fluid.
  const auto is_flat_surface_cell = [&](int v0, int v1, int v2, int v3) {
    if (!is_flat_cell(v0, v1, v2, v3)) return false;
    const int v[4] = {v0, v1, v2, v3};
    double scale = 0.0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) scale = std::max(scale, (pts[v[i]] - pts[v[j]]).norm());
    for (int i = 0; i < 4; ++i)
      for (const auto& e : surf->points[surface_id(v[i])].on) {
        const auto& T = set.corners[e.first];
        const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]).normalized();
        bool all = true;
        for (int j = 0; j < 4 && all; ++j)
          all = std::abs((pts[v[j]] - T[0]).dot(n)) <= 1e-9 * scale;
        if (all) return true;
      }
    return false;
  };
  // Sub-triangles to split under flat cells: the faces of a flat cell straddling coplanar
  // triangles (no triangle holds all four of its points), and for a flat cell off the surface
  // and in the fluid (a zero-volume fluid cell), the sub-triangles on one of its edges that
  // lie in the surface: the edge on the lowest triangle id, so one face of the crease only
  // (splitting both sides alike keeps the mirror symmetry, and the trapezoids come back); if
  // it has no such edge, the sub-triangles at its points.
  const auto flat_cell_subs = [&](const MatX4i& cells) {
    std::unordered_map<TripleKey, int, TripleHash> sub_of;
    std::unordered_map<std::uint64_t, std::vector<int>> subs_on_edge;
    std::unordered_map<int, std::vector<int>> subs_at_point;
    const auto alive_subs = [&](auto&& f) {
      for (std::size_t sub = 0; sub < surf->subs.size(); ++sub)
        if (surf->subs[sub].alive) f(surf->subs[sub], static_cast<int>(sub));
    };
    std::vector<int> out;
    for (Index t = 0; t < cells.rows(); ++t) {
      const int v0 = cells(t, 0), v1 = cells(t, 1), v2 = cells(t, 2), v3 = cells(t, 3);
      if (!is_flat_cell(v0, v1, v2, v3)) continue;
      if (!is_flat_surface_cell(v0, v1, v2, v3)) {
        // Inside the solid (at a convex edge of it) it goes with the solid's cells: the side of
        // a triangle holding one of its edges, else the winding number.
        const int c[4] = {v0, v1, v2, v3};
        int side = 0;
        for (int i = 0; i < 4 && side == 0; ++i)
          for (int j = i + 1; j < 4 && side == 0; ++j) {
            const int g = common_triangle(c[i], c[j], c[j]);
            if (g < 0) continue;
            const auto& T = set.corners[g];
            const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]);
            double d = 0.0;
            for (int k = 0; k < 4; ++k) {
              const double dk = (pts[c[k]] - T[0]).dot(n);
              if (std::abs(dk) > std::abs(d)) d = dk;
            }
            side = d > 0 ? 1 : -1;
          }
        if (side == 0) {
          const int b = surf->points[surface_id(v0)].body;
          const Vec3 x = 0.25 * (pts[v0] + pts[v1] + pts[v2] + pts[v3]);
          side = winding_number(x, solids[b].vertices, solids[b].triangles) > 0.5 ? -1 : 1;
        }
        if (side < 0) continue;
        if (subs_on_edge.empty())
          alive_subs([&](const SubTri& st, int sub) {
            for (int k = 0; k < 3; ++k) {
              subs_on_edge[edge_key(st.v[k] + nL, st.v[(k + 1) % 3] + nL)].push_back(sub);
              subs_at_point[st.v[k] + nL].push_back(sub);
            }
          });
        int best_g = std::numeric_limits<int>::max();
        std::uint64_t best_e = 0;
        for (int i = 0; i < 4; ++i)
          for (int j = i + 1; j < 4; ++j) {
            const std::uint64_t e = edge_key(cells(t, i), cells(t, j));
            const int g = common_triangle(cells(t, i), cells(t, j), cells(t, j));
            if (g >= 0 && g < best_g && subs_on_edge.count(e)) best_g = g, best_e = e;
          }
        if (best_g != std::numeric_limits<int>::max()) {
          const auto& on = subs_on_edge.at(best_e);
          out.insert(out.end(), on.begin(), on.end());
        } else {
          for (int k = 0; k < 4; ++k) {
            const auto& at = subs_at_point[cells(t, k)];
            out.insert(out.end(), at.begin(), at.end());
          }
        }
        continue;
      }
      const int g = common_triangle(v0, v1, v2);
      bool common = false;
      if (g >= 0)
        for (const auto& e : surf->points[surface_id(v3)].on) common |= e.first == g;
      if (common) continue;  // flat on one triangle: handled by classification, no straddle
      if (sub_of.empty())
        alive_subs([&](const SubTri& st, int sub) {
          sub_of.emplace(sorted_key(st.v[0] + nL, st.v[1] + nL, st.v[2] + nL), sub);
        });
      for (int k = 0; k < 4; ++k) {
        auto it = sub_of.find(
            sorted_key(cells(t, (k + 1) % 4), cells(t, (k + 2) % 4), cells(t, (k + 3) % 4)));
        if (it != sub_of.end()) out.push_back(it->second);
      }
    }
    return out;
  };
  // Slivers away from the solids (octree transitions in oblique staircases) are perturbed
  // rather than deleted [Tournois, Srinivasan & Alliez 2009, sliver perturbation]: each
  // lattice vertex of each is moved by 0.05–0.2 of its spacing in up to 12 pseudo-random
  // directions, keeping the first move that raises the smallest dihedral angle of the cells
  // with no solid vertex around its star's vertices (all the cells a move can change).
  // Measured on a thin sheet tilted 3°, 17°, 45° and 71°: min dihedral away from it
  // 3.7–11° without, 10.0–11.0° with four rounds. Returns the number moved.
  const auto perturb_away_slivers = [&](const MatX4i& T) {
    MatX3 P(static_cast<Index>(pts.size()), 3);
    std::vector<int> targets;
    {
      std::vector<Index> cand;  // cells with no solid vertex that may have a small angle
      for (Index t = 0; t < T.rows(); ++t) {
        bool surface = false;
        for (int k = 0; k < 4; ++k) surface |= T(t, k) >= nL;
        if (!surface && maybe_flat(T, t, 0.5)) cand.push_back(t);
      }
      for (std::size_t v = 0; v < pts.size(); ++v) P.row(v) = pts[v].transpose();
      MatX4i sub(static_cast<Index>(cand.size()), 4);
      for (std::size_t i = 0; i < cand.size(); ++i) sub.row(i) = T.row(cand[i]);
      const TetQuality q = tet_quality(P, sub);
      for (Index i = 0; i < sub.rows(); ++i) {
        if (!(q.min_dihedral_deg(i) < kAwayDeg)) continue;
        for (int k = 0; k < 4; ++k)
          if (!on_box(pts[sub(i, k)])) targets.push_back(sub(i, k));
      }
    }
    std::sort(targets.begin(), targets.end());
    targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
    int moved = 0;
    MatX4i around;
    const auto worst_around = [&](const std::vector<int>& ring) {
      dt.cells_around(ring, around);
      for (const int v : ring) P.row(v) = pts[v].transpose();
      const TetQuality q = tet_quality(P, around);
      double worst = kInf;  // over the cells with no solid vertex
      for (Index t = 0; t < around.rows(); ++t) {
        bool surface = false;
        for (int k = 0; k < 4; ++k) surface |= around(t, k) >= nL;
        if (!surface) worst = std::min(worst, q.min_dihedral_deg(t));
      }
      return worst;
    };
    for (const int v : targets) {
      MatX4i star;
      dt.cells_around({v}, star);
      std::vector<int> ring(star.data(), star.data() + star.size());
      std::sort(ring.begin(), ring.end());
      ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
      const double before = worst_around(ring);
      const Vec3 old_x = pts[v], old_y = dt_pts[v];
      std::uint64_t h = static_cast<std::uint64_t>(v) * 0x9E3779B97F4A7C15ULL + 1;
      bool ok = false;
      for (int attempt = 0; attempt < 12 && !ok; ++attempt) {
        Vec3 dir;
        for (int a = 0; a < 3; ++a) {
          h ^= h >> 31;
          h *= 0xBF58476D1CE4E5B9ULL;
          h ^= h >> 29;
          dir(a) = static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0) * 2.0 - 1.0;
        }
        if (dir.norm() < 1e-3) continue;
        const Vec3 x = old_x + (0.05 + 0.05 * (attempt % 4)) * pt_size[v] * dir.normalized();
        if ((x.array() <= domain.lo.array()).any() || (x.array() >= domain.hi.array()).any())
          continue;
        dt.remove(v);
        pts[v] = x;
        dt_pts[v] = to_dt(x);
        dt.insert(dt_pts[v], v);
        ok = worst_around(ring) > before;
        if (!ok) {
          dt.remove(v);
          pts[v] = old_x;
          dt_pts[v] = old_y;
          dt.insert(old_y, v);
        }
      }
      moved += ok;
    }
    return moved;
  };
  int cleanup_rounds = 0, perturb_rounds = 0;
  MatX4i near;  // cells touching the surface
  for (int round = 0;; ++round) {
    dt.cells_touching(nL, near);
    facet_tri.clear();
    std::vector<double> covered(set.corners.size(), 0.0);
    for (Index t = 0; t < near.rows(); ++t) {
      for (int k = 0; k < 4; ++k) {
        const int a = near(t, (k + 1) % 4), b = near(t, (k + 2) % 4), c = near(t, (k + 3) % 4);
        if (a < nL || b < nL || c < nL) continue;
        auto [it, fresh] = facet_tri.try_emplace(sorted_key(a, b, c), -1);
        if (!fresh) continue;
        const int g = common_triangle(a, b, c);
        it->second = g >= 0 ? g : (in_surface(a, b, c) ? -2 : -1);
        if (g >= 0) covered[g] += 0.5 * (pts[b] - pts[a]).cross(pts[c] - pts[a]).norm();
      }
    }
    // A triangle is recovered if each of its sub-triangles is a Delaunay face, or if other
    // faces on it tile it exactly (another diagonal of a co-circular quad). Over-coverage
    // comes from flat cells on the surface (both diagonals), which classification handles.
    std::vector<int> missing;
    const auto by_tri_now = surf->subs_by_triangle();
    for (std::size_t g = 0; g < covered.size(); ++g) {
      if (std::abs(covered[g] - tri_area[g]) <= 1e-9 * tri_area[g]) continue;
      bool all = true;
      for (int sub : by_tri_now[g]) {
        const SubTri& st = surf->subs[sub];
        all &= facet_tri.count(sorted_key(st.v[0] + nL, st.v[1] + nL, st.v[2] + nL)) > 0;
      }
      if (!all) missing.push_back(static_cast<int>(g));
    }
    std::vector<int> split;
    if (missing.empty()) {
      // Conforming. A flat cell whose four surface points span two coplanar triangles (a
      // co-circular quad of a rotated box face) would leave fluid faces straddling both:
      // split the sub-triangles under it instead (their shared edge, by LEPP), within the
      // round budget.
      split = flat_cell_subs(near);
      if (split.empty() || round >= options.max_recovery_rounds) {
        // Slivers are removed by deleting a lattice vertex of each, then conformity is
        // checked again. They come from points that are coplanar in exact arithmetic but not
        // after rounding (a lattice plane through a box solid's face, or lattice points at
        // octree transitions when the box needs an anisotropic lattice).
        dt.extract(tets, nbrs);
        bool changed = false;
        if (perturb_rounds < kPerturbRounds) {
          ++perturb_rounds;
          const int moved = perturb_away_slivers(tets);
          report.sliver_points_moved += moved;
          changed |= moved > 0;
        }
        // After the sliver rounds, degenerate cells (is_degenerate) still lose a vertex, once
        // no vertex was moved in this pass (`tets` is then the current triangulation).
        const bool degenerate_only = cleanup_rounds >= kSliverRounds;
        if (cleanup_rounds < kSliverRounds + kDegenerateRounds && !(degenerate_only && changed)) {
          ++cleanup_rounds;
          const std::vector<int> drop = sliver_vertices(tets, degenerate_only);
          for (int v : drop) {
            lattice_removed[v] = 1;
            dt.remove(v);
          }
          report.sliver_points_removed += static_cast<Index>(drop.size());
          changed |= !drop.empty();
        }
        if (!changed) break;
        continue;
      }
    } else {
      if (round >= options.max_recovery_rounds) {
        const int g = missing.front();
        const int b = set.tri_body[g];
        throw MeshError(fmt::format(
            "remesh: body {}: triangle {} (and {} more) is not recovered by the fluid mesh after "
            "{} "
            "rounds of Steiner points ({:.3g} of its area covered): the surface is too close to "
            "itself, another body or a wall for the mesh size; use a smaller surface_size",
            solids[b].body, set.local(g), missing.size() - 1, round, covered[g] / tri_area[g]));
      }
      // Split the sub-triangles of the missing triangles that are not mesh faces.
      const auto by_tri = surf->subs_by_triangle();
      for (int g : missing)
        for (int s : by_tri[g]) {
          const SubTri& st = surf->subs[s];
          if (!facet_tri.count(sorted_key(st.v[0] + nL, st.v[1] + nL, st.v[2] + nL)))
            split.push_back(s);
        }
    }
    report.recovery_rounds = round + 1;
    std::vector<int> new_subs;
    const int before = static_cast<int>(surf->points.size());
    // Straddled quads are split off-centre: a midpoint makes right isosceles triangles whose
    // quads with the neighbours are co-circular again (22 rounds at 1M cells; 0.45: a few).
    surf->refine_subs(split, &new_subs, missing.empty() ? kStraddleSplitAt : 0.5);
    // Keep the new sub-triangles' diametral spheres empty of lattice points.
    for (int s : new_subs) {
      if (!surf->subs[s].alive) continue;
      Vec3 c;
      double r2;
      surf->diametral(surf->subs[s], c, r2);
      const double r = std::sqrt(r2);
      lattice_grid.for_box(c - Vec3::Constant(r), c + Vec3::Constant(r), [&](int v) {
        if (!lattice_removed[v] && (pts[v] - c).squaredNorm() <= r2 * (1.0 + 1e-9)) {
          lattice_removed[v] = 1;
          dt.remove(v);
        }
      });
    }
    for (int p = before; p < static_cast<int>(surf->points.size()); ++p) {
      pts.push_back(surf->points[p].x);
      dt_pts.push_back(to_dt(pts.back()));
      dt.insert(dt_pts.back(), static_cast<int>(pts.size()) - 1);
    }
  }
  report.steiner_points = static_cast<Index>(surf->points.size()) - report.surface_points;
  report.cells_delaunay = static_cast<Index>(tets.rows());
  report.seconds_recovery = now_seconds() - t0;

  // 5. Cells inside solids: flood fill between solid faces, one winding number per region.
  t0 = now_seconds();
  const Index nT = static_cast<Index>(tets.rows());
  std::vector<int> region(nT, -1);
  std::vector<char> region_fluid;
  std::vector<Index> stack;
  // Flat cells on a surface (is_flat_surface_cell) belong to the solid: the fluid meets the
  // surface through their other two faces, which cover the same quad.
  std::vector<char> flat(nT, 0);
  for (Index t = 0; t < nT; ++t)
    flat[t] = is_flat_surface_cell(tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3));

  const auto is_barrier = [&](Index t, int k) {
    const int a = tets(t, (k + 1) % 4), b = tets(t, (k + 2) % 4), c = tets(t, (k + 3) % 4);
    if (a < nL || b < nL || c < nL) return false;
    if (flat[t] || (nbrs(t, k) >= 0 && flat[nbrs(t, k)])) return true;
    auto it = facet_tri.find(sorted_key(a, b, c));
    return it != facet_tri.end() && it->second != -1;
  };
  for (Index seed = 0; seed < nT; ++seed) {
    if (region[seed] >= 0) continue;
    const int r = static_cast<int>(region_fluid.size());
    region[seed] = r;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const Index t = stack.back();
      stack.pop_back();
      for (int k = 0; k < 4; ++k) {
        const Index u = nbrs(t, k);
        if (u < 0 || region[u] >= 0 || is_barrier(t, k)) continue;
        region[u] = r;
        stack.push_back(u);
      }
    }
    const Vec3 x =
        0.25 * (pts[tets(seed, 0)] + pts[tets(seed, 1)] + pts[tets(seed, 2)] + pts[tets(seed, 3)]);
    if (flat[seed]) {
      region_fluid.push_back(0);
      ++report.flat_cells_removed;
      continue;
    }
    bool inside = false;
    for (std::size_t b = 0; b < solids.size() && !inside; ++b) {
      if ((x.array() < set.body_lo[b].array()).any() || (x.array() > set.body_hi[b].array()).any())
        continue;
      inside = winding_number(x, solids[b].vertices, solids[b].triangles) > 0.5;
    }
    region_fluid.push_back(!inside);
  }
  // Fluid cells, with the vertices they use renumbered compactly.
  std::vector<int> new_id(pts.size(), -1);
  std::vector<int> old_id;
  Index nF = 0;
  for (Index t = 0; t < nT; ++t) nF += region_fluid[region[t]];
  MatX4i ftets(nF, 4);
  Index row = 0;
  for (Index t = 0; t < nT; ++t) {
    if (!region_fluid[region[t]]) continue;
    for (int k = 0; k < 4; ++k) {
      int& id = new_id[tets(t, k)];
      if (id < 0) {
        id = static_cast<int>(old_id.size());
        old_id.push_back(tets(t, k));
      }
      ftets(row, k) = id;
    }
    ++row;
  }
  report.cells_removed = nT - nF;
  TETFSI_REQUIRE(MeshError, nF > 0, "remesh: no fluid cell is left: the solids fill the domain");
  // Safety net: the fluid volume must be the box minus the solids (signed, so cavities count
  // as fluid); anything else is a leak through a triangle that was not recovered.
  {
    double expected = (domain.hi - domain.lo).prod(), fluid = 0.0;
    for (const SolidSurface& sol : solids)
      for (Index t = 0; t < sol.triangles.rows(); ++t)
        expected -= Vec3(sol.vertices.row(sol.triangles(t, 0)))
                        .dot(Vec3(sol.vertices.row(sol.triangles(t, 1)))
                                 .cross(Vec3(sol.vertices.row(sol.triangles(t, 2))))) /
                    6.0;
    Index degenerate = -1;  // a fluid cell of no volume that the sliver rounds left
    for (Index t = 0; t < nT; ++t)
      if (region_fluid[region[t]]) {
        fluid +=
            (pts[tets(t, 1)] - pts[tets(t, 0)])
                .dot((pts[tets(t, 2)] - pts[tets(t, 0)]).cross(pts[tets(t, 3)] - pts[tets(t, 0)])) /
            6.0;
        if (degenerate < 0 && is_degenerate(tets, t)) degenerate = t;
      }
    if (degenerate >= 0) {
      const Vec3 x = 0.25 * (pts[tets(degenerate, 0)] + pts[tets(degenerate, 1)] +
                             pts[tets(degenerate, 2)] + pts[tets(degenerate, 3)]);
      int surface = 0;
      for (int k = 0; k < 4; ++k) surface += tets(degenerate, k) >= nL;
      throw MeshError(fmt::format(
          "remesh: a fluid cell at ({:.6g}, {:.6g}, {:.6g}) with {} of its 4 vertices on solids "
          "is flat (coplanar to round-off) and deleting lattice vertices did not remove it (none "
          "but box points, or the rounds ran out): change surface_size slightly and report the "
          "scene",
          x.x(), x.y(), x.z(), surface));
    }
    TETFSI_REQUIRE(MeshError, std::abs(fluid - expected) <= 1e-8 * (domain.hi - domain.lo).prod(),
                   "remesh: the fluid cells fill {:.9g} m^3 but the box minus the solids is {:.9g} "
                   "m^3: a solid surface leaks (not recovered); try a smaller surface_size and "
                   "report the scene",
                   fluid, expected);
  }
  MatX3 verts(old_id.size(), 3);
  for (std::size_t v = 0; v < old_id.size(); ++v) verts.row(v) = pts[old_id[v]].transpose();
  report.seconds_classify = now_seconds() - t0;

  // 6. The TetMesh, tags and provenance.
  t0 = now_seconds();
  TetMesh m = build_tet_mesh(std::move(verts), std::move(ftets));
  for (std::size_t v = 0; v < old_id.size(); ++v) {
    const int o = old_id[v];
    if (o < nL) continue;
    const SurfacePoint& sp = surf->points[surface_id(o)];
    m.vertex_body(v) = solids[sp.body].body;
    m.vertex_triangle(v) = set.local(sp.on.front().first);
    m.vertex_bary.row(v) = sp.on.front().second.transpose();
  }
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (!m.is_boundary(f)) {
      m.face_kind[f] = FaceKind::Interior;
      continue;
    }
    const int a = old_id[m.faces(f, 0)], b = old_id[m.faces(f, 1)], c = old_id[m.faces(f, 2)];
    if (a >= nL && b >= nL && c >= nL) {
      const int g = common_triangle(a, b, c);
      if (g >= 0) {
        m.face_kind[f] = FaceKind::Solid;
        m.face_body(f) = solids[set.tri_body[g]].body;
        m.face_triangle(f) = set.local(g);
        const Vec3 w = (surf->bary(surface_id(a), g) + surf->bary(surface_id(b), g) +
                        surf->bary(surface_id(c), g)) /
                       3.0;
        m.face_bary.row(f) = w.transpose();
        continue;
      }
      // A face of a flat cell that straddles two coplanar triangles: it is attributed to the
      // triangle that holds its centroid.
      const Vec3 x = m.face_centroids.row(f).transpose();
      int best = -1;
      Vec3 best_w;
      double best_err = kInf;
      for (int v : {a, b, c})
        for (const auto& e : surf->points[surface_id(v)].on) {
          const auto& T = set.corners[e.first];
          const Vec3 n = (T[1] - T[0]).cross(T[2] - T[0]);
          const double n2 = n.squaredNorm();
          const Vec3 w((T[2] - T[1]).cross(x - T[1]).dot(n) / n2,
                       (T[0] - T[2]).cross(x - T[2]).dot(n) / n2, 0.0);
          const Vec3 wz(w(0), w(1), 1.0 - w(0) - w(1));
          const double err = std::max(0.0, -wz.minCoeff()) + std::abs((x - T[0]).dot(n)) / n2;
          if (err < best_err) best_err = err, best = e.first, best_w = wz;
        }
      if (best >= 0 && best_err < 1e-6) {
        m.face_kind[f] = FaceKind::Solid;
        m.face_body(f) = solids[set.tri_body[best]].body;
        m.face_triangle(f) = set.local(best);
        m.face_bary.row(f) = best_w.cwiseMax(0.0).transpose() / best_w.cwiseMax(0.0).sum();
        ++report.straddling_faces;
        continue;
      }
    }
    int side = -1;
    for (int s = 0; s < 6 && side < 0; ++s) {
      const int ax = s / 2;
      const double plane = (s % 2) ? domain.hi(ax) : domain.lo(ax);
      if (pts[a](ax) == plane && pts[b](ax) == plane && pts[c](ax) == plane) side = s;
    }
    if (side < 0) {
      const Vec3 x = m.face_centroids.row(f).transpose();
      throw MeshError(fmt::format(
          "remesh: boundary face {} at ({:.6g}, {:.6g}, {:.6g}) is neither on the domain box nor "
          "on a solid triangle (a leak in the fluid mesh): report this with the scene",
          f, x.x(), x.y(), x.z()));
    }
    m.face_kind[f] = domain.default_kind;
    const Vec3 x = m.face_centroids.row(f).transpose();
    Vec2 uv;
    int j = 0;
    for (int ax = 0; ax < 3; ++ax)
      if (ax != side / 2) uv(j++) = x(ax);
    for (std::size_t p = 0; p < domain.patches.size(); ++p) {
      const DomainPatch& dp = domain.patches[p];
      if (dp.side == side && (uv.array() >= dp.lo.array() - 1e-9).all() &&
          (uv.array() <= dp.hi.array() + 1e-9).all()) {
        m.face_kind[f] = dp.kind;
        m.face_patch(f) = static_cast<int>(p);
      }
    }
  }
  report.seconds_build = now_seconds() - t0;
  report.seconds_total = now_seconds() - t_start;
  if (report_out) *report_out = report;
  return m;
}

MatX4i delaunay_tets(const MatX3& points) {
  std::vector<Vec3> p(points.rows());
  for (Index i = 0; i < points.rows(); ++i) p[i] = points.row(i).transpose();
  return delaunay_of(p);
}

}  // namespace tetfsi::mesh
