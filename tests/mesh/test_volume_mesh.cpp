/// Tests of mesh/volume_mesh.cpp and mesh/generate.cpp: box generation, volumes, boundary
/// extraction, validation messages.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "mesh/volume_mesh.hpp"
#include "tests/test_util.hpp"

using tetfsi::test::message_of;
using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

/// Surface of a tet mesh's boundary as a SurfaceMesh (same vertex array).
SurfaceMesh boundary_surface(const VolumeMesh& m) {
  return SurfaceMesh{m.vertices, boundary_triangles(m)};
}

/// Σ over triangles of (area-weighted normal) · centroid = ∫ x·n dA = 3 V (divergence theorem).
double flux_of_position(const SurfaceMesh& s) {
  double sum = 0.0;
  for (Index f = 0; f < s.num_triangles(); ++f) {
    const Vec3 a = s.vertices.row(s.triangles(f, 0)), b = s.vertices.row(s.triangles(f, 1)),
               c = s.vertices.row(s.triangles(f, 2));
    sum += 0.5 * (b - a).cross(c - a).dot((a + b + c) / 3.0);
  }
  return sum;
}

}  // namespace

TEST_CASE("make_box: counts, exact volume, all tets positive, vertex numbering") {
  const Vec3 lo(-0.3, 0.1, 2.0), hi(0.9, 0.35, 2.7);
  const Vec3i cells(4, 3, 5);
  const VolumeMesh m = make_box(lo, hi, cells);
  CHECK(m.num_vertices() == 5 * 4 * 6);
  CHECK(m.num_tets() == 6 * 4 * 3 * 5);
  const double box_volume = (hi - lo).prod();
  // Sum of 360 tet volumes: rounding ~1e-15 relative; 1e-12 leaves room.
  CHECK(std::abs(total_volume(m) - box_volume) <= 1e-12 * box_volume);
  const double cell_volume = box_volume / 60.0;
  for (Index t = 0; t < m.num_tets(); ++t) {
    // Every Kuhn tet has exactly 1/6 of its cell's volume.
    CHECK(tet_volume(m, t) == doctest::Approx(cell_volume / 6.0).epsilon(1e-12));
  }
  // Vertex (i, j, k) = i + (nx+1)(j + (ny+1) k).
  const Index v = 3 + 5 * (2 + 4 * 4);
  CHECK(m.vertices(v, 0) == doctest::Approx(lo.x() + 3 * 0.3).epsilon(1e-14));
  CHECK(m.vertices(v, 1) == doctest::Approx(lo.y() + 2 * 0.25 / 3).epsilon(1e-14));
  CHECK(m.vertices(v, 2) == doctest::Approx(lo.z() + 4 * 0.14).epsilon(1e-14));
  CHECK(m.vertices.row(m.num_vertices() - 1) == hi.transpose());
  CHECK_NOTHROW(validate_volume_mesh(m, "box"));
}

TEST_CASE("make_box: bad arguments are InputErrors") {
  CHECK_THROWS_AS(make_box(Vec3(0, 0, 0), Vec3(1, 0, 1), Vec3i(1, 1, 1)), InputError);
  CHECK_THROWS_AS(make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 0, 1)), InputError);
}

TEST_CASE("boundary_triangles of a box: count, outward, closed, conforming") {
  const Vec3 lo(0, 0, 0), hi(2.0, 1.0, 0.5);
  const int nx = 5, ny = 3, nz = 2;
  const VolumeMesh m = make_box(lo, hi, Vec3i(nx, ny, nz));
  VecXi owner;
  const MatX3i b = boundary_triangles(m, &owner);
  // Each boundary quad is two triangles; interior faces are shared (conforming split).
  CHECK(b.rows() == 2 * 2 * (nx * ny + ny * nz + nz * nx));
  REQUIRE(owner.size() == b.rows());
  const SurfaceMesh s{m.vertices, b};
  const double volume = (hi - lo).prod();
  // Divergence theorem: ∫ x·n dA = 3 V; sums of ~124 products, 1e-12 relative.
  CHECK(std::abs(flux_of_position(s) - 3.0 * volume) <= 1e-12 * 3.0 * volume);
  CHECK_NOTHROW(validate_closed_surface(s, "box boundary"));
  // Owner tet contains the triangle; every boundary vertex lies on the box surface.
  for (Index f = 0; f < b.rows(); ++f) {
    std::set<int> tv(m.tets.row(owner(f)).data(), m.tets.row(owner(f)).data() + 4);
    for (int k = 0; k < 3; ++k) {
      CHECK(tv.count(b(f, k)) == 1);
      const Vec3 p = m.vertices.row(b(f, k));
      const bool on_face =
          (p - lo).cwiseAbs().minCoeff() < 1e-15 || (p - hi).cwiseAbs().minCoeff() < 1e-15;
      CHECK(on_face);
    }
  }
}

