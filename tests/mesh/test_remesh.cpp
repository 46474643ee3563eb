/// Tests of mesh/remesh.cpp: the fluid mesh built around solid surfaces is conforming (every
/// solid triangle is tiled by Solid faces), has the right volume, d_f ≥ 0 on interior faces,
/// interface barycentric weights that reproduce the face centroids, fluid kept in cavities,
/// and clear errors for bad geometry. Sphere, box, thin sheet, two close sheets, a paddle
/// moved and rotated through 50 remeshes. The same input gives the same mesh, bit for bit.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/delaunay.hpp"
#include "mesh/generate.hpp"
#include "mesh/quality.hpp"
#include "mesh/remesh.hpp"
#include "mesh/tet_mesh.hpp"
#include "mesh/volume_mesh.hpp"
#include "tests/test_util.hpp"

using tetfsi::test::message_of;
using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

/// An icosphere (mesh::make_icosphere) as the surface of body `body`.
SolidSurface icosphere(const Vec3& centre, double radius, int levels, int body = 0) {
  const SurfaceMesh m = make_icosphere(centre, radius, levels);
  SolidSurface s;
  s.body = body;
  s.vertices = m.vertices;
  s.triangles = m.triangles;
  return s;
}

/// Boundary of a box body (Kuhn tets), optionally rotated by R about `pivot`.
SolidSurface box_surface(const Vec3& lo, const Vec3& hi, const Vec3i& cells, int body = 0,
                         const Mat3& R = Mat3::Identity(), const Vec3& pivot = Vec3::Zero()) {
  const VolumeMesh vm = make_box(lo, hi, cells);
  SolidSurface s;
  s.body = body;
  s.triangles = boundary_triangles(vm);
  s.vertices = vm.vertices;
  for (Index i = 0; i < s.vertices.rows(); ++i)
    s.vertices.row(i) = (pivot + R * (vm.vertices.row(i).transpose() - pivot)).transpose();
  return s;
}

/// sheet_a of the smoke_sheets scene (0.5 x 0.5 x 0.01 m, 1 x 10 x 10 cells, turned -45 deg
/// about z) with its two vertical end edges exact (pinned) and the rest bent along the normal
/// by up to `bend` m plus noise of `noise` m (hash of `seed`, deterministic).
SolidSurface bent_sheet(int seed, double bend, double noise) {
  const VolumeMesh vm =
      make_box(Vec3(-0.005, -0.25, -0.25), Vec3(0.005, 0.25, 0.25), Vec3i(1, 10, 10));
  const Mat3 R = Eigen::AngleAxisd(-M_PI / 4, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 n = R * Vec3::UnitX();
  std::uint64_t h = static_cast<std::uint64_t>(seed) * 0x9E3779B97F4A7C15ULL + 7;
  const auto rnd = [&h] {
    h ^= h >> 31;
    h *= 0xBF58476D1CE4E5B9ULL;
    h ^= h >> 29;
    return static_cast<double>(h >> 11) / 9007199254740992.0 * 2 - 1;
  };
  SolidSurface s;
  s.triangles = boundary_triangles(vm);
  s.vertices.resize(vm.vertices.rows(), 3);
  for (Index i = 0; i < vm.vertices.rows(); ++i) {
    const Vec3 p = vm.vertices.row(i).transpose();
    Vec3 x = Vec3(0.75, 0.5, 0.45) + R * p;
    if (std::abs(p.y()) != 0.25) {
      const double w =
          std::sin(M_PI * (p.y() + 0.25) / 0.5) * (1 + 0.5 * std::sin(3 * p.z() + 0.1 * seed));
      Vec3 u;
      for (int a = 0; a < 3; ++a) u(a) = rnd();
      x += bend * w * n + noise * u;
    }
    s.vertices.row(i) = x.transpose();
  }
  return s;
}

/// A body's boundary as the fluid driver passes it: mesh::boundary_triangles of its tets,
/// with the vertices those triangles use, compacted in order of first use.
SolidSurface body_surface(const VolumeMesh& body, int id = 0) {
  const MatX3i tri = boundary_triangles(body);
  std::vector<int> node(body.num_vertices(), -1);
  std::vector<Vec3> xs;
  SolidSurface s;
  s.body = id;
  s.triangles.resize(tri.rows(), 3);
  for (Index f = 0; f < tri.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int& v = node[tri(f, k)];
      if (v < 0) {
        v = static_cast<int>(xs.size());
        xs.push_back(body.vertices.row(tri(f, k)).transpose());
      }
      s.triangles(f, k) = v;
    }
  }
  s.vertices.resize(static_cast<Index>(xs.size()), 3);
  for (std::size_t i = 0; i < xs.size(); ++i) s.vertices.row(i) = xs[i].transpose();
  return s;
}

/// Signed volume enclosed by a closed surface (divergence theorem).
double enclosed_volume(const SolidSurface& s) {
  double v6 = 0;
  for (Index t = 0; t < s.triangles.rows(); ++t) {
    const Vec3 a = s.vertices.row(s.triangles(t, 0)), b = s.vertices.row(s.triangles(t, 1)),
               c = s.vertices.row(s.triangles(t, 2));
    v6 += a.dot(b.cross(c));
  }
  return v6 / 6.0;
}

struct Checked {
  Index cells = 0;
  double min_rel_dual = 0;
};

