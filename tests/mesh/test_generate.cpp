/// Tests of the body generators of mesh/generate.cpp beyond make_box (test_volume_mesh.cpp):
/// spherical shells, balls, hollow boxes and tubes. For each: every tet positive, conforming
/// (every face in one or two tets), the boundary a given number of closed, consistently
/// oriented surfaces (spheres, Euler characteristic 2 each; the tube's one torus, 0), the
/// tet volume equal to the volume its boundary
/// encloses to round-off and to the analytic volume within a stated bound, and bad
/// parameters rejected with messages that say what to change.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "mesh/quality.hpp"
#include "mesh/volume_mesh.hpp"
#include "tests/test_util.hpp"

using tetfsi::test::message_of;
using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

/// ∫ x·n dA / 3 over a closed oriented surface = the volume it encloses (divergence theorem;
/// an inward-oriented component subtracts its volume).
double enclosed_volume(const MatX3& x, const MatX3i& tri) {
  double v6 = 0.0;
  for (Index f = 0; f < tri.rows(); ++f) {
    const Vec3 a = x.row(tri(f, 0)), b = x.row(tri(f, 1)), c = x.row(tri(f, 2));
    v6 += a.dot(b.cross(c));
  }
  return v6 / 6.0;
}

struct Topology {
  Index interior_faces = 0, boundary_faces = 0;
  Index overfull_faces = 0;    ///< faces in three or more tets (must be 0)
  Index bad_edges = 0;         ///< boundary edges not matched once by their reverse (must be 0)
  std::vector<Index> euler;    ///< V − E + F of each connected boundary component
  std::vector<int> component;  ///< #B component of each boundary triangle
};

/// Face counts of the tets and the connected components of boundary_triangles(m).
Topology topology(const VolumeMesh& m, const MatX3i& boundary) {
  Topology out;
  std::map<std::array<int, 3>, int> faces;
  constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (Index t = 0; t < m.num_tets(); ++t) {
    for (const auto& f : kFace) {
      std::array<int, 3> key = {m.tets(t, f[0]), m.tets(t, f[1]), m.tets(t, f[2])};
      std::sort(key.begin(), key.end());
      ++faces[key];
    }
  }
  for (const auto& [key, count] : faces) {
    out.interior_faces += count == 2;
    out.boundary_faces += count == 1;
    out.overfull_faces += count > 2;
  }
  // Directed edges: each must appear once, and its reverse once (closed and consistently
  // oriented). Components by union-find over shared edges.
  std::map<std::pair<int, int>, Index> directed;
  for (Index f = 0; f < boundary.rows(); ++f)
    for (int e = 0; e < 3; ++e) ++directed[{boundary(f, e), boundary(f, (e + 1) % 3)}];
  std::vector<Index> parent(boundary.rows());
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](Index i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::map<std::pair<int, int>, Index> edge_owner;
  for (Index f = 0; f < boundary.rows(); ++f) {
    for (int e = 0; e < 3; ++e) {
      const int a = boundary(f, e), b = boundary(f, (e + 1) % 3);
      if (directed[{a, b}] != 1 || directed.count({b, a}) == 0 || directed[{b, a}] != 1)
        ++out.bad_edges;
      const auto key = std::minmax(a, b);
      const auto it = edge_owner.find(key);
      if (it == edge_owner.end())
        edge_owner[key] = f;
      else
        parent[find(f)] = find(it->second);
    }
  }
  std::map<Index, int> id;
  out.component.resize(boundary.rows());
  for (Index f = 0; f < boundary.rows(); ++f) {
    const Index r = find(f);
    if (!id.count(r)) id[r] = static_cast<int>(id.size());
    out.component[f] = id[r];
  }
  out.euler.assign(id.size(), 0);
  std::vector<std::set<int>> verts(id.size());
  std::vector<std::set<std::pair<int, int>>> edges(id.size());
  for (Index f = 0; f < boundary.rows(); ++f) {
    const int c = out.component[f];
    for (int e = 0; e < 3; ++e) {
      verts[c].insert(boundary(f, e));
      edges[c].insert(std::minmax(boundary(f, e), boundary(f, (e + 1) % 3)));
    }
    out.euler[c] += 1;  // F
  }
  for (std::size_t c = 0; c < id.size(); ++c)
    out.euler[c] += static_cast<Index>(verts[c].size()) - static_cast<Index>(edges[c].size());
  return out;
}

