/// @file remesh_surface.cpp
/// The solid surfaces of the remesher (remesh_stages.hpp): RefinedSurface, its Rivara
/// longest-edge bisection, and refine_surface (size, then Gabriel), used by stages 1–2 and 4.
#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "mesh/remesh_stages.hpp"

namespace tetfsi::mesh::detail {

namespace {

/// A solid sub-triangle whose longest edge exceeds this multiple of the surface size is split.
constexpr double kSurfaceEdgeFactor = 1.5;
/// Smallest circumradius, as a fraction of the surface size, that Gabriel refinement splits.
constexpr double kGabrielFloor = 0.1;

}  // namespace

Vec3 triangle_circumcentre(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, n = ab.cross(ac);
  return a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) /
                 (2.0 * n.squaredNorm());
}

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

RefinedSurface::RefinedSurface(const SolidSet& set) : m_set(set) {
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

std::pair<int, int> RefinedSurface::longest_edge(const SubTri& s, double* len) const {
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

int RefinedSurface::split_edge(int a, int b, std::vector<int>* new_subs, double t) {
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

int RefinedSurface::refine_subs(const std::vector<int>& list, std::vector<int>* new_subs,
                                double at) {
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

int RefinedSurface::add_sub(const SubTri& st) {
  const int id = static_cast<int>(subs.size());
  subs.push_back(st);
  if (static_cast<std::size_t>(st.tri) >= m_by_tri.size()) m_by_tri.resize(st.tri + 1);
  m_by_tri[st.tri].push_back(id);  // ids grow: the list stays in order
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

void RefinedSurface::remove_sub(int s) {
  subs[s].alive = false;
  auto& of = m_by_tri[subs[s].tri];
  of.erase(std::find(of.begin(), of.end(), s));
  for (int k = 0; k < 3; ++k) {
    auto it = m_edges.find(edge_key(subs[s].v[k], subs[s].v[(k + 1) % 3]));
    for (int& e : it->second)
      if (e == s) e = -1;
    if (it->second[0] < 0 && it->second[1] < 0) m_edges.erase(it);
  }
}

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

}  // namespace tetfsi::mesh::detail