TEST_CASE("boundary_triangles: a single tet has its four faces, outward") {
  VolumeMesh m;
  m.vertices = MatX3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.tets = MatX4i{{0, 1, 2, 3}};
  REQUIRE(tet_volume(m, 0) == doctest::Approx(1.0 / 6.0).epsilon(1e-15));
  const SurfaceMesh s = boundary_surface(m);
  CHECK(s.num_triangles() == 4);
  CHECK(flux_of_position(s) == doctest::Approx(3.0 / 6.0).epsilon(1e-14));
}

TEST_CASE("boundary_triangles: a face shared by three tets is a MeshError") {
  VolumeMesh m;
  m.vertices = MatX3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}, {0.1, 0.1, 2}};
  m.tets = MatX4i{{0, 1, 2, 3}, {0, 2, 1, 4}, {0, 1, 2, 5}};
  const std::string msg = message_of<MeshError>([&] { boundary_triangles(m); });
  CHECK(msg.find("non-manifold") != std::string::npos);
  CHECK(msg.find("face (vertices 0 1 2) is shared by tets 0, 1, 2") != std::string::npos);
}

TEST_CASE("validate_volume_mesh: an inverted tet is named with its vertices and volume") {
  VolumeMesh m = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(2, 2, 2));
  const Index bad = 17;
  m.tets.row(bad) = Vec4i(m.tets(bad, 0), m.tets(bad, 1), m.tets(bad, 3), m.tets(bad, 2));
  const std::string msg = message_of<MeshError>([&] { validate_volume_mesh(m, "bar.msh"); });
  INFO(msg);
  CHECK(msg.rfind("bar.msh: tet 17 (vertices ", 0) == 0);
  CHECK(msg.find(fmt::format("{} {} {} {}", m.tets(bad, 0), m.tets(bad, 1), m.tets(bad, 2),
                             m.tets(bad, 3))) != std::string::npos);
  CHECK(msg.find("inverted") != std::string::npos);
  CHECK(msg.find("-0.0208") != std::string::npos);  // -1/48 m^3
  CHECK(msg.find('\n') == std::string::npos);
  // One tet flipped: fix_global_orientation leaves the mesh alone.
  CHECK_FALSE(fix_global_orientation(m));
}

TEST_CASE("validate_volume_mesh: degenerate, repeated vertex, bad index, non-finite, empty") {
  VolumeMesh m;
  m.vertices = MatX3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.5, 0.5, 0}};
  m.tets = MatX4i{{0, 1, 2, 3}, {0, 1, 2, 4}};  // tet 1 is flat
  std::string msg = message_of<MeshError>([&] { validate_volume_mesh(m, "flat"); });
  CHECK(msg.find("tet 1 (vertices 0 1 2 4) is degenerate") != std::string::npos);
  m.tets.row(1) = Vec4i(0, 1, 1, 3);
  msg = message_of<MeshError>([&] { validate_volume_mesh(m, "rep"); });
  CHECK(msg.find("tet 1 (vertices 0 1 1 3) uses a vertex twice") != std::string::npos);
  m.tets.row(1) = Vec4i(0, 1, 2, 7);
  msg = message_of<MeshError>([&] { validate_volume_mesh(m, "idx"); });
  CHECK(msg.find("tet 1 refers to vertex index 7") != std::string::npos);
  m.tets.conservativeResize(1, 4);
  m.vertices(4, 2) = std::nan("");
  msg = message_of<MeshError>([&] { validate_volume_mesh(m, "nan"); });
  CHECK(msg.find("vertex 4 has a non-finite coordinate") != std::string::npos);
  VolumeMesh empty;
  CHECK_THROWS_AS(validate_volume_mesh(empty, "empty"), MeshError);
}