/// Every invariant of the remesher's contract, asserted with stated tolerances.
/// `r`: the remesh report; its straddling faces (documented in remesh.hpp) may leave up to
/// two triangles each not tiled one by one, but the body's surface is still tiled as a whole.
Checked check_invariants(const TetMesh& m, const FluidDomain& d,
                         const std::vector<SolidSurface>& solids, const RemeshReport& r = {}) {
  // Volume: box minus the solids (an inward-oriented cavity shell subtracts negative volume).
  double solid_volume = 0;
  for (const auto& s : solids) solid_volume += enclosed_volume(s);
  const double box = (d.hi - d.lo).prod();
  CHECK(total_volume(m) == doctest::Approx(box - solid_volume).epsilon(1e-10));
  // Closed: Σ A n over the boundary vanishes.
  CHECK(boundary_area_vector(m).norm() <= 1e-10 * (d.hi - d.lo).squaredNorm());
  // d_f ≥ 0 on interior faces (Delaunay); round-off allowed: 1e-9 of the face's edge length.
  Checked out;
  out.cells = m.num_tets();
  out.min_rel_dual = 1e300;
  Index negative = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.is_boundary(f)) continue;
    const Vec3 a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
               c = m.vertices.row(m.faces(f, 2));
    const double edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0;
    out.min_rel_dual = std::min(out.min_rel_dual, m.dual_lengths(f) / edge);
    negative += m.dual_lengths(f) < -1e-9 * edge;
  }
  CHECK(negative == 0);
  // Conformity: Solid faces tile each solid triangle exactly; weights reproduce centroids;
  // normals point from the fluid into the solid (against the triangle's outward normal).
  std::map<std::pair<int, int>, double> covered;
  Index bad_bary = 0, bad_centroid = 0, bad_normal = 0, unknown_body = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.face_kind[f] != FaceKind::Solid) continue;
    const int b = m.face_body(f), t = m.face_triangle(f);
    const SolidSurface* s = nullptr;
    for (const auto& x : solids)
      if (x.body == b) s = &x;
    if (!s || t < 0 || t >= s->triangles.rows()) {
      ++unknown_body;
      continue;
    }
    covered[{b, t}] += m.face_areas(f);
    const Vec3 w = m.face_bary.row(f);
    bad_bary += (w.array() < -1e-12).any() || (w.array() > 1 + 1e-12).any() ||
                std::abs(w.sum() - 1) > 1e-12;
    const Vec3 p0 = s->vertices.row(s->triangles(t, 0)), p1 = s->vertices.row(s->triangles(t, 1)),
               p2 = s->vertices.row(s->triangles(t, 2));
    const Vec3 x = w(0) * p0 + w(1) * p1 + w(2) * p2;
    bad_centroid += (x - m.face_centroids.row(f).transpose()).norm() > 1e-9 * (p1 - p0).norm();
    const Vec3 nt = (p1 - p0).cross(p2 - p0).normalized();
    bad_normal += m.face_normals.row(f).dot(nt) > -1 + 1e-9;
  }
  CHECK(unknown_body == 0);
  CHECK(bad_bary == 0);
  CHECK(bad_centroid == 0);
  CHECK(bad_normal == 0);
  Index uncovered = 0;
  for (const auto& s : solids) {
    double body_area = 0, body_covered = 0;
    for (Index t = 0; t < s.triangles.rows(); ++t) {
      const Vec3 p0 = s.vertices.row(s.triangles(t, 0)), p1 = s.vertices.row(s.triangles(t, 1)),
                 p2 = s.vertices.row(s.triangles(t, 2));
      const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
      const auto it = covered.find({s.body, static_cast<int>(t)});
      uncovered += it == covered.end() || std::abs(it->second - area) > 1e-9 * area;
      body_area += area;
      if (it != covered.end()) body_covered += it->second;
    }
    CHECK(body_covered == doctest::Approx(body_area).epsilon(1e-9));
  }
  CHECK(uncovered <= 2 * r.straddling_faces);
  // Box faces are tagged with a box kind, everything else is interior or solid.
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.is_boundary(f)) {
      REQUIRE(m.face_kind[f] != FaceKind::Interior);
    } else {
      REQUIRE(m.face_kind[f] == FaceKind::Interior);
    }
  }
  // Vertex provenance: a surface vertex lies on its triangle at its barycentric position.
  for (Index v = 0; v < m.num_vertices(); ++v) {
    if (m.vertex_body(v) < 0) continue;
    const SolidSurface* s = nullptr;
    for (const auto& x : solids)
      if (x.body == m.vertex_body(v)) s = &x;
    REQUIRE(s != nullptr);
    const int t = m.vertex_triangle(v);
    const Vec3 w = m.vertex_bary.row(v);
    const Vec3 x = w(0) * s->vertices.row(s->triangles(t, 0)) +
                   w(1) * s->vertices.row(s->triangles(t, 1)) +
                   w(2) * s->vertices.row(s->triangles(t, 2));
    REQUIRE((x - m.vertices.row(v).transpose()).norm() < 1e-9);
  }
  return out;
}

FluidDomain unit_box() {
  FluidDomain d;
  d.lo = Vec3::Zero();
  d.hi = Vec3::Ones();
  return d;
}

/// FNV-1a over the bytes of an array (a checksum to compare runs of separate processes).
template <class Array>
std::uint64_t fnv1a(const Array& a, std::uint64_t h = 1469598103934665603ULL) {
  const auto* c = reinterpret_cast<const unsigned char*>(a.data());
  for (std::size_t i = 0; i < sizeof(*a.data()) * static_cast<std::size_t>(a.size()); ++i)
    h = (h ^ c[i]) * 1099511628211ULL;
  return h;
}

/// Checksum of a mesh's numbering and tags: vertices, tets, faces, face and vertex tags.
std::uint64_t checksum(const TetMesh& m) {
  std::uint64_t h = fnv1a(m.vertices);
  h = fnv1a(m.tets, h);
  h = fnv1a(m.faces, h);
  h = fnv1a(m.face_kind, h);
  h = fnv1a(m.face_patch, h);
  h = fnv1a(m.face_body, h);
  h = fnv1a(m.face_triangle, h);
  h = fnv1a(m.face_bary, h);
  h = fnv1a(m.vertex_body, h);
  h = fnv1a(m.vertex_triangle, h);
  return fnv1a(m.vertex_bary, h);
}

/// First row where two arrays of the same shape differ (−1 if none): a short failure message.
template <class A, class B>
Index first_different_row(const A& a, const B& b) {
  for (Index i = 0; i < a.rows(); ++i)
    if (a.row(i) != b.row(i)) return i;
  return -1;
}