/// The common checks: positive tets, conforming, `components` closed surfaces of Euler
/// characteristic `euler` each (2: spheres), tet volume = enclosed volume to round-off.
/// Returns the boundary triangles.
MatX3i check_body(const VolumeMesh& m, std::size_t components, Index euler = 2) {
  CHECK_NOTHROW(validate_volume_mesh(m, "generated"));
  Index nonpositive = 0;
  for (Index t = 0; t < m.num_tets(); ++t) nonpositive += tet_volume(m, t) <= 0;
  CHECK(nonpositive == 0);
  const MatX3i boundary = boundary_triangles(m);
  const Topology top = topology(m, boundary);
  CHECK(top.overfull_faces == 0);
  CHECK(top.boundary_faces == boundary.rows());
  CHECK(4 * m.num_tets() == 2 * top.interior_faces + top.boundary_faces);
  CHECK(top.bad_edges == 0);
  REQUIRE(top.euler.size() == components);
  for (Index chi : top.euler) CHECK(chi == euler);  // 2: each component a topological sphere
  // Σ tet volumes vs the boundary's enclosed volume: both sums of ~1e4 terms of one sign
  // (tets) or cancelling (boundary cones), rounding ~1e-15 relative each; 1e-12 is room.
  const double v = total_volume(m);
  CHECK(std::abs(v - enclosed_volume(m.vertices, boundary)) <= 1e-12 * v);
  return boundary;
}

/// Volume of the polyhedral unit icosphere of `s` subdivisions.
double unit_icosphere_volume(int s) {
  const SurfaceMesh u = make_icosphere(Vec3::Zero(), 1.0, s);
  return enclosed_volume(u.vertices, u.triangles);
}

}  // namespace

TEST_CASE("make_spherical_shell: conforming prisms, two spheres, inner normals to the centre") {
  const Vec3 c(0.3, -0.2, 1.1);
  const double ri = 0.4, ro = 0.5;
  for (int s = 0; s <= 3; ++s) {
    for (int layers : {1, 3}) {
      CAPTURE(s);
      CAPTURE(layers);
      const VolumeMesh m = make_spherical_shell(c, ri, ro, s, layers);
      const Index nf = 20 * (1 << (2 * s)), nv = 10 * (1 << (2 * s)) + 2;
      CHECK(m.num_tets() == 3 * layers * nf);
      CHECK(m.num_vertices() == (layers + 1) * nv);
      const MatX3i boundary = check_body(m, 2);
      CHECK(boundary.rows() == 2 * nf);
      // Each boundary triangle lies on one sphere; its normal points away from the centre
      // on the outer one, toward it on the inner one (out of the solid into the cavity).
      Index inner = 0, outer = 0, wrong = 0;
      for (Index f = 0; f < boundary.rows(); ++f) {
        const Vec3 a = m.vertices.row(boundary(f, 0)), b = m.vertices.row(boundary(f, 1)),
                   d = m.vertices.row(boundary(f, 2));
        const Vec3 n = (b - a).cross(d - a).normalized(), mid = (a + b + d) / 3.0 - c;
        const double cosine = n.dot(mid.normalized());
        // Flat triangles of an inscribed icosphere: |cos| ≥ 0.79 even for s = 0.
        if ((a - c).norm() < 0.5 * (ri + ro)) {
          ++inner;
          wrong += cosine > -0.75;
        } else {
          ++outer;
          wrong += cosine < 0.75;
        }
      }
      CHECK(inner == nf);
      CHECK(outer == nf);
      CHECK(wrong == 0);
      // Polyhedral volume (R_o³ − R_i³) × the unit icosphere's, to round-off.
      const double v = total_volume(m), vi = unit_icosphere_volume(s);
      CHECK(v == doctest::Approx((ro * ro * ro - ri * ri * ri) * vi).epsilon(1e-12));
      if (s == 2) {
        // Against the analytic shell (4/3)π(R_o³ − R_i³): inscribed, so smaller, by the
        // icosphere's deficit, 1 − V_ico / V_ball = 3.3 % at s = 2 (0.84 % at s = 3; second
        // order, about 4x per subdivision as test_remesh.cpp checks).
        const double exact = 4.0 / 3.0 * M_PI * (ro * ro * ro - ri * ri * ri);
        const double deficit = (exact - v) / exact;
        MESSAGE("shell s = 2 volume deficit " << deficit);
        CHECK(deficit > 0.0);
        CHECK(deficit < 0.035);
      }
      // Quality where the layer is about as thick as the edges (s = 2: edges ≈ 0.13 at
      // r = 0.5, layer 0.1): 35.6°. Thinner layers are as flat as asked for (s = 0, 3
      // layers: 3.4°).
      if (s == 2 && layers == 1) {
        const TetQuality q = tet_quality(m.vertices, m.tets);
        MESSAGE("shell min dihedral " << q.min_dihedral_deg.minCoeff());
        CHECK(q.min_dihedral_deg.minCoeff() > 30.0);
      }
    }
  }
}

