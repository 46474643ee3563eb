/// @file generate.cpp
/// Structured tet meshes: boxes and hollow boxes (Kuhn/Freudenthal split of a hexahedral
/// grid), balls (a Kuhn cube mapped onto the ball), spherical shells (icosphere prisms), bowls
/// (cube-sphere prisms), tubes
/// (a Kuhn-split (r, θ, axis) grid, periodic in θ).
#include "mesh/generate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::mesh {

namespace {

/// Kuhn split of a unit cube: one tet per permutation (p0, p1, p2) of the axes, the path
/// 0 → e_p0 → e_p0 + e_p1 → (1,1,1) along the cell's main diagonal, as corner bit codes
/// (x | y<<1 | z<<2). Every cell uses the same diagonal direction, so the face diagonals of
/// neighbouring cells agree (conforming). Odd permutations give negative tets; swapping the
/// two middle path vertices fixes them.
std::array<std::array<int, 4>, 6> kuhn_local() {
  constexpr std::array<std::array<int, 3>, 6> kPerms = {
      {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};
  std::array<std::array<int, 4>, 6> local{};
  for (int p = 0; p < 6; ++p) {
    int code = 0;
    local[p][0] = code;
    for (int s = 0; s < 3; ++s) {
      code |= 1 << kPerms[p][s];
      local[p][s + 1] = code;
    }
    if (p >= 3) std::swap(local[p][1], local[p][2]);  // odd permutation
  }
  return local;
}

/// Throws unless a grid of `cells` (each ≥ 1) has fewer tets and vertices than an int holds
/// (checked before anything is allocated).
void check_grid_size(const Vec3i& cells, const char* what) {
  const long long nvx = cells(0) + 1LL, nvy = cells(1) + 1LL, nvz = cells(2) + 1LL;
  const long long num_cells = static_cast<long long>(cells(0)) * cells(1) * cells(2);
  TETFSI_REQUIRE(InputError, 6 * num_cells < (1LL << 31) && nvx * nvy * nvz < (1LL << 31),
                 "{}: {} x {} x {} cells give more tets than an int index can hold; use "
                 "fewer cells",
                 what, cells(0), cells(1), cells(2));
}

/// Kuhn-split tensor grid with grid lines `lines[a]` (increasing) in axis a: vertex (i, j, k)
/// has index i + nx (j + ny k) (n_a = lines[a].size()); the cells (i, j, k) with
/// `keep(i, j, k)` become 6 tets each. Vertices of dropped cells are kept (the caller may
/// remove_unused_vertices). `what` names the generator in errors.
template <class Keep>
VolumeMesh kuhn_grid(const std::array<std::vector<double>, 3>& lines, Keep&& keep,
                     const char* what) {
  const long long nvx = static_cast<long long>(lines[0].size()),
                  nvy = static_cast<long long>(lines[1].size()),
                  nvz = static_cast<long long>(lines[2].size());
  const long long num_cells = (nvx - 1) * (nvy - 1) * (nvz - 1);
  check_grid_size(
      Vec3i(static_cast<int>(nvx - 1), static_cast<int>(nvy - 1), static_cast<int>(nvz - 1)), what);
  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(nvx * nvy * nvz), 3);
  for (long long k = 0; k < nvz; ++k) {
    for (long long j = 0; j < nvy; ++j) {
      for (long long i = 0; i < nvx; ++i) {
        const Index v = static_cast<Index>(i + nvx * (j + nvy * k));
        m.vertices.row(v) << lines[0][i], lines[1][j], lines[2][k];
      }
    }
  }
  const auto local = kuhn_local();
  std::vector<Vec4i> tets;
  tets.reserve(static_cast<std::size_t>(6 * num_cells));
  for (long long k = 0; k + 1 < nvz; ++k) {
    for (long long j = 0; j + 1 < nvy; ++j) {
      for (long long i = 0; i + 1 < nvx; ++i) {
        if (!keep(i, j, k)) continue;
        for (int p = 0; p < 6; ++p) {
          Vec4i t;
          for (int c = 0; c < 4; ++c) {
            const int code = local[p][c];
            const long long ii = i + (code & 1), jj = j + ((code >> 1) & 1),
                            kk = k + ((code >> 2) & 1);
            t(c) = static_cast<Index>(ii + nvx * (jj + nvy * kk));
          }
          tets.push_back(t);
        }
      }
    }
  }
  m.tets.resize(static_cast<Index>(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t) m.tets.row(static_cast<Index>(t)) = tets[t];
  return m;
}

/// `cells` equal steps from a to b; the last line sits exactly on b (no rounding drift).
void append_uniform(std::vector<double>& lines, double a, double b, int cells) {
  const double h = (b - a) / cells;
  for (int i = 0; i <= cells; ++i) {
    if (i == 0 && !lines.empty()) continue;  // shared with the previous segment
    lines.push_back(i == cells ? b : a + i * h);
  }
}

/// Throws unless the centre and radii are finite and 0 < inner_radius < outer_radius; `what`
/// names the generator, `hint` is appended to the second message.
void check_shell_radii(const char* what, const Vec3& centre, double inner_radius,
                       double outer_radius, const char* hint) {
  TETFSI_REQUIRE(InputError,
                 centre.allFinite() && std::isfinite(inner_radius) && std::isfinite(outer_radius),
                 "{}: centre and radii must be finite, got centre ({} {} {}), inner_radius {}, "
                 "outer_radius {}",
                 what, centre.x(), centre.y(), centre.z(), inner_radius, outer_radius);
  TETFSI_REQUIRE(InputError, inner_radius > 0 && inner_radius < outer_radius,
                 "{}: need 0 < inner_radius < outer_radius, got inner_radius {} and outer_radius "
                 "{}{}",
                 what, inner_radius, outer_radius, hint);
}

/// The unit-sphere surface `unit` (vertices on the unit sphere about the origin) extruded
/// radially into `layers` equal layers between the radii about `centre`: vertex v of layer k
/// (k = 0 at inner_radius … layers at outer_radius) has index v + k·#V. Each prism (triangle
/// × layer) is cut into 3 tets by the index order of its triangle's vertices: with v0 < v1 < v2,
/// bottom b_i and top t_i, (b0 b1 b2 t2), (b0 b1 t1 t2), (b0 t0 t1 t2). The quad over edge
/// (vi, vj), i < j, is cut by the diagonal b_i–t_j in both prisms that share it, so
/// neighbours conform; each tet is made positive by swapping its last two vertices.
VolumeMesh extrude_radially(const SurfaceMesh& unit, const Vec3& centre, double inner_radius,
                            double outer_radius, int layers) {
  const long long nv = unit.num_vertices(), nf = unit.num_triangles();
  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(nv * (layers + 1LL)), 3);
  const double dr = (outer_radius - inner_radius) / layers;
  for (int k = 0; k <= layers; ++k) {
    const double r = k == layers ? outer_radius : inner_radius + k * dr;  // exact ends
    for (Index v = 0; v < nv; ++v)
      m.vertices.row(static_cast<Index>(v + nv * k)) =
          centre.transpose() + r * unit.vertices.row(v);
  }
  m.tets.resize(static_cast<Index>(3 * nf * layers), 4);
  Index t = 0;
  for (int k = 0; k < layers; ++k) {
    const Index bottom = static_cast<Index>(nv * k), top = static_cast<Index>(nv * (k + 1));
    for (Index f = 0; f < nf; ++f) {
      std::array<Index, 3> v = {unit.triangles(f, 0), unit.triangles(f, 1), unit.triangles(f, 2)};
      std::sort(v.begin(), v.end());
      const std::array<Vec4i, 3> prism = {
          Vec4i(bottom + v[0], bottom + v[1], bottom + v[2], top + v[2]),
          Vec4i(bottom + v[0], bottom + v[1], top + v[1], top + v[2]),
          Vec4i(bottom + v[0], top + v[0], top + v[1], top + v[2])};
      for (Vec4i tet : prism) {
        const auto x = [&](int c) { return Vec3(m.vertices.row(tet(c)).transpose()); };
        if (signed_volume(x(0), x(1), x(2), x(3)) < 0) std::swap(tet(2), tet(3));
        m.tets.row(t++) = tet.transpose();
      }
    }
  }
  return m;
}

/// The lower half (z ≤ 0) of the unit sphere as an equiangular cube sphere: the lattice
/// points (i, j, k) on the surface of the cube [−m, m]³ with k ≤ 0 (the bottom face and the
/// lower halves of the four sides), mapped to the unit vector along
/// (tan(π i / 4m), tan(π j / 4m), tan(π k / 4m)); each lattice square is cut into two
/// triangles along its shorter diagonal on the sphere. The rim (k = 0) lies on z = 0 exactly.
SurfaceMesh unit_hemisphere(int m) {
  std::map<std::array<int, 3>, Index> index;
  std::vector<Vec3> points;
  const auto vertex = [&](const std::array<int, 3>& p) {
    const auto [it, inserted] = index.try_emplace(p, static_cast<Index>(points.size()));
    if (inserted) {
      Vec3 x;
      for (int a = 0; a < 3; ++a) x(a) = std::tan(0.25 * M_PI * p[a] / m);
      points.push_back(x.normalized());
    }
    return it->second;
  };
  std::vector<Vec3i> triangles;
  const auto quad = [&](const std::array<int, 3>& o, int u, int v) {  // square at o in axes u, v
    std::array<int, 3> a = o, b = o, c = o, d = o;
    b[u] += 1, c[u] += 1, c[v] += 1, d[v] += 1;
    const Index ia = vertex(a), ib = vertex(b), ic = vertex(c), id = vertex(d);
    if ((points[ia] - points[ic]).norm() <= (points[ib] - points[id]).norm())
      triangles.insert(triangles.end(), {Vec3i(ia, ib, ic), Vec3i(ia, ic, id)});
    else
      triangles.insert(triangles.end(), {Vec3i(ia, ib, id), Vec3i(ib, ic, id)});
  };
  for (int i = -m; i < m; ++i)
    for (int j = -m; j < m; ++j) quad({i, j, -m}, 0, 1);  // bottom
  for (int s = -m; s < m; ++s) {
    for (int k = -m; k < 0; ++k) {
      for (const int side : {-m, m}) {
        quad({side, s, k}, 1, 2);  // x = ±m
        quad({s, side, k}, 0, 2);  // y = ±m
      }
    }
  }
  SurfaceMesh unit;
  unit.vertices.resize(static_cast<Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v)
    unit.vertices.row(static_cast<Index>(v)) = points[v].transpose();
  unit.triangles.resize(static_cast<Index>(triangles.size()), 3);
  for (std::size_t f = 0; f < triangles.size(); ++f)
    unit.triangles.row(static_cast<Index>(f)) = triangles[f].transpose();
  return unit;
}

}  // namespace