TEST_CASE("validate_volume_mesh: labels print the file's ids") {
  VolumeMesh m;
  m.vertices = MatX3{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.tets = MatX4i{{0, 2, 1, 3}};
  MeshLabels labels{{10, 20, 30, 40}, {99}};
  const std::string msg = message_of<MeshError>([&] { validate_volume_mesh(m, "f.msh", labels); });
  CHECK(msg.rfind("f.msh: element 99 (nodes 10 30 20 40) is inverted", 0) == 0);
}

TEST_CASE("fix_global_orientation and remove_unused_vertices") {
  VolumeMesh m = make_box(Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3i(2, 1, 3));
  const double v = total_volume(m);
  m.tets.col(0).swap(m.tets.col(1));  // every tet negative
  CHECK(total_volume(m) == doctest::Approx(-v).epsilon(1e-12));
  CHECK(fix_global_orientation(m));
  CHECK(total_volume(m) == doctest::Approx(v).epsilon(1e-12));
  CHECK_NOTHROW(validate_volume_mesh(m, "flipped"));
  CHECK_FALSE(fix_global_orientation(m));

  // Keep only the first 6 tets (one cell): 8 of the box's vertices remain.
  const MatX3 before = m.vertices;
  m.tets.conservativeResize(6, 4);
  VecXi old_index;
  CHECK(remove_unused_vertices(m, &old_index) == before.rows() - 8);
  CHECK(m.num_vertices() == 8);
  REQUIRE(old_index.size() == 8);
  CHECK(std::is_sorted(old_index.data(), old_index.data() + 8));
  for (Index i = 0; i < 8; ++i) CHECK(m.vertices.row(i) == before.row(old_index(i)));
  CHECK(m.tets.maxCoeff() == 7);
  CHECK(total_volume(m) == doctest::Approx(1.0).epsilon(1e-12));  // one 1 x 2 x 1 cell
}

TEST_CASE("validate_closed_surface: open, inconsistent, inward, degenerate") {
  const VolumeMesh m = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1));
  SurfaceMesh s = boundary_surface(m);
  REQUIRE(s.num_triangles() == 12);
  CHECK_NOTHROW(validate_closed_surface(s, "cube"));

  SurfaceMesh open = s;
  open.triangles.conservativeResize(11, 3);
  std::string msg = message_of<MeshError>([&] { validate_closed_surface(open, "open.off"); });
  INFO(msg);
  CHECK(msg.rfind("open.off: edge (", 0) == 0);
  CHECK(msg.find("open") != std::string::npos);

  SurfaceMesh flipped_one = s;
  flipped_one.triangles.row(3) = Vec3i(s.triangles(3, 0), s.triangles(3, 2), s.triangles(3, 1));
  msg = message_of<MeshError>([&] { validate_closed_surface(flipped_one, "one.stl"); });
  CHECK(msg.find("inconsistently oriented") != std::string::npos);

  SurfaceMesh inward = s;
  inward.triangles.col(1).swap(inward.triangles.col(2));
  msg = message_of<MeshError>([&] { validate_closed_surface(inward, "in.obj"); });
  CHECK(msg.find("inward") != std::string::npos);

  SurfaceMesh degenerate = s;
  degenerate.triangles(5, 2) = degenerate.triangles(5, 1);
  msg = message_of<MeshError>([&] { validate_closed_surface(degenerate, "deg.off"); });
  CHECK(msg.find("triangle 5") != std::string::npos);
  CHECK(msg.find("degenerate") != std::string::npos);
}

TEST_CASE("boundary_triangles of a 750k-tet box: face count and enclosed volume") {
  const VolumeMesh m = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(50, 50, 50));
  const MatX3i b = boundary_triangles(m);
  CHECK(b.rows() == 2 * 2 * 3 * 50 * 50);
  // Volume via the boundary: Σ x·n dA / 3 = 1 (divergence theorem), 1e-10 relative for 30k terms.
  CHECK(flux_of_position(SurfaceMesh{m.vertices, b}) / 3.0 == doctest::Approx(1.0).epsilon(1e-10));
}