TEST_CASE("make_ball: conforming, one sphere, volume bounds, min dihedral") {
  const Vec3 c(-1.0, 0.5, 2.0);
  const double r = 0.3;
  double previous_deficit = 1.0;
  for (int s = 0; s <= 4; ++s) {
    CAPTURE(s);
    const VolumeMesh m = make_ball(c, r, s);
    const MatX3i boundary = check_body(m, 1);
    CHECK(boundary.rows() == 20 * (1 << (2 * s)));  // the icosphere of `s` subdivisions
    // s = 2: 20 core cones; level 1: 2 layers (7 · 20 + 3 · 80); level 2: 3 (7 · 80 + 2 · 3 · 320).
    if (s == 2) CHECK(m.num_tets() == 20 + 140 + 240 + 560 + 1920);
    // Every boundary vertex on the sphere (to round-off).
    double off_sphere = 0.0, min_plane = r;
    for (Index f = 0; f < boundary.rows(); ++f) {
      const Vec3 a = m.vertices.row(boundary(f, 0)), b = m.vertices.row(boundary(f, 1)),
                 d = m.vertices.row(boundary(f, 2));
      for (const Vec3& p : {a, b, d})
        off_sphere = std::max(off_sphere, std::abs((p - c).norm() - r));
      // Distance from the centre to the triangle's plane, positive: the triangle faces away
      // from the centre (the boundary is star-shaped about it).
      min_plane = std::min(min_plane, (b - a).cross(d - a).normalized().dot(a - c));
    }
    CHECK(off_sphere <= 1e-14);
    CHECK(min_plane > 0.0);
    // Inscribed (vertices on the sphere, faces seen from the centre): the ball of radius
    // min_plane lies inside and the polyhedron inside the sphere, so
    // (4/3)π min_plane³ ≤ V ≤ (4/3)π r³: a bound from the mesh, no fitted tolerance.
    const double v = total_volume(m), exact = 4.0 / 3.0 * M_PI * r * r * r;
    CHECK(v <= exact);
    CHECK(v >= 4.0 / 3.0 * M_PI * std::pow(min_plane, 3) * (1 - 1e-12));
    const double deficit = (exact - v) / exact;
    MESSAGE("ball s = " << s << ": volume deficit " << deficit << ", min plane distance / r "
                        << min_plane / r);
    if (s > 0) CHECK(deficit < previous_deficit / 3.0);  // second order: about 4x per level
    previous_deficit = deficit;
    // The boundary is the icosphere: its inscribed deficit, 3.4 % at s = 2 (edges ≈ r / 4).
    if (s == 2) CHECK(deficit < 0.035);
    // Quality: 29.5° at every s ≥ 1 (the transition layers repeat the same shapes; the core's
    // 20 cones are nearly regular, 69°); 25° leaves room for round-off and small changes.
    const TetQuality q = tet_quality(m.vertices, m.tets);
    MESSAGE("ball s = " << s << ": min dihedral " << q.min_dihedral_deg.minCoeff()
                        << ", max dihedral " << q.max_dihedral_deg.maxCoeff());
    CHECK(q.min_dihedral_deg.minCoeff() > 25.0);
    CHECK(q.max_dihedral_deg.maxCoeff() < 145.0);
  }
}