/// Two meshes are the same bit for bit: numbering, positions and tags.
void check_identical(const TetMesh& a, const TetMesh& b) {
  REQUIRE(a.num_vertices() == b.num_vertices());
  REQUIRE(a.num_tets() == b.num_tets());
  REQUIRE(a.num_faces() == b.num_faces());
  CHECK(first_different_row(a.vertices, b.vertices) == -1);
  CHECK(first_different_row(a.tets, b.tets) == -1);
  CHECK(first_different_row(a.faces, b.faces) == -1);
  CHECK(first_different_row(a.face_tets, b.face_tets) == -1);
  CHECK(a.face_kind == b.face_kind);
  CHECK(first_different_row(a.face_patch, b.face_patch) == -1);
  CHECK(first_different_row(a.face_body, b.face_body) == -1);
  CHECK(first_different_row(a.face_triangle, b.face_triangle) == -1);
  CHECK(first_different_row(a.face_bary, b.face_bary) == -1);
  CHECK(first_different_row(a.vertex_body, b.vertex_body) == -1);
  CHECK(first_different_row(a.vertex_triangle, b.vertex_triangle) == -1);
  CHECK(first_different_row(a.vertex_bary, b.vertex_bary) == -1);
  CHECK(first_different_row(a.dual_lengths, b.dual_lengths) == -1);
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("make_icosphere: closed, outward, 20 * 4^s triangles, volume converging to the ball") {
    double previous_error = 1.0;
    for (int s = 0; s <= 4; ++s) {
      const SurfaceMesh m = make_icosphere(Vec3(1, 2, 3), 0.5, s);
      CHECK(m.num_triangles() == 20 * (1 << (2 * s)));
      CHECK(m.num_vertices() == 10 * (1 << (2 * s)) + 2);
      validate_closed_surface(m, "icosphere");  // throws if open or inconsistently oriented
      SolidSurface sol;
      sol.vertices = m.vertices;
      sol.triangles = m.triangles;
      const double ball = 4.0 / 3.0 * M_PI * 0.125;
      const double error = (ball - enclosed_volume(sol)) / ball;  // inscribed: smaller
      CHECK(error > 0);
      if (s > 0) CHECK(error < previous_error / 3.0);  // second order: about 4x per subdivision
      previous_error = error;
    }
    CHECK(previous_error < 0.01);
    CHECK_THROWS_AS(make_icosphere(Vec3::Zero(), -1.0, 1), InputError);
  }
  TEST_CASE("remesh: an empty box is a graded BCC mesh with exact walls and patches") {
    FluidDomain d = unit_box();
    d.patches.push_back({"jet", FaceKind::Inflow, 0, Vec2(0.2, 0.3), Vec2(0.8, 0.7)});
    d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(1, 1)});
    Sizing s;
    s.surface_size = s.far_size = 0.1;
    RemeshReport r;
    const TetMesh m = remesh(d, {}, s, &r);
    const Checked c = check_invariants(m, d, {});
    const QualitySummary q = summarize_quality(m);
    MESSAGE("empty box: ", m.num_tets(), " cells, min dihedral ", q.min_dihedral_deg,
            ", min d_f/edge ", c.min_rel_dual, ", nonpositive ", q.nonpositive_dual);
    CHECK(q.min_dihedral_deg > 10.0);
    double inflow = 0, open = 0;
    for (Index f = 0; f < m.num_faces(); ++f) {
      if (m.face_kind[f] == FaceKind::Inflow) inflow += m.face_areas(f);
      if (m.face_kind[f] == FaceKind::Open) open += m.face_areas(f);
    }
    CHECK(inflow == doctest::Approx(0.24).epsilon(1e-12));  // 0.6 × 0.4, on lattice lines
    CHECK(open == doctest::Approx(1.0).epsilon(1e-12));
  }

  TEST_CASE("cospherical_groups: a Kuhn cube is one group and a BCC lattice has none") {
    // The 6 Kuhn tets of a cube share the cube's circumsphere: one group.
    const VolumeMesh cube = make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1));
    Index n = 0;
    const VecXi g = cospherical_groups(build_tet_mesh(cube.vertices, cube.tets), 1e-9, &n);
    CHECK(n == 1);
    CHECK((g.array() == 0).all());
    // Two Kuhn cubes: two spheres, two groups.
    const VolumeMesh two = make_box(Vec3::Zero(), Vec3(2, 1, 1), Vec3i(2, 1, 1));
    cospherical_groups(build_tet_mesh(two.vertices, two.tets), 1e-9, &n);
    CHECK(n == 2);
    // The remesher's uniform BCC interior has no co-spherical cells: every cell its own group.
    FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = s.far_size = 0.1;
    const TetMesh m = remesh(d, {}, s);
    cospherical_groups(m, 1e-9, &n);
    CHECK(n == m.num_tets());
    // With a sphere, the octree transitions group some cells; each group has one circumcentre.
    Sizing ss;
    ss.surface_size = 0.04;
    ss.far_size = 0.16;
    const TetMesh ms = remesh(d, {icosphere(Vec3(0.5, 0.5, 0.5), 0.2, 3)}, ss);
    const VecXi gs = cospherical_groups(ms, 1e-9, &n);
    CHECK(n < ms.num_tets());
    std::vector<Index> first(n, -1);
    Index spread = 0;
    for (Index t = 0; t < ms.num_tets(); ++t) {
      Index& f = first[gs(t)];
      if (f < 0) f = t;
      spread += (ms.circumcentres.row(t) - ms.circumcentres.row(f)).norm() > 1e-9;
    }
    CHECK(spread == 0);
    MESSAGE("sphere mesh: ", ms.num_tets(), " cells in ", n, " co-spherical groups");
  }

  TEST_CASE("remesh: sphere") {
    const FluidDomain d = unit_box();
    const std::vector<SolidSurface> solids = {icosphere(Vec3(0.5, 0.5, 0.5), 0.2, 3)};
    Sizing s;
    s.surface_size = 0.04;
    s.far_size = 0.16;
    RemeshReport r;
    const TetMesh m = remesh(d, solids, s, &r);
    const Checked c = check_invariants(m, d, solids, r);
    const QualitySummary q = summarize_quality(m);
    MESSAGE("sphere: ", m.num_tets(), " cells, ", r.steiner_points, " Steiner, ", r.recovery_rounds,
            " rounds, min dihedral ", q.min_dihedral_deg, " away ", q.min_dihedral_away_deg,
            ", slivers ", q.slivers, ", min d_f/edge ", c.min_rel_dual, " nonpos ",
            q.nonpositive_dual, " tiny ", q.tiny_dual, " t=", r.seconds_total);
    CHECK(q.min_dihedral_away_deg > 10.0);
  }

  TEST_CASE("remesh: box solid with sharp edges") {
    const FluidDomain d = unit_box();
    const std::vector<SolidSurface> solids = {
        box_surface(Vec3(0.3, 0.35, 0.4), Vec3(0.7, 0.65, 0.6), Vec3i(4, 3, 2))};
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    RemeshReport r;
    const TetMesh m = remesh(d, solids, s, &r);
    check_invariants(m, d, solids, r);
    const QualitySummary q = summarize_quality(m);
    MESSAGE("box: ", m.num_tets(), " cells, ", r.steiner_points, " Steiner, ", r.recovery_rounds,
            " rounds, min dihedral away ", q.min_dihedral_away_deg);
    CHECK(q.min_dihedral_away_deg > 10.0);
    CHECK(r.steiner_points > 0);  // its 0.1 m triangles are longer than 1.5 × 0.05 m
  }

  TEST_CASE("remesh: thin sheet of thickness far_size / 20") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    const double t = s.far_size / 20;
    const std::vector<SolidSurface> solids = {
        box_surface(Vec3(0.2, 0.2, 0.5 - t / 2), Vec3(0.8, 0.8, 0.5 + t / 2), Vec3i(12, 12, 1))};
    RemeshReport r;
    const TetMesh m = remesh(d, solids, s, &r);
    const Checked c = check_invariants(m, d, solids, r);
    const QualitySummary q = summarize_quality(m);
    MESSAGE("thin sheet: ", c.cells, " cells, ", r.steiner_points, " Steiner, ", r.recovery_rounds,
            " rounds, min dihedral away ", q.min_dihedral_away_deg);
    CHECK(q.min_dihedral_away_deg > 10.0);
  }

  TEST_CASE("remesh: thin sheet at oblique angles") {
    // Conformity and the other invariants hold in any orientation, and the cells away from
    // the sheet keep 10° (the octree's staircase transitions along the oblique slab made
    // 3.7° before sliver perturbation).
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    for (double deg : {3.0, 17.0, 45.0, 71.0}) {
      CAPTURE(deg);
      const Mat3 R =
          Eigen::AngleAxisd(deg * M_PI / 180.0, Vec3(1, 2, 3).normalized()).toRotationMatrix();
      const std::vector<SolidSurface> solids = {box_surface(Vec3(0.2, 0.2, 0.495),
                                                            Vec3(0.8, 0.8, 0.505), Vec3i(12, 12, 1),
                                                            0, R, Vec3(0.5, 0.5, 0.5))};
      RemeshReport r;
      const TetMesh m = remesh(d, solids, s, &r);
      check_invariants(m, d, solids, r);
      CHECK(r.straddling_faces == 0);
      CHECK(summarize_quality(m).min_dihedral_away_deg > 10.0);
    }
  }

  TEST_CASE("remesh: a bent sheet turned 45 deg leaves no flat fluid cell") {
    // smoke_sheets failed at step 28 in build_tet_mesh ("not positively oriented, signed
    // volume -2.26e-21 m^3"): a lattice edge under the sheet's pinned bottom edge, both along
    // the sheet's normal and symmetric about its mid-plane, made a co-circular trapezoid: a
    // flat fluid cell, positive in the Delaunay's lattice units, of round-off volume in metres.
    // Seeds 7 and 50 of this bent sheet failed the same way (volumes -7e-23 and 0 m^3) before
    // degenerate cells kept losing a lattice vertex after the sliver rounds.
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.03;
    s.far_size = 0.1;
    for (int seed : {7, 50}) {
      CAPTURE(seed);
      const std::vector<SolidSurface> solids = {bent_sheet(seed, 3e-3, 3e-4)};
      RemeshReport r;
      const TetMesh m = remesh(d, solids, s, &r);
      check_invariants(m, d, solids, r);
      Index flat = 0;
      for (Index t = 0; t < m.num_tets(); ++t) {
        double l = 0;
        for (int i = 0; i < 4; ++i)
          for (int j = i + 1; j < 4; ++j)
            l = std::max(l, (m.vertices.row(m.tets(t, i)) - m.vertices.row(m.tets(t, j))).norm());
        flat += 6.0 * m.volumes(t) <= 1e-9 * l * l * l;  // the remesher's kFlat
      }
      CHECK(flat == 0);
    }
  }

  TEST_CASE("remesh: two sheets close together and a sheet near a wall") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    const double t = 0.01, gap = 0.02;  // gap smaller than the surface size
    const Mat3 tilt = Eigen::AngleAxisd(0.05, Vec3::UnitX()).toRotationMatrix();
    const std::vector<SolidSurface> solids = {
        box_surface(Vec3(0.2, 0.2, 0.5), Vec3(0.8, 0.8, 0.5 + t), Vec3i(12, 12, 1), 0),
        box_surface(Vec3(0.2, 0.2, 0.5 + t + gap), Vec3(0.8, 0.8, 0.5 + 2 * t + gap),
                    Vec3i(10, 10, 1), 1, tilt, Vec3(0.5, 0.2, 0.5)),
        box_surface(Vec3(0.1, 0.1, 0.015), Vec3(0.9, 0.9, 0.025), Vec3i(8, 8, 1), 2)};
    RemeshReport r;
    const TetMesh m = remesh(d, solids, s, &r);
    check_invariants(m, d, solids, r);
    MESSAGE("two sheets + wall: ", m.num_tets(), " cells, ", r.steiner_points, " Steiner, ",
            r.recovery_rounds, " rounds, ", r.straddling_faces, " straddling faces");
  }

  TEST_CASE("remesh: a paddle moved and rotated through 50 remeshes") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.06;
    s.far_size = 0.25;
    const SolidSurface rest =
        box_surface(Vec3(-0.15, -0.02, -0.1), Vec3(0.15, 0.02, 0.1), Vec3i(6, 1, 4));
    int total_rounds = 0;
    Index straddling = 0;
    for (int step = 0; step < 50; ++step) {
      const double a = 0.13 * step;
      const Mat3 R = (Eigen::AngleAxisd(a, Vec3::UnitZ()) *
                      Eigen::AngleAxisd(0.7 * a, Vec3(1, 1, 0).normalized()))
                         .toRotationMatrix();
      const Vec3 centre(0.5 + 0.25 * std::cos(0.2 * step), 0.5 + 0.2 * std::sin(0.3 * step),
                        0.5 + 0.004 * step);
      SolidSurface p = rest;
      for (Index i = 0; i < p.vertices.rows(); ++i)
        p.vertices.row(i) = (centre + R * rest.vertices.row(i).transpose()).transpose();
      RemeshReport r;
      const TetMesh m = remesh(d, {p}, s, &r);
      CAPTURE(step);
      check_invariants(m, d, {p}, r);
      total_rounds += r.recovery_rounds;
      straddling += r.straddling_faces;
    }
    MESSAGE("paddle: ", total_rounds, " recovery rounds, ", straddling,
            " straddling faces over 50 remeshes");
  }

  TEST_CASE("remesh: the same input gives the same mesh bit for bit and local recovery = full") {
    // Vertex removal in CGAL used to fill holes in an order hashed by addresses, so meshes
    // whose recovery removed lattice points (diametral spheres, slivers, perturbation) were
    // numbered differently from run to run. Each case is meshed twice in this process; the
    // checksums let two processes be compared (run the test twice).
    const FluidDomain d = unit_box();
    const SolidSurface rest =
        box_surface(Vec3(-0.15, -0.02, -0.1), Vec3(0.15, 0.02, 0.1), Vec3i(6, 1, 4));
    const auto paddle = [&](int step) {
      const double a = 0.13 * step;
      const Mat3 R = (Eigen::AngleAxisd(a, Vec3::UnitZ()) *
                      Eigen::AngleAxisd(0.7 * a, Vec3(1, 1, 0).normalized()))
                         .toRotationMatrix();
      const Vec3 centre(0.5 + 0.25 * std::cos(0.2 * step), 0.5 + 0.2 * std::sin(0.3 * step),
                        0.5 + 0.004 * step);
      SolidSurface p = rest;
      for (Index i = 0; i < p.vertices.rows(); ++i)
        p.vertices.row(i) = (centre + R * rest.vertices.row(i).transpose()).transpose();
      return p;
    };
    SolidSurface hollow = icosphere(Vec3(0.5, 0.5, 0.5), 0.45, 3);
    {
      const SolidSurface inner = icosphere(Vec3(0.5, 0.5, 0.5), 0.38, 3);
      const Index nv = hollow.vertices.rows(), nt = hollow.triangles.rows();
      hollow.vertices.conservativeResize(nv + inner.vertices.rows(), 3);
      hollow.vertices.bottomRows(inner.vertices.rows()) = inner.vertices;
      hollow.triangles.conservativeResize(nt + inner.triangles.rows(), 3);
      for (Index t = 0; t < inner.triangles.rows(); ++t)
        hollow.triangles.row(nt + t) =
            Eigen::RowVector3i(inner.triangles(t, 0), inner.triangles(t, 2),
                               inner.triangles(t, 1)) +
            Eigen::RowVector3i::Constant(static_cast<int>(nv));
    }
    const Mat3 tilt =
        Eigen::AngleAxisd(17.0 * M_PI / 180.0, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    const SolidSurface sheet = box_surface(Vec3(0.2, 0.2, 0.495), Vec3(0.8, 0.8, 0.505),
                                           Vec3i(12, 12, 1), 0, tilt, Vec3(0.5, 0.5, 0.5));
    struct Case {
      std::string name;
      std::vector<SolidSurface> solids;
      double surface, far;
    };
    const std::vector<Case> cases = {
        {"sphere", {icosphere(Vec3(0.5, 0.5, 0.5), 0.2, 3)}, 0.04, 0.16},
        {"hollow sphere", {hollow}, 0.08, 0.16},
        {"oblique sheet", {sheet}, 0.05, 0.2},
        {"paddle", {paddle(7)}, 0.06, 0.25}};
    Index removed = 0, moved = 0;
    int rounds = 0;
    for (const Case& c : cases) {
      CAPTURE(c.name);
      Sizing s;
      s.surface_size = c.surface;
      s.far_size = c.far;
      RemeshReport r1, r2, r3;
      const TetMesh a = remesh(d, c.solids, s, &r1);
      const TetMesh b = remesh(d, c.solids, s, &r2);
      check_identical(a, b);
      CHECK(r1.steiner_points == r2.steiner_points);
      CHECK(r1.sliver_points_removed == r2.sliver_points_removed);
      CHECK(r1.sliver_points_moved == r2.sliver_points_moved);
      CHECK(r1.recovery_rounds == r2.recovery_rounds);
      // The local recovery (each round re-examines what the last one changed) gives the mesh
      // the full one (every cell touching a solid, every round) gives.
      Sizing full = s;
      full.local_recovery = false;
      const TetMesh e = remesh(d, c.solids, full, &r3);
      check_identical(a, e);
      CHECK(r1.recovery_rounds == r3.recovery_rounds);
      CHECK(r1.cleanup_rounds == r3.cleanup_rounds);
      removed += r1.sliver_points_removed;
      moved += r1.sliver_points_moved;
      rounds += r1.recovery_rounds;
      MESSAGE(c.name, ": ", a.num_tets(), " cells, ", r1.recovery_rounds, " rounds, ",
              r1.sliver_points_removed, " slivers removed, ", r1.sliver_points_moved,
              " moved, checksum ", fmt::format("{:016x}", checksum(a)));
    }
    // The cases do exercise the removals.
    CHECK(removed > 0);
    CHECK(moved > 0);
    CHECK(rounds > static_cast<int>(cases.size()));
  }

  TEST_CASE("Delaunay::remove and remove_many leave the Delaunay of the other points") {
    // An exact 8^3 lattice (every cube's corners co-spherical: the symbolic perturbation
    // decides) and a jittered one. Removed: clusters inside (a 2x2x2 block, a row), scattered
    // single vertices, and a cluster on the hull (a box corner and its neighbours, which the
    // removal leaves to CGAL's own). After each removal the cells, as sorted id quadruples,
    // are those of a fresh build of the remaining points, and every neighbour is mutual.
    for (const double jitter : {0.0, 0.2}) {
      CAPTURE(jitter);
      std::vector<Vec3> pts;
      std::uint64_t h = 777;
      const auto rnd = [&] {
        h = h * 6364136223846793005ULL + 1442695040888963407ULL;
        return static_cast<double>(h >> 11) / 9007199254740992.0 - 0.5;
      };
      const auto at = [](int i, int j, int k) { return (i * 8 + j) * 8 + k; };
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j)
          for (int k = 0; k < 8; ++k)
            pts.push_back(Vec3(i + jitter * rnd(), j + jitter * rnd(), k + jitter * rnd()));
      Delaunay d;
      d.build(pts);
      std::vector<char> alive(pts.size(), 1);
      const auto cells_of = [](const Delaunay& dl, const std::vector<int>& id_of) {
        MatX4i t, n;
        dl.extract(t, n);
        for (Index c = 0; c < t.rows(); ++c)
          for (int k = 0; k < 4; ++k) {
            const int o = n(c, k);
            if (o < 0) continue;
            int back = 0;  // o's neighbours: c exactly once
            for (int j = 0; j < 4; ++j) back += n(o, j) == c;
            CHECK(back == 1);
          }
        std::vector<std::array<int, 4>> rows;
        for (Index c = 0; c < t.rows(); ++c) {
          std::array<int, 4> r = {id_of[t(c, 0)], id_of[t(c, 1)], id_of[t(c, 2)], id_of[t(c, 3)]};
          std::sort(r.begin(), r.end());
          rows.push_back(r);
        }
        std::sort(rows.begin(), rows.end());
        return rows;
      };
      const auto check_against_fresh = [&] {
        std::vector<Vec3> rest;
        std::vector<int> id_of;
        for (std::size_t i = 0; i < pts.size(); ++i)
          if (alive[i]) rest.push_back(pts[i]), id_of.push_back(static_cast<int>(i));
        Delaunay fresh;
        fresh.build(rest);
        std::vector<int> same(pts.size());
        std::iota(same.begin(), same.end(), 0);
        CHECK(d.num_vertices() == static_cast<Index>(rest.size()));
        CHECK(cells_of(d, same) == cells_of(fresh, id_of));
      };
      std::vector<int> block, row, hull;
      for (int i = 3; i < 5; ++i)
        for (int j = 3; j < 5; ++j)
          for (int k = 3; k < 5; ++k) block.push_back(at(i, j, k));
      for (int k = 1; k < 7; ++k) row.push_back(at(1, 6, k));
      hull = {at(0, 0, 0), at(1, 0, 0), at(0, 1, 0), at(0, 0, 1), at(1, 1, 1)};
      std::vector<int> many = block;
      many.insert(many.end(), row.begin(), row.end());
      many.insert(many.end(), hull.begin(), hull.end());
      d.remove_many(many);
      for (int v : many) alive[v] = 0;
      check_against_fresh();
      for (int v : {at(2, 2, 5), at(6, 3, 2), at(5, 5, 6)}) {
        d.remove(v);
        alive[v] = 0;
        check_against_fresh();
      }
      d.remove(at(7, 7, 7));  // on the hull
      alive[at(7, 7, 7)] = 0;
      check_against_fresh();
    }
  }

  TEST_CASE("Delaunay::update gives the triangulation build gives - ids and cells") {
    // A jittered 9^3 lattice; the update keeps two thirds of it, moves some points and adds
    // new ones: the same cells as a fresh build of the new points (canonical vertex order,
    // rows sorted), also when the cost criterion sends it to a rebuild.
    std::vector<Vec3> a, b;
    std::uint64_t h = 12345;
    const auto rnd = [&] {
      h = h * 6364136223846793005ULL + 1442695040888963407ULL;
      return static_cast<double>(h >> 11) / 9007199254740992.0;
    };
    for (int i = 0; i < 9; ++i)
      for (int j = 0; j < 9; ++j)
        for (int k = 0; k < 9; ++k) {
          const Vec3 p(i + 0.2 * rnd(), j + 0.2 * rnd(), k + 0.2 * rnd());
          a.push_back(p);
          if ((i + j + k) % 3 != 0) b.push_back(p);                            // kept
          if ((i + 2 * j + k) % 7 == 0) b.push_back(p + Vec3(0.5, 0.5, 0.5));  // new
        }
    std::reverse(b.begin(), b.end());  // new ids for every kept point
    const auto sorted_cells = [](const Delaunay& d) {
      MatX4i t, n;
      d.extract(t, n);
      std::vector<std::array<int, 4>> rows;
      for (Index i = 0; i < t.rows(); ++i) {
        // canonical: the smallest id first, the second smallest next
        CHECK(t(i, 0) < std::min({t(i, 1), t(i, 2), t(i, 3)}));
        CHECK(t(i, 1) < std::min(t(i, 2), t(i, 3)));
        rows.push_back({t(i, 0), t(i, 1), t(i, 2), t(i, 3)});
      }
      std::sort(rows.begin(), rows.end());
      return rows;
    };
    Delaunay fresh;
    fresh.build(b);
    const auto want = sorted_cells(fresh);
    Delaunay d;
    d.build(a);
    Index removed = 0, inserted = 0;
    CHECK(d.update(b, 1e9, removed, inserted));
    CHECK(removed == static_cast<Index>(a.size()) - (static_cast<Index>(b.size()) - inserted));
    CHECK(removed > 200);
    CHECK(inserted > 50);
    CHECK(d.num_vertices() == static_cast<Index>(b.size()));
    CHECK(sorted_cells(d) == want);
    // Past the cost limit it rebuilds: the same cells again, and it says so.
    Delaunay e;
    e.build(a);
    CHECK_FALSE(e.update(b, 0.1, removed, inserted));
    CHECK(sorted_cells(e) == want);
    // Two new points at one position: the rebuild's error, naming both.
    std::vector<Vec3> dup = b;
    dup.push_back(b[3]);
    const std::string msg = message_of<MeshError>([&] { d.update(dup, 1e9, removed, inserted); });
    CHECK(msg.find(fmt::format("points 3 and {} coincide", b.size())) != std::string::npos);
  }

  TEST_CASE(
      "remesh: the incremental path gives the full rebuild's mesh bit for bit, step after step") {
    // A paddle moving and turning slowly beside a sphere that stays put: each step's
    // incremental remesh (from the last step's triangulation) against a full one of the same
    // input, and every invariant on it.
    const FluidDomain d = unit_box();
    const SolidSurface rest =
        box_surface(Vec3(-0.15, -0.02, -0.1), Vec3(0.15, 0.02, 0.1), Vec3i(6, 1, 4));
    const SolidSurface ball = icosphere(Vec3(0.25, 0.3, 0.3), 0.12, 3, 1);
    const auto paddle = [&](int step) {
      const double a = 0.03 * step;
      const Mat3 R = (Eigen::AngleAxisd(a, Vec3::UnitZ()) *
                      Eigen::AngleAxisd(0.7 * a, Vec3(1, 1, 0).normalized()))
                         .toRotationMatrix();
      const Vec3 centre(0.62 + 0.01 * step, 0.6, 0.6 - 0.004 * step);
      SolidSurface p = rest;
      for (Index i = 0; i < p.vertices.rows(); ++i)
        p.vertices.row(i) = (centre + R * rest.vertices.row(i).transpose()).transpose();
      return p;
    };
    for (const double max_cost : {1e9, 1.0}) {  // always incremental; the default criterion
      CAPTURE(max_cost);
      Sizing s;
      s.surface_size = 0.05;
      s.far_size = 0.2;
      s.incremental = true;
      s.incremental_max_cost = max_cost;
      Sizing full = s;
      full.incremental = false;
      Remesher remesher;
      int incremental = 0;
      for (int step = 0; step < 6; ++step) {
        CAPTURE(step);
        const std::vector<SolidSurface> solids = {paddle(step), ball};
        RemeshReport ri, rf;
        const TetMesh mi = remesher.remesh(d, solids, s, &ri);
        const TetMesh mf = remesh(d, solids, full, &rf);
        check_identical(mi, mf);
        check_invariants(mi, d, solids, ri);
        CHECK_FALSE(rf.incremental);
        CHECK(rf.vertices_removed == 0);
        if (step == 0 || !ri.incremental) {
          CHECK(step == 0);  // the paddle moves little: incremental after the first
          CHECK(ri.vertices_removed == 0);
          continue;
        }
        ++incremental;
        // The paddle's points go and come; the ball's and the far lattice stay.
        CHECK(ri.vertices_removed > 50);
        CHECK(ri.vertices_inserted > 50);
        CHECK(ri.vertices_removed + ri.vertices_inserted < mi.num_vertices() / 2);
      }
      CHECK(incremental == 5);
      MESSAGE("max cost ", max_cost, ": ", incremental, " of 5 remeshes incremental");
    }
  }

  TEST_CASE(
      "remesh: CGAL's parallel insertion (parallel_insertion) gives the same meshes bit for bit") {
    // A ball moving past another, remeshed at 2 and 3 threads with the parallel full
    // Delaunay: every step rebuilt (incremental off), and incremental updates of the copied
    // triangulation (the first step's), against the sequential full remesh.
    const int saved = thread_count();
    const FluidDomain d = unit_box();
    const SolidSurface still = icosphere(Vec3(0.3, 0.5, 0.5), 0.12, 3, 1);
    for (const int threads : {2, 3}) {
      for (const bool incremental : {false, true}) {
        CAPTURE(threads);
        CAPTURE(incremental);
        set_thread_count(threads);
        Sizing seq;
        seq.surface_size = 0.04;
        seq.far_size = 0.16;
        seq.incremental = false;
        Sizing par = seq;
        par.incremental = incremental;
        par.incremental_max_cost = 1e9;
        par.parallel_insertion = true;
        Remesher remesher;
        for (int step = 0; step < 3; ++step) {
          CAPTURE(step);
          const std::vector<SolidSurface> solids = {
              still, icosphere(Vec3(0.62 + 0.02 * step, 0.55, 0.5), 0.1, 3, 2)};
          RemeshReport rp;
          const TetMesh mp = remesher.remesh(d, solids, par, &rp);
          const TetMesh ms = remesh(d, solids, seq);
          check_identical(mp, ms);
          CHECK(rp.incremental == (incremental && step > 0));
        }
      }
    }
    set_thread_count(saved);
  }

  TEST_CASE("Remesher: after a failed remesh or reset() the next one is a full rebuild") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.06;
    s.far_size = 0.24;
    s.incremental = true;
    s.incremental_max_cost = 1e9;
    const SolidSurface a = icosphere(Vec3(0.4, 0.5, 0.5), 0.12, 2);
    const SolidSurface b = icosphere(Vec3(0.42, 0.5, 0.5), 0.12, 2);
    Remesher remesher;
    RemeshReport r;
    remesher.remesh(d, {a}, s, &r);
    CHECK_FALSE(r.incremental);
    remesher.remesh(d, {b}, s, &r);
    CHECK(r.incremental);
    // Two overlapping bodies: the remesh fails before its Delaunay; the kept one serves.
    CHECK_THROWS_AS(remesher.remesh(d, {a, b}, s, &r), MeshError);
    check_identical(remesher.remesh(d, {a}, s, &r), remesh(d, {a}, s));
    CHECK(r.incremental);
    // A recovery that fails (no rounds allowed): the triangulation it left is dropped.
    RemeshOptions none;
    none.max_recovery_rounds = 0;
    const Mat3 tilt =
        Eigen::AngleAxisd(17.0 * M_PI / 180.0, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    const SolidSurface sheet = box_surface(Vec3(0.2, 0.2, 0.495), Vec3(0.8, 0.8, 0.505),
                                           Vec3i(12, 12, 1), 0, tilt, Vec3(0.5, 0.5, 0.5));
    CHECK_THROWS_AS(remesher.remesh(d, {sheet}, s, &r, none), MeshError);
    const TetMesh m = remesher.remesh(d, {a}, s, &r);
    CHECK_FALSE(r.incremental);
    check_identical(m, remesh(d, {a}, s));
    remesher.remesh(d, {b}, s, &r);
    CHECK(r.incremental);
    remesher.reset();
    remesher.remesh(d, {a}, s, &r);
    CHECK_FALSE(r.incremental);
    // An update that costs too much rebuilds, and the next call rebuilds without trying;
    // the meshes are the full ones all the same.
    Sizing dear = s;
    dear.incremental_max_cost = 0.0;
    remesher.remesh(d, {b}, dear, &r);
    for (const SolidSurface& x : {a, b, a}) {
      check_identical(remesher.remesh(d, {x}, dear, &r), remesh(d, {x}, s));
      CHECK_FALSE(r.incremental);
    }
    // Sizing::incremental false: always full, nothing kept.
    s.incremental = false;
    remesher.remesh(d, {b}, s, &r);
    CHECK_FALSE(r.incremental);
    s.incremental = true;
    remesher.remesh(d, {a}, s, &r);
    CHECK_FALSE(r.incremental);
  }

  TEST_CASE("remesh: fluid enclosed by a hollow solid stays fluid") {
    const FluidDomain d = unit_box();
    // One body: a shell between radii 0.3 and 0.22; its inner surface points into the cavity.
    SolidSurface outer = icosphere(Vec3(0.5, 0.5, 0.5), 0.3, 3);
    const SolidSurface inner = icosphere(Vec3(0.5, 0.5, 0.5), 0.22, 3);
    const Index nv = outer.vertices.rows(), nt = outer.triangles.rows();
    outer.vertices.conservativeResize(nv + inner.vertices.rows(), 3);
    outer.vertices.bottomRows(inner.vertices.rows()) = inner.vertices;
    outer.triangles.conservativeResize(nt + inner.triangles.rows(), 3);
    for (Index t = 0; t < inner.triangles.rows(); ++t)
      outer.triangles.row(nt + t) =
          Eigen::RowVector3i(inner.triangles(t, 0), inner.triangles(t, 2), inner.triangles(t, 1)) +
          Eigen::RowVector3i::Constant(static_cast<int>(nv));
    Sizing s;
    s.surface_size = 0.04;
    s.far_size = 0.2;
    const TetMesh m = remesh(d, {outer}, s);
    check_invariants(m, d, {outer});  // volume = box − shell, so the cavity is fluid
    Index cavity_cells = 0;
    for (Index t = 0; t < m.num_tets(); ++t) {
      const Vec3 c = (m.vertices.row(m.tets(t, 0)) + m.vertices.row(m.tets(t, 1)) +
                      m.vertices.row(m.tets(t, 2)) + m.vertices.row(m.tets(t, 3))) /
                     4.0;
      cavity_cells += (c - Vec3(0.5, 0.5, 0.5)).norm() < 0.2;
    }
    CHECK(cavity_cells > 50);
  }

  TEST_CASE(
      "remesh: a make_spherical_shell body keeps its cavity as fluid of the cavity's volume") {
    // A water balloon: the body's boundary triangles (outer sphere outward, inner toward the
    // centre) with its surface nodes, as the fluid driver passes a body.
    const Vec3 c(0.5, 0.5, 0.5);
    const double ri = 0.22, ro = 0.3;
    const SolidSurface shell = body_surface(make_spherical_shell(c, ri, ro, 3, 2));
    CHECK(shell.vertices.rows() == 2 * 642);  // the middle layer's nodes are not on the surface

    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.04;
    s.far_size = 0.2;
    const TetMesh m = remesh(d, {shell}, s);
    check_invariants(m, d, {shell});  // volume = box − shell: the cavity is fluid
    // Cavity cells: centroid inside the inner sphere's polyhedron (radius ≤ ri), shell cells
    // are gone, outside cells have centroid radius ≥ ro cos(max face angle) > 0.29.
    double cavity = 0.0;
    Index cavity_cells = 0;
    for (Index t = 0; t < m.num_tets(); ++t) {
      const Vec3 x = (m.vertices.row(m.tets(t, 0)) + m.vertices.row(m.tets(t, 1)) +
                      m.vertices.row(m.tets(t, 2)) + m.vertices.row(m.tets(t, 3))) /
                     4.0;
      if ((x - c).norm() < 0.5 * (ri + ro)) {
        cavity +=
            std::abs(signed_volume(m.vertices.row(m.tets(t, 0)), m.vertices.row(m.tets(t, 1)),
                                   m.vertices.row(m.tets(t, 2)), m.vertices.row(m.tets(t, 3))));
        ++cavity_cells;
      }
    }
    // The polyhedral cavity: ri³ × the unit icosphere's volume (s = 3), to round-off (the
    // remesher's volume contract is 1e-10 relative); the ball's (4/3)π ri³ within the
    // icosphere's 0.84 % inscribed deficit at s = 3.
    SolidSurface unit = icosphere(Vec3::Zero(), 1.0, 3);
    const double polyhedral = ri * ri * ri * enclosed_volume(unit);
    MESSAGE("cavity: " << cavity_cells << " cells, volume " << cavity << " vs polyhedral "
                       << polyhedral << " and ball " << 4.0 / 3.0 * M_PI * ri * ri * ri);
    CHECK(cavity_cells > 50);
    CHECK(cavity == doctest::Approx(polyhedral).epsilon(1e-10));
    CHECK(cavity == doctest::Approx(4.0 / 3.0 * M_PI * ri * ri * ri).epsilon(0.0085));
  }

  TEST_CASE("remesh: a make_hollow_box body with a one-cell wall keeps its cavity as fluid") {
    // A wall one cell (0.04) thick under cavity cells 0.053-0.16 long: its surface triangles
    // are long and thin (up to 4:1) on both sides of the wall. These cell counts leaked
    // ("boundary face ... neither on the domain box nor on a solid triangle").
    const Vec3 lo(0.3, 0.3, 0.2), hi(0.7, 0.7, 0.6);
    const double t = 0.04;
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.04;
    s.far_size = 0.15;
    s.grading = 0.5;
    for (const Vec3i& cells :
         {Vec3i(6, 6, 2), Vec3i(5, 5, 2), Vec3i(4, 4, 2), Vec3i(4, 4, 3), Vec3i(3, 3, 3)}) {
      CAPTURE(cells.transpose());
      const SolidSurface body = body_surface(make_hollow_box(lo, hi, t, cells));
      RemeshReport r;
      const TetMesh m = remesh(d, {body}, s, &r);
      check_invariants(m, d, {body}, r);  // volume = box − walls: the cavity is fluid
      // Cavity cells: the fluid cells with their centroid inside the body's outer box.
      double cavity = 0.0;
      for (Index c = 0; c < m.num_tets(); ++c) {
        const Vec3 x = (m.vertices.row(m.tets(c, 0)) + m.vertices.row(m.tets(c, 1)) +
                        m.vertices.row(m.tets(c, 2)) + m.vertices.row(m.tets(c, 3))) /
                       4.0;
        if ((x.array() > lo.array()).all() && (x.array() < hi.array()).all())
          cavity +=
              std::abs(signed_volume(m.vertices.row(m.tets(c, 0)), m.vertices.row(m.tets(c, 1)),
                                     m.vertices.row(m.tets(c, 2)), m.vertices.row(m.tets(c, 3))));
      }
      CHECK(cavity == doctest::Approx((hi - lo - Vec3::Constant(2 * t)).prod()).epsilon(1e-9));
      // No flat fluid cell is left (four surface points on both sides of a cavity edge, coplanar
      // to round-off: |6V| <= 1e-9 l^3, as the remesher's kFlat).
      Index flat = 0;
      for (Index c = 0; c < m.num_tets(); ++c) {
        double l = 0.0;
        for (int i = 0; i < 4; ++i)
          for (int j = i + 1; j < 4; ++j)
            l = std::max(l, (m.vertices.row(m.tets(c, i)) - m.vertices.row(m.tets(c, j))).norm());
        flat += 6.0 * m.volumes(c) <= 1e-9 * l * l * l;
      }
      CHECK(flat == 0);
      MESSAGE(cells.transpose(), ": ", m.num_tets(), " cells, ", r.recovery_rounds, " rounds, ",
              r.steiner_points, " Steiner points");
    }
  }

  TEST_CASE("remesh: refinement field and cell budget") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    const Index coarse = remesh(d, {}, s).num_tets();
    s.refine = [](const Vec3& x) { return x.z() > 0.7 ? 0.05 : -1.0; };
    const TetMesh fine = remesh(d, {}, s);
    check_invariants(fine, d, {});
    CHECK(fine.num_tets() > 4 * coarse);
    s.max_cells = fine.num_tets() / 3;
    const TetMesh capped = remesh(d, {}, s);
    CHECK(capped.num_tets() <= s.max_cells);
    CHECK(capped.num_tets() > s.max_cells / 20);
  }

  TEST_CASE("remesh: bad geometry and bad sizing are one-line errors naming body and triangle") {
    const FluidDomain d = unit_box();
    Sizing s;
    s.surface_size = 0.05;
    s.far_size = 0.2;
    // Poking out of the domain.
    const SolidSurface out = icosphere(Vec3(0.9, 0.5, 0.5), 0.2, 1, 3);
    std::string msg = message_of<MeshError>([&] { remesh(d, {out}, s); });
    CHECK(msg.find("body 3") != std::string::npos);
    CHECK(msg.find("not inside the fluid domain") != std::string::npos);
    // Two bodies overlapping.
    const SolidSurface a = icosphere(Vec3(0.4, 0.5, 0.5), 0.15, 1, 0);
    const SolidSurface b = icosphere(Vec3(0.6, 0.5, 0.5), 0.15, 1, 1);
    msg = message_of<MeshError>([&] { remesh(d, {a, b}, s); });
    CHECK(msg.find("bodies 0 and 1 overlap") != std::string::npos);
    CHECK(msg.find("triangle") != std::string::npos);
    // One inside the other without touching.
    const SolidSurface small = icosphere(Vec3(0.4, 0.5, 0.5), 0.05, 1, 1);
    msg = message_of<MeshError>([&] { remesh(d, {a, small}, s); });
    CHECK(msg.find("body 1 lies inside body 0") != std::string::npos);
    // A self-intersecting surface: one vertex pushed through the far side of the sphere.
    SolidSurface folded = icosphere(Vec3(0.5, 0.5, 0.5), 0.2, 1, 2);
    folded.vertices.row(0) = Eigen::RowVector3d(0.5, 0.5, 0.5) -
                             1.5 * (folded.vertices.row(0) - Eigen::RowVector3d(0.5, 0.5, 0.5));
    msg = message_of<MeshError>([&] { remesh(d, {folded}, s); });
    CHECK(msg.find("body 2") != std::string::npos);
    CHECK(msg.find("intersects itself") != std::string::npos);
    MESSAGE(msg);
    // An open surface.
    SolidSurface open = icosphere(Vec3(0.5, 0.5, 0.5), 0.2, 1, 4);
    open.triangles.conservativeResize(open.triangles.rows() - 1, 3);
    msg = message_of<MeshError>([&] { remesh(d, {open}, s); });
    CHECK(msg.find("body 4") != std::string::npos);
    // Bad sizing.
    Sizing bad = s;
    bad.surface_size = std::nan("");
    CHECK(message_of<InputError>([&] { remesh(d, {}, bad); }).find("surface_size") !=
          std::string::npos);
    bad = s;
    bad.far_size = 0.01;
    CHECK(message_of<InputError>([&] { remesh(d, {}, bad); }).find("far_size") !=
          std::string::npos);
    bad = s;
    bad.grading = 0;
    CHECK(message_of<InputError>([&] { remesh(d, {}, bad); }).find("grading") != std::string::npos);
    for (const std::string& m : {msg}) CHECK(m.find('\n') == std::string::npos);
  }

}  // TEST_SUITE