VolumeMesh make_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells) {
  TETFSI_REQUIRE(InputError, lo.allFinite() && hi.allFinite(),
                 "make_box: corners must be finite, got lo ({} {} {}) and hi ({} {} {})", lo.x(),
                 lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
  for (int a = 0; a < 3; ++a) {
    TETFSI_REQUIRE(InputError, lo(a) < hi(a),
                   "make_box: need lo < hi in every axis, got lo ({} {} {}) and hi ({} {} {}); "
                   "swap or widen the corners",
                   lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
    TETFSI_REQUIRE(InputError, cells(a) >= 1,
                   "make_box: need at least one cell per axis, got cells ({} {} {})", cells(0),
                   cells(1), cells(2));
  }
  check_grid_size(cells, "make_box");
  std::array<std::vector<double>, 3> lines;
  for (int a = 0; a < 3; ++a) append_uniform(lines[a], lo(a), hi(a), cells(a));
  VolumeMesh m = kuhn_grid(
      lines, [](long long, long long, long long) { return true; }, "make_box");
  logger().debug("make_box: {} x {} x {} cells, {} vertices, {} tets", cells(0), cells(1), cells(2),
                 m.num_vertices(), m.num_tets());
  return m;
}

SurfaceMesh make_icosphere(const Vec3& centre, double radius, int subdivisions) {
  TETFSI_REQUIRE(InputError, std::isfinite(radius) && radius > 0 && centre.allFinite(),
                 "make_icosphere: need a finite centre and radius > 0, got radius {}", radius);
  TETFSI_REQUIRE(InputError, subdivisions >= 0 && subdivisions <= 7,
                 "make_icosphere: subdivisions must be 0..7, got {}", subdivisions);
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<Vec3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<Vec3i> g;
    g.reserve(4 * f.size());
    for (const auto& tri : f) {
      const int a = midpoint(tri(0), tri(1)), b = midpoint(tri(1), tri(2)),
                c = midpoint(tri(2), tri(0));
      g.insert(g.end(), {{tri(0), a, c}, {tri(1), b, a}, {tri(2), c, b}, {a, b, c}});
    }
    f = std::move(g);
  }
  SurfaceMesh s;
  s.vertices.resize(static_cast<Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i)
    s.vertices.row(static_cast<Index>(i)) = (centre + radius * v[i]).transpose();
  s.triangles.resize(static_cast<Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i)
    s.triangles.row(static_cast<Index>(i)) = f[i].transpose();
  return s;
}

VolumeMesh make_spherical_shell(const Vec3& centre, double inner_radius, double outer_radius,
                                int subdivisions, int layers) {
  check_shell_radii("make_spherical_shell", centre, inner_radius, outer_radius,
                    "; for a solid ball use make_ball");
  TETFSI_REQUIRE(InputError, subdivisions >= 0 && subdivisions <= 7,
                 "make_spherical_shell: subdivisions must be 0..7, got {}", subdivisions);
  TETFSI_REQUIRE(InputError, layers >= 1 && layers <= 10000,
                 "make_spherical_shell: layers must be 1..10000, got {}", layers);
  const SurfaceMesh unit = make_icosphere(Vec3::Zero(), 1.0, subdivisions);
  const long long nv = unit.num_vertices(), nf = unit.num_triangles();
  TETFSI_REQUIRE(InputError, nv * (layers + 1LL) < (1LL << 31) && 3 * nf * layers < (1LL << 31),
                 "make_spherical_shell: {} layers of {} triangles give more tets than an int "
                 "index can hold; use fewer layers or subdivisions",
                 layers, nf);

  VolumeMesh m = extrude_radially(unit, centre, inner_radius, outer_radius, layers);
  logger().debug("make_spherical_shell: radii {} .. {}, {} layers of {} prisms, {} tets",
                 inner_radius, outer_radius, layers, nf, m.num_tets());
  return m;
}

VolumeMesh make_ball(const Vec3& centre, double radius, int subdivisions) {
  TETFSI_REQUIRE(InputError, centre.allFinite() && std::isfinite(radius) && radius > 0,
                 "make_ball: need a finite centre and radius > 0, got centre ({} {} {}) and "
                 "radius {}",
                 centre.x(), centre.y(), centre.z(), radius);
  TETFSI_REQUIRE(InputError, subdivisions >= 0 && subdivisions <= 6,
                 "make_ball: subdivisions must be 0..6, got {}", subdivisions);
  const int s = subdivisions;
  // Icospheres of every level: level l's vertices are the first 10·4^l + 2 of level s's (the
  // subdivision appends midpoints), and triangle f of level l has children 4f .. 4f+3 at
  // level l+1, the last one (mid01, mid12, mid20).
  std::vector<SurfaceMesh> level;
  for (int l = 0; l <= s; ++l) level.push_back(make_icosphere(Vec3::Zero(), 1.0, l));
  const MatX3& unit = level[s].vertices;

  // Spheres (radius, level): the core icosahedron at R / 2^s (edges ≈ the surface's), then
  // for each level l = 1..s the region [R 2^(l−1−s), R 2^(l−s)], where level-l edges grow from
  // half to all of the surface's, cut into n_l layers with radii in geometric progression
  // (thickness ∝ radius ∝ local edge): n_l = round(kThickness · 2^l) makes a layer about
  // 0.8 × its edge (icosphere edges ≈ 1.05 r / 2^l; thickness ≈ r ln 2 / n_l).
  constexpr double kThickness = 0.6931471805599453 / (1.05 * 0.8);
  std::vector<std::pair<double, int>> spheres = {{std::ldexp(radius, -s), 0}};
  for (int l = 1; l <= s; ++l) {
    const int n = std::max(1, static_cast<int>(std::lround(kThickness * (1 << l))));
    const double a = std::ldexp(radius, l - 1 - s);
    for (int i = 1; i <= n; ++i)
      spheres.emplace_back(l == s && i == n ? radius : a * std::pow(2.0, double(i) / n), l);
  }
  std::vector<Index> offset;  // first vertex of each sphere; vertex 0 is the centre
  Index nv = 1;
  for (const auto& sp : spheres) {
    offset.push_back(nv);
    nv += level[sp.second].num_vertices();
  }
  VolumeMesh m;
  m.vertices.resize(nv, 3);
  m.vertices.row(0) = centre.transpose();
  for (std::size_t k = 0; k < spheres.size(); ++k) {
    for (Index v = 0; v < level[spheres[k].second].num_vertices(); ++v)
      m.vertices.row(offset[k] + v) = centre.transpose() + spheres[k].first * unit.row(v);
  }
  std::vector<Vec4i> tets;
  const auto add = [&](Vec4i t) {
    const auto x = [&](int c) { return Vec3(m.vertices.row(t(c)).transpose()); };
    if (signed_volume(x(0), x(1), x(2), x(3)) < 0) std::swap(t(2), t(3));
    tets.push_back(t);
  };
  for (Index f = 0; f < level[0].num_triangles(); ++f)  // the core: cones to the centre
    add(Vec4i(0, offset[0] + level[0].triangles(f, 0), offset[0] + level[0].triangles(f, 1),
              offset[0] + level[0].triangles(f, 2)));
  for (std::size_t k = 0; k + 1 < spheres.size(); ++k) {
    const Index lo = offset[k], hi = offset[k + 1];
    const int l = spheres[k].second;
    if (spheres[k + 1].second == l) {
      // Prism layer: 3 tets by vertex index order, as make_spherical_shell.
      for (Index f = 0; f < level[l].num_triangles(); ++f) {
        std::array<Index, 3> v = {level[l].triangles(f, 0), level[l].triangles(f, 1),
                                  level[l].triangles(f, 2)};
        std::sort(v.begin(), v.end());
        add(Vec4i(lo + v[0], lo + v[1], lo + v[2], hi + v[2]));
        add(Vec4i(lo + v[0], lo + v[1], hi + v[1], hi + v[2]));
        add(Vec4i(lo + v[0], hi + v[0], hi + v[1], hi + v[2]));
      }
      continue;
    }
    // Transition layer, level l inside → l + 1 outside: over triangle (a, b, c) with outer
    // midpoints (m_ab, m_bc, m_ca), the side over edge (a, b) is cut (a b m_ab), (a a' m_ab),
    // (b m_ab b') whichever prism looks at it (conforming); one tet per corner,
    // (a a' m_ab m_ca), and the octahedron (a b c m_ab m_bc m_ca) left between them cut into
    // 4 around its shortest diagonal.
    for (Index f = 0; f < level[l].num_triangles(); ++f) {
      const Vec3i p = level[l].triangles.row(f).transpose();
      const Vec3i mid = level[l + 1].triangles.row(4 * f + 3).transpose();  // ab, bc, ca
      const std::array<Index, 3> in = {lo + p(0), lo + p(1), lo + p(2)};
      const std::array<Index, 3> out = {hi + p(0), hi + p(1), hi + p(2)};
      const std::array<Index, 3> mm = {hi + mid(0), hi + mid(1), hi + mid(2)};
      for (int c = 0; c < 3; ++c) add(Vec4i(in[c], out[c], mm[c], mm[(c + 2) % 3]));
      // Corner c is opposite midpoint (c + 1) % 3.
      int best = 0;
      double shortest = 1e300;
      for (int c = 0; c < 3; ++c) {
        const double d = (m.vertices.row(in[c]) - m.vertices.row(mm[(c + 1) % 3])).norm();
        if (d < shortest) shortest = d, best = c;
      }
      const Index apex = in[best], opposite = mm[(best + 1) % 3];
      // The ring around the diagonal: in[b+1], m_(b), m_(b+2), in[b+2] (b = best).
      const std::array<Index, 4> ring = {in[(best + 1) % 3], mm[best], mm[(best + 2) % 3],
                                         in[(best + 2) % 3]};
      for (int r = 0; r < 4; ++r) add(Vec4i(apex, opposite, ring[r], ring[(r + 1) % 4]));
    }
  }
  m.tets.resize(static_cast<Index>(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t) m.tets.row(static_cast<Index>(t)) = tets[t];
  logger().debug("make_ball: radius {}, {} spheres, {} vertices, {} tets", radius, spheres.size(),
                 m.num_vertices(), m.num_tets());
  return m;
}

VolumeMesh make_hollow_box(const Vec3& lo, const Vec3& hi, double wall_thickness,
                           const Vec3i& cells) {
  const double t = wall_thickness;
  TETFSI_REQUIRE(InputError, lo.allFinite() && hi.allFinite() && std::isfinite(t),
                 "make_hollow_box: corners and wall thickness must be finite, got lo ({} {} {}), "
                 "hi ({} {} {}), thickness {}",
                 lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z(), t);
  TETFSI_REQUIRE(InputError, t > 0, "make_hollow_box: wall thickness must be > 0, got {}", t);
  std::array<std::vector<double>, 3> lines;
  Vec3i wall_cells;
  for (int a = 0; a < 3; ++a) {
    TETFSI_REQUIRE(InputError, lo(a) < hi(a),
                   "make_hollow_box: need lo < hi in every axis, got lo ({} {} {}) and hi ({} {} "
                   "{}); swap or widen the corners",
                   lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
    TETFSI_REQUIRE(InputError, lo(a) + t < hi(a) - t,
                   "make_hollow_box: wall thickness {} leaves no cavity in {} (the box is {} "
                   "wide there, two walls take {}); use a thinner wall or a larger box",
                   t, "xyz"[a], hi(a) - lo(a), 2 * t);
    TETFSI_REQUIRE(InputError, cells(a) >= 1,
                   "make_hollow_box: need at least one cavity cell per axis, got cells ({} {} {})",
                   cells(0), cells(1), cells(2));
    // Wall cells as close to the cavity's cell size as whole numbers allow (at least one).
    const double h = ((hi(a) - t) - (lo(a) + t)) / cells(a);
    const double w = std::max(1.0, std::round(t / h));
    TETFSI_REQUIRE(InputError, w < 1e6,
                   "make_hollow_box: the walls are {} cavity cells thick in {}; use more cavity "
                   "cells or a thinner wall",
                   w, "xyz"[a]);
    wall_cells(a) = static_cast<int>(w);
  }
  check_grid_size(cells + 2 * wall_cells, "make_hollow_box");
  for (int a = 0; a < 3; ++a) {
    append_uniform(lines[a], lo(a), lo(a) + t, wall_cells(a));
    append_uniform(lines[a], lo(a) + t, hi(a) - t, cells(a));
    append_uniform(lines[a], hi(a) - t, hi(a), wall_cells(a));
  }
  const auto in_cavity = [&](long long i, int a) {
    return i >= wall_cells(a) && i < wall_cells(a) + cells(a);
  };
  VolumeMesh m = kuhn_grid(
      lines,
      [&](long long i, long long j, long long k) {
        return !(in_cavity(i, 0) && in_cavity(j, 1) && in_cavity(k, 2));
      },
      "make_hollow_box");
  remove_unused_vertices(m);
  logger().debug(
      "make_hollow_box: walls {} thick ({} {} {} cells), cavity {} x {} x {} cells, "
      "{} vertices, {} tets",
      t, wall_cells(0), wall_cells(1), wall_cells(2), cells(0), cells(1), cells(2),
      m.num_vertices(), m.num_tets());
  return m;
}

VolumeMesh make_tube(const Vec3& centre, int axis, double inner_radius, double outer_radius,
                     double length, int radial_cells, int around_cells, int axial_cells) {
  TETFSI_REQUIRE(InputError,
                 centre.allFinite() && std::isfinite(inner_radius) && std::isfinite(outer_radius) &&
                     std::isfinite(length),
                 "make_tube: centre, radii and length must be finite, got centre ({} {} {}), "
                 "inner_radius {}, outer_radius {}, length {}",
                 centre.x(), centre.y(), centre.z(), inner_radius, outer_radius, length);
  TETFSI_REQUIRE(InputError, inner_radius > 0 && inner_radius < outer_radius,
                 "make_tube: need 0 < inner_radius < outer_radius, got inner_radius {} and "
                 "outer_radius {}",
                 inner_radius, outer_radius);
  TETFSI_REQUIRE(InputError, length > 0, "make_tube: length must be > 0, got {}", length);
  TETFSI_REQUIRE(InputError, axis >= 0 && axis <= 2,
                 "make_tube: axis must be 0, 1 or 2 (x, y, z), got {}", axis);
  TETFSI_REQUIRE(InputError, around_cells >= 6,
                 "make_tube: around_cells must be >= 6 (sectors around the axis), got {}",
                 around_cells);
  TETFSI_REQUIRE(InputError, radial_cells >= 1,
                 "make_tube: radial_cells must be >= 1 (layers across the wall), got {}",
                 radial_cells);
  TETFSI_REQUIRE(InputError, axial_cells >= 1,
                 "make_tube: axial_cells must be >= 1 (slices along the axis), got {}",
                 axial_cells);
  check_grid_size(Vec3i(radial_cells, around_cells, axial_cells), "make_tube");

  const int nr = radial_cells + 1, nt = around_cells, ns = axial_cells + 1;
  std::vector<double> radii, along;
  append_uniform(radii, inner_radius, outer_radius, radial_cells);
  append_uniform(along, -0.5 * length, 0.5 * length, axial_cells);
  // (u, v, w) = (e_(axis+1), e_(axis+2), e_axis) is right-handed (a cyclic shift of x, y, z),
  // so (r, θ, s) ↦ centre + r (cos θ u + sin θ v) + s w has Jacobian determinant r > 0.
  const int u = (axis + 1) % 3, v = (axis + 2) % 3, w = axis;
  const auto vertex = [&](long long i, long long j, long long k) {
    return static_cast<Index>(i + nr * ((j % nt) + nt * k));  // θ wraps: j = nt is j = 0
  };
  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(static_cast<long long>(nr) * nt * ns), 3);
  for (int k = 0; k < ns; ++k) {
    for (int j = 0; j < nt; ++j) {
      const double theta = 2.0 * M_PI * j / nt;
      const double c = std::cos(theta), sn = std::sin(theta);
      for (int i = 0; i < nr; ++i) {
        Vec3 x = centre;
        x(u) += radii[i] * c;
        x(v) += radii[i] * sn;
        x(w) += along[k];
        m.vertices.row(vertex(i, j, k)) = x.transpose();
      }
    }
  }
  // Kuhn split in index space (positive there; the cell's corners map to a prism over a
  // trapezoid, convex as a sector spans 2π / n ≤ 60° < 180°, where every corner triangle
  // keeps its index-space orientation, so the tets stay positive). Index j + 1 of the last
  // sector is taken mod nt: every cell is split the same way, so the seam's faces are cut
  // alike from both sides.
  const auto local = kuhn_local();
  m.tets.resize(static_cast<Index>(6LL * radial_cells * around_cells * axial_cells), 4);
  Index t = 0;
  for (long long k = 0; k < axial_cells; ++k) {
    for (long long j = 0; j < around_cells; ++j) {
      for (long long i = 0; i < radial_cells; ++i) {
        for (int p = 0; p < 6; ++p) {
          for (int c = 0; c < 4; ++c) {
            const int code = local[p][c];
            m.tets(t, c) = vertex(i + (code & 1), j + ((code >> 1) & 1), k + ((code >> 2) & 1));
          }
          ++t;
        }
      }
    }
  }
  logger().debug(
      "make_tube: radii {} .. {}, length {} along {}, {} x {} x {} cells, {} vertices, "
      "{} tets",
      inner_radius, outer_radius, length, "xyz"[axis], radial_cells, around_cells, axial_cells,
      m.num_vertices(), m.num_tets());
  return m;
}

VolumeMesh make_bowl(const Vec3& centre, double inner_radius, double outer_radius, int cells,
                     int layers) {
  check_shell_radii("make_bowl", centre, inner_radius, outer_radius, "");
  TETFSI_REQUIRE(InputError, cells >= 2 && cells <= 512 && cells % 2 == 0,
                 "make_bowl: cells (from the bottom to the rim) must be even and in 2..512, got {}",
                 cells);
  TETFSI_REQUIRE(InputError, layers >= 1 && layers <= 10000,
                 "make_bowl: layers must be 1..10000, got {}", layers);
  const SurfaceMesh unit = unit_hemisphere(cells / 2);
  TETFSI_REQUIRE(InputError,
                 unit.num_vertices() * (layers + 1LL) < (1LL << 31) &&
                     3LL * unit.num_triangles() * layers < (1LL << 31),
                 "make_bowl: {} layers of {} triangles give more tets than an int index can "
                 "hold; use fewer layers or cells",
                 layers, unit.num_triangles());
  VolumeMesh m = extrude_radially(unit, centre, inner_radius, outer_radius, layers);
  logger().debug("make_bowl: radii {} .. {}, {} cells to the rim, {} layers, {} tets", inner_radius,
                 outer_radius, cells, layers, m.num_tets());
  return m;
}

}  // namespace tetfsi::mesh