TEST_CASE("make_hollow_box: walls around one box cavity, exact volume, cavity normals inward") {
  const Vec3 lo(-0.5, 0.0, 1.0), hi(0.7, 0.6, 1.4);
  const double t = 0.1;
  const Vec3i cells(5, 4, 2);  // cavity 1.0 × 0.4 × 0.2: cells 0.2, 0.1, 0.1
  const VolumeMesh m = make_hollow_box(lo, hi, t, cells);
  // Walls: round(0.1 / 0.2) = 1 (half rounds up), round(0.1 / 0.1) = 1 cell; grid 7 × 6 × 4.
  CHECK(m.num_tets() == 6 * (7 * 6 * 4 - 5 * 4 * 2));
  CHECK(m.num_vertices() == 8 * 7 * 5 - 4 * 3 * 1);  // the cavity's inner grid points removed
  const MatX3i boundary = check_body(m, 2);
  const double exact = (hi - lo).prod() - (hi - lo - Vec3::Constant(2 * t)).prod();
  CHECK(std::abs(total_volume(m) - exact) <= 1e-12 * exact);
  // Cavity faces: normals into the cavity (toward its centre); outer faces: outward.
  const Vec3 mid = 0.5 * (lo + hi);
  Index cavity = 0, wrong = 0;
  for (Index f = 0; f < boundary.rows(); ++f) {
    const Vec3 a = m.vertices.row(boundary(f, 0)), b = m.vertices.row(boundary(f, 1)),
               d = m.vertices.row(boundary(f, 2));
    const Vec3 n = (b - a).cross(d - a), x = (a + b + d) / 3.0;
    const bool on_outer =
        ((x - lo).cwiseAbs().minCoeff() < 1e-12) || ((hi - x).cwiseAbs().minCoeff() < 1e-12);
    cavity += !on_outer;
    wrong += on_outer ? n.dot(x - mid) <= 0 : n.dot(x - mid) >= 0;
  }
  CHECK(cavity == 2 * 2 * (5 * 4 + 4 * 2 + 5 * 2));  // 2 triangles per cavity-face cell
  CHECK(wrong == 0);
  // Kuhn tets of the tensor grid: no tet flatter than its cell's aspect allows.
  CHECK(tet_quality(m.vertices, m.tets).min_dihedral_deg.minCoeff() > 20.0);

  // Thick walls get more cells: 0.3 / 0.1 = 3 per wall in each axis.
  const VolumeMesh thick = make_hollow_box(Vec3::Zero(), Vec3(0.8, 0.8, 0.8), 0.3, Vec3i(2, 2, 2));
  CHECK(thick.num_tets() == 6 * (8 * 8 * 8 - 2 * 2 * 2));
  check_body(thick, 2);
  CHECK(std::abs(total_volume(thick) - (0.512 - 0.008)) <= 1e-12);
}

TEST_CASE("make_tube: conforming across the seam, one torus, exact polygonal volume") {
  struct Case {
    Vec3 centre;
    int axis;
    double ri, ro, length;
    int nr, nt, ns;
  };
  const std::vector<Case> cases = {
      {Vec3(0.3, -0.2, 1.1), 2, 0.08, 0.1, 0.8, 2, 24, 16},  // the typical size
      {Vec3(0.3, -0.2, 1.1), 0, 0.08, 0.1, 0.8, 2, 24, 16},
      {Vec3(-1.0, 0.5, 0.0), 1, 0.2, 0.5, 0.3, 3, 7, 2},  // odd sector count, thick wall
      {Vec3::Zero(), 2, 0.5, 1.0, 1.0, 1, 6, 1}};         // the coarsest allowed
  for (const Case& q : cases) {
    CAPTURE(q.axis);
    CAPTURE(q.nt);
    const VolumeMesh m = make_tube(q.centre, q.axis, q.ri, q.ro, q.length, q.nr, q.nt, q.ns);
    CHECK(m.num_tets() == 6 * q.nr * q.nt * q.ns);
    CHECK(m.num_vertices() == (q.nr + 1) * q.nt * (q.ns + 1));
    // One closed, outward-oriented torus (V − E + F = 0). Had the seam θ = 2π ≡ 0 not
    // conformed, its faces would be boundary faces and the counts below would not add up.
    const MatX3i boundary = check_body(m, 1, 0);
    CHECK(boundary.rows() == 4 * q.nt * (q.ns + q.nr));
    // Vertex (i, j, k) where the header says.
    const Vec3 w = Vec3::Unit(q.axis), u = Vec3::Unit((q.axis + 1) % 3);
    const auto at = [&](int i, int j, int k) {
      return Vec3(m.vertices.row(i + (q.nr + 1) * (j + q.nt * k)).transpose());
    };
    CHECK((at(0, 0, 0) - (q.centre + q.ri * u - 0.5 * q.length * w)).norm() <= 1e-15);
    CHECK((at(q.nr, 0, q.ns) - (q.centre + q.ro * u + 0.5 * q.length * w)).norm() <= 1e-15);
    // Each boundary triangle on one of the four parts, normal out of the solid: away from the
    // axis on the outer prism, toward it on the inner (into the bore), ∓axis on the ends.
    const auto radial = [&](const Vec3& x) {
      const Vec3 d = x - q.centre;
      return Vec3(d - d.dot(w) * w);
    };
    Index outer = 0, inner = 0, bottom = 0, top = 0, other = 0, wrong = 0;
    for (Index f = 0; f < boundary.rows(); ++f) {
      const Vec3 a = m.vertices.row(boundary(f, 0)), b = m.vertices.row(boundary(f, 1)),
                 d = m.vertices.row(boundary(f, 2));
      const Vec3 n = (b - a).cross(d - a).normalized(), x = (a + b + d) / 3.0;
      const auto all = [&](auto&& pred) { return pred(a) && pred(b) && pred(d); };
      const auto at_r = [&](double r) {
        return all([&](const Vec3& p) { return std::abs(radial(p).norm() - r) <= 1e-12; });
      };
      const auto at_s = [&](double s) {
        return all([&](const Vec3& p) { return std::abs((p - q.centre).dot(w) - s) <= 1e-12; });
      };
      // A side triangle's centroid is at most half a sector off its face's mid-angle:
      // cos ≥ cos(π/6) ≈ 0.87 for n ≥ 6.
      const double cosine = n.dot(radial(x).normalized());
      if (at_r(q.ro)) {
        ++outer;
        wrong += cosine < 0.85;
      } else if (at_r(q.ri)) {
        ++inner;
        wrong += cosine > -0.85;
      } else if (at_s(-0.5 * q.length)) {
        ++bottom;
        wrong += std::abs(n.dot(w) + 1.0) > 1e-12;
      } else if (at_s(0.5 * q.length)) {
        ++top;
        wrong += std::abs(n.dot(w) - 1.0) > 1e-12;
      } else {
        ++other;
      }
    }
    CHECK(outer == 2 * q.nt * q.ns);
    CHECK(inner == 2 * q.nt * q.ns);
    CHECK(bottom == 2 * q.nr * q.nt);
    CHECK(top == 2 * q.nr * q.nt);
    CHECK(other == 0);
    CHECK(wrong == 0);
    // The n-gon annulus × length, to round-off.
    const double n = q.nt;
    const double exact =
        0.5 * n * std::sin(2.0 * M_PI / n) * (q.ro * q.ro - q.ri * q.ri) * q.length;
    CHECK(std::abs(total_volume(m) - exact) <= 1e-12 * exact);
  }

  // Quality of the typical size: cells 0.01 (radial) × 0.021..0.026 (around) × 0.05 (axial),
  // Kuhn tets as flat as that 1 : 2.5 : 5 aspect makes them: min dihedral 11.2°, max 97.5°
  // (the mesh is deterministic; the bounds leave a little room).
  const VolumeMesh m = make_tube(Vec3::Zero(), 2, 0.08, 0.1, 0.8, 2, 24, 16);
  const TetQuality q = tet_quality(m.vertices, m.tets);
  MESSAGE("tube 2 x 24 x 16 (R 0.08 / 0.1, L 0.8): min dihedral "
          << q.min_dihedral_deg.minCoeff() << ", max dihedral " << q.max_dihedral_deg.maxCoeff());
  CHECK(q.min_dihedral_deg.minCoeff() > 11.0);
  CHECK(q.max_dihedral_deg.maxCoeff() < 98.0);
}

TEST_CASE("make_bowl: one closed surface, rim on the plane, volume of the half shell") {
  const Vec3 c(0.3, -0.2, 1.1);
  const double ri = 0.08, ro = 0.1;
  for (int cells : {2, 8, 16}) {
    for (int layers : {1, 2}) {
      CAPTURE(cells);
      CAPTURE(layers);
      const VolumeMesh m = make_bowl(c, ri, ro, cells, layers);
      CHECK(m.num_tets() == 18 * layers * cells * cells);
      const MatX3i boundary = check_body(m, 1);  // one topological sphere: inside, rim, outside
      // Every vertex lies on a layer's sphere at or below the rim's plane; the rim's vertices
      // (4 cells around, layers + 1 radii) lie on the plane exactly.
      Index on_rim = 0, above = 0, off_sphere = 0;
      for (Index v = 0; v < m.num_vertices(); ++v) {
        const Vec3 d = m.vertices.row(v).transpose() - c;
        above += d.z() > 0.0;
        on_rim += d.z() == 0.0;
        const double layer = (d.norm() - ri) / (ro - ri) * layers;
        off_sphere += std::abs(layer - std::round(layer)) > 1e-12;
      }
      CHECK(above == 0);
      CHECK(off_sphere == 0);
      CHECK(on_rim == 4 * cells * (layers + 1));
      // Boundary triangles: on the rim (normal +z), the outside (normal away from the centre)
      // or the inside (toward it).
      Index rim = 0, wrong = 0;
      for (Index f = 0; f < boundary.rows(); ++f) {
        const Vec3 a = m.vertices.row(boundary(f, 0)), b = m.vertices.row(boundary(f, 1)),
                   d = m.vertices.row(boundary(f, 2));
        const Vec3 n = (b - a).cross(d - a).normalized(), mid = (a + b + d) / 3.0 - c;
        if (a.z() == c.z() && b.z() == c.z() && d.z() == c.z()) {
          ++rim;
          wrong += n.z() < 1.0 - 1e-12;
        } else if ((a - c).norm() < 0.5 * (ri + ro)) {
          wrong += n.dot(mid.normalized()) > -0.5;
        } else {
          wrong += n.dot(mid.normalized()) < 0.5;
        }
      }
      CHECK(rim == 2 * 4 * cells * layers);
      CHECK(wrong == 0);
      // Inscribed in the half shell (2/3)π(R_o³ − R_i³): below it, by a deficit that falls
      // about 4x per doubling of cells (second order); 16 cells: under 1 %.
      const double exact = 2.0 / 3.0 * M_PI * (ro * ro * ro - ri * ri * ri);
      const double deficit = (exact - total_volume(m)) / exact;
      MESSAGE("bowl cells " << cells << " volume deficit " << deficit);
      CHECK(deficit > 0.0);
      if (cells == 16) CHECK(deficit < 0.01);
      if (cells == 8 && layers == 2) {
        const TetQuality q = tet_quality(m.vertices, m.tets);
        MESSAGE("bowl min dihedral " << q.min_dihedral_deg.minCoeff());
        CHECK(q.min_dihedral_deg.minCoeff() > 15.0);
      }
    }
  }
  CHECK(message_of<InputError>([&] {
          make_bowl(c, 0.1, 0.1, 8, 1);
        }).find("make_bowl: need 0 < inner_radius < outer_radius") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_bowl(c, 0.05, 0.1, 7, 1);
        }).find("cells (from the bottom to the rim) must be even and in 2..512, got 7") !=
        std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_bowl(c, 0.05, 0.1, 8, 0);
        }).find("make_bowl: layers must be 1..10000, got 0") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_bowl(c, std::nan(""), 0.1, 8, 1);
        }).find("must be finite") != std::string::npos);
}

TEST_CASE("generators: bad parameters are InputErrors that say what to change") {
  const Vec3 c = Vec3::Zero();
  const double nan = std::nan("");
  CHECK(message_of<InputError>([&] { make_spherical_shell(c, 0.5, 0.5, 2, 1); })
            .find("need 0 < inner_radius < outer_radius, got inner_radius 0.5 and outer_radius "
                  "0.5") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_spherical_shell(c, 0.6, 0.5, 2, 1);
        }).find("inner_radius < outer_radius") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_spherical_shell(c, 0.0, 0.5, 2, 1);
        }).find("0 < inner_radius") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_spherical_shell(c, nan, 0.5, 2, 1);
        }).find("must be finite") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_spherical_shell(c, 0.4, 0.5, 2, 0);
        }).find("layers must be 1..10000, got 0") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_spherical_shell(c, 0.4, 0.5, 8, 1);
        }).find("subdivisions must be 0..7, got 8") != std::string::npos);
  CHECK(message_of<InputError>([&] { make_ball(c, -1.0, 2); }).find("radius > 0") !=
        std::string::npos);
  CHECK(message_of<InputError>([&] { make_ball(Vec3(nan, 0, 0), 1.0, 2); }).find("finite") !=
        std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_ball(c, 1.0, 7);
        }).find("subdivisions must be 0..6, got 7") != std::string::npos);
  const Vec3 lo = Vec3::Zero(), hi(1, 1, 0.5);
  CHECK(message_of<InputError>([&] {
          make_hollow_box(lo, hi, 0.25, Vec3i(2, 2, 2));
        }).find("wall thickness 0.25 leaves no cavity in z") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_hollow_box(lo, hi, 0.0, Vec3i(2, 2, 2));
        }).find("wall thickness must be > 0") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_hollow_box(lo, hi, nan, Vec3i(2, 2, 2));
        }).find("must be finite") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_hollow_box(hi, lo, 0.1, Vec3i(2, 2, 2));
        }).find("need lo < hi") != std::string::npos);
  CHECK(message_of<InputError>([&] {
          make_hollow_box(lo, hi, 0.1, Vec3i(2, 0, 2));
        }).find("at least one cavity cell per axis") != std::string::npos);
  const auto tube_error = [&](auto&& make) { return message_of<InputError>(make); };
  CHECK(tube_error([&] { make_tube(c, 2, 0.1, 0.1, 1.0, 1, 12, 4); })
            .find("make_tube: need 0 < inner_radius < outer_radius, got inner_radius 0.1 and "
                  "outer_radius 0.1") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.2, 0.1, 1.0, 1, 12, 4);
        }).find("inner_radius < outer_radius") != std::string::npos);
  CHECK(tube_error([&] { make_tube(c, 2, 0.0, 0.1, 1.0, 1, 12, 4); }).find("0 < inner_radius") !=
        std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.05, 0.1, 0.0, 1, 12, 4);
        }).find("make_tube: length must be > 0, got 0") != std::string::npos);
  CHECK(tube_error([&] { make_tube(c, 2, 0.05, nan, 1.0, 1, 12, 4); }).find("must be finite") !=
        std::string::npos);
  CHECK(tube_error([&] {
          make_tube(Vec3(0, nan, 0), 2, 0.05, 0.1, 1.0, 1, 12, 4);
        }).find("must be finite") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 3, 0.05, 0.1, 1.0, 1, 12, 4);
        }).find("make_tube: axis must be 0, 1 or 2 (x, y, z), got 3") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, -1, 0.05, 0.1, 1.0, 1, 12, 4);
        }).find("axis must be 0, 1 or 2") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.05, 0.1, 1.0, 1, 5, 4);
        }).find("around_cells must be >= 6") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.05, 0.1, 1.0, 0, 12, 4);
        }).find("radial_cells must be >= 1") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.05, 0.1, 1.0, 1, 12, 0);
        }).find("axial_cells must be >= 1") != std::string::npos);
  CHECK(tube_error([&] {
          make_tube(c, 2, 0.05, 0.1, 1.0, 2000, 2000, 2000);
        }).find("more tets than an int index can hold") != std::string::npos);
  for (const std::string& msg : {tube_error([&] { make_tube(c, 2, 0.2, 0.1, 1.0, 1, 12, 4); }),
                                 tube_error([&] { make_tube(c, 2, 0.05, 0.1, 1.0, 1, 5, 4); })})
    CHECK(msg.find('\n') == std::string::npos);  // one line
}
