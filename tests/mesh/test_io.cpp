/// Tests of mesh/io.cpp: every reader on its sample in data/meshes (made by
/// data/meshes/make_samples.py), the Gmsh writer round trip, and the error messages.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "mesh/volume_mesh.hpp"
#include "tests/test_util.hpp"

using tetfsi::test::contains;
using tetfsi::test::message_of;
using namespace tetfsi;
using namespace tetfsi::mesh;
namespace fs = std::filesystem;

namespace {

const fs::path kData = fs::path(TETFSI_SOURCE_DIR) / "data" / "meshes";

/// A fresh scratch directory for files the tests write.
fs::path scratch_dir() {
  const fs::path dir = fs::path(TETFSI_BINARY_DIR) / "test_mesh_tmp";
  fs::create_directories(dir);
  return dir;
}

fs::path write_text(const std::string& name, const std::string& text) {
  const fs::path p = scratch_dir() / name;
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

/// Volume enclosed by a closed outward surface: Σ a·(b×c)/6.
double enclosed_volume(const SurfaceMesh& s) {
  double v = 0.0;
  for (Index f = 0; f < s.num_triangles(); ++f) {
    const Vec3 a = s.vertices.row(s.triangles(f, 0)), b = s.vertices.row(s.triangles(f, 1)),
               c = s.vertices.row(s.triangles(f, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

/// The sample bar: 1 x 0.1 x 0.1 m, 10 Kuhn-split cubes.
void check_bar(const VolumeMesh& m) {
  CHECK(m.num_vertices() == 44);  // the file's 45th node is unused and dropped
  CHECK(m.num_tets() == 60);
  // 60 tets of 1/6000 m^3 each; rounding ~1e-16 relative, 1e-12 asked.
  CHECK(std::abs(total_volume(m) - 0.01) <= 1e-12 * 0.01);
  CHECK(boundary_triangles(m).rows() == 2 * 2 * (10 * 1 + 1 * 1 + 1 * 10));
  for (Index t = 0; t < m.num_tets(); ++t) CHECK(tet_volume(m, t) > 0.0);
}

}  // namespace

TEST_CASE("read Gmsh 2.2 and 4.1 samples: counts, volume, identical meshes") {
  const VolumeMesh v2 = read_volume_mesh(kData / "bar_v2.msh");
  const VolumeMesh v4 = read_volume_mesh(kData / "bar_v4.msh");
  check_bar(v2);
  check_bar(v4);
  CHECK(v2.vertices == v4.vertices);  // exact: same decimal text in both files
  CHECK(v2.tets == v4.tets);
}

TEST_CASE("read TetGen .node/.ele (globally inverted, 1-based) and .vtu: same mesh as Gmsh") {
  const VolumeMesh ref = read_volume_mesh(kData / "bar_v2.msh");
  const VolumeMesh from_node = read_volume_mesh(kData / "bar.node");
  const VolumeMesh from_ele = read_volume_mesh(kData / "bar.ele");
  check_bar(from_node);
  CHECK(from_node.vertices == ref.vertices);
  CHECK(from_node.tets == ref.tets);  // flipped back by swapping the last two vertices
  CHECK(from_ele.tets == from_node.tets);
  const VolumeMesh vtu = read_volume_mesh(kData / "bar.vtu");
  check_bar(vtu);
  CHECK(vtu.vertices == ref.vertices);
  CHECK(vtu.tets == ref.tets);
}

TEST_CASE("small hand-written files: 0-based TetGen, CRLF Gmsh, tabs and comments") {
  write_text("one.ele", "# zero-based\n1 4 0\n0\t0 1 2 3\n");
  const fs::path node =
      write_text("one.node", "4 3 0 0 # header\n0 0 0 0\n1 2 0 0\n\n2 0 2 0\n3 0 0 2\n");
  const VolumeMesh tg = read_volume_mesh(node);
  CHECK(tg.num_tets() == 1);
  CHECK(total_volume(tg) == doctest::Approx(8.0 / 6.0).epsilon(1e-15));

  const fs::path crlf =
      write_text("crlf.msh",
                 "$MeshFormat\r\n2.2 0 8\r\n$EndMeshFormat\r\n$Nodes\r\n4\r\n1 0 0 0\r\n2 1 0 0\r\n"
                 "3 0 1 0\r\n4 0 0 1\r\n$EndNodes\r\n$Elements\r\n1\r\n1 4 0 1 2 3 4\r\n"
                 "$EndElements\r\n");
  const VolumeMesh g = read_volume_mesh(crlf);
  CHECK(g.num_tets() == 1);
  CHECK(total_volume(g) == doctest::Approx(1.0 / 6.0).epsilon(1e-15));
}

TEST_CASE("write_msh / read_volume_mesh round trip is exact") {
  const VolumeMesh m = make_box(Vec3(-0.1, 1.0 / 3.0, 2e-3), Vec3(0.7, 0.9, 0.05), Vec3i(3, 2, 4));
  const fs::path p = scratch_dir() / "roundtrip.msh";
  write_msh(m, p);
  const VolumeMesh r = read_volume_mesh(p);
  CHECK(r.vertices == m.vertices);  // shortest round-trip decimal: bit-exact
  CHECK(r.tets == m.tets);
  CHECK_THROWS_AS(write_msh(m, scratch_dir() / "no_such_dir" / "x.msh"), InputError);
}

TEST_CASE("an inverted tet in a file: MeshError naming file, element, nodes, 'inverted'") {
  const fs::path p = kData / "bar_inverted.msh";
  const std::string msg = message_of<MeshError>([&] { read_volume_mesh(p); });
  INFO(msg);
  // The 23rd tet is element 26 of the file (3 non-tet elements come first).
  CHECK(msg.rfind(p.string() + ": element 26 (nodes ", 0) == 0);
  CHECK(contains(msg, "is inverted (signed volume -0.000167 m^3)"));  // -1/6000
  CHECK(contains(msg, "fix the element's vertex order or remesh"));
  CHECK_FALSE(contains(msg, "\n"));
}

TEST_CASE("missing files are InputErrors naming the file") {
  const fs::path p = kData / "no_such_mesh.msh";
  CHECK(message_of<InputError>([&] { read_volume_mesh(p); }) == p.string() + ": no such file");
  const fs::path s = kData / "no_such_surface.stl";
  CHECK(message_of<InputError>([&] { read_surface_mesh(s); }) == s.string() + ": no such file");
  // TetGen: the .ele partner of an existing .node is missing.
  const fs::path node = write_text("lonely.node", "1 3 0 0\n1 0 0 0\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(node); }),
                 (scratch_dir() / "lonely.ele").string() + ": no such file"));
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(kData / "bar_v2.xyz"); }),
                 "no such file"));
}

TEST_CASE("syntax errors name path:line and what was expected") {
  const fs::path bad_coord = write_text(
      "bad_coord.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n2 0 0 zero\n");
  CHECK(message_of<InputError>([&] { read_volume_mesh(bad_coord); }) ==
        bad_coord.string() + ":7: expected x y z coordinates, got '2 0 0 zero'");

  const fs::path binary = write_text("binary.msh", "$MeshFormat\n4.1 1 8\n\x01\0\0\0\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(binary); }),
                 "binary .msh is not supported; re-save as ASCII"));

  const fs::path unknown_node = write_text(
      "unknown_node.msh",
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
      "$EndNodes\n$Elements\n1\n7 4 2 0 1 1 2 3 9\n$EndElements\n");
  CHECK(message_of<InputError>([&] { read_volume_mesh(unknown_node); }) ==
        unknown_node.string() + ":13: element 7 refers to node 9, which $Nodes does not define");

  const fs::path truncated =
      write_text("truncated.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n");
  CHECK(message_of<InputError>([&] { read_volume_mesh(truncated); }) ==
        truncated.string() + ":7: expected a node line 'tag x y z', got end of file");

  const fs::path old = write_text("old.msh", "$MeshFormat\n4 0 8\n$EndMeshFormat\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(old); }), "re-save as ASCII"));

  const fs::path obj = write_text("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  CHECK(message_of<InputError>([&] { read_surface_mesh(obj); }) ==
        obj.string() +
            ":4: face vertex 4 refers to vertex 4, but only 3 vertices are defined so far");

  const fs::path vtu =
      write_text("truncated.vtu",
                 "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n"
                 "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"1\"><Points>\n");
  const std::string vtu_msg = message_of<InputError>([&] { read_volume_mesh(vtu); });
  INFO(vtu_msg);
  CHECK(vtu_msg.rfind(vtu.string() + ": VTK could not read the file: Error parsing XML in stream "
                                     "at line 4",
                      0) == 0);
  CHECK_FALSE(contains(vtu_msg, "\n"));
  const fs::path not_vtu = write_text("poly.vtu", "<VTKFile type=\"PolyData\"></VTKFile>\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(not_vtu); }),
                 "not a VTK XML UnstructuredGrid file"));

  const fs::path v1 = write_text("v1.msh", "$NOD\n1\n1 0 0 0\n$ENDNOD\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(v1); }), "version 1"));

  const fs::path tg = write_text("bad_header.node", "4 2 0 0\n");
  write_text("bad_header.ele", "0 4 0\n");
  CHECK(message_of<InputError>([&] { read_volume_mesh(tg); }) ==
        tg.string() + ":1: expected dimension 3, got 2");

  const fs::path stl = write_text("bad.stl", "not an stl\n");
  CHECK(contains(message_of<InputError>([&] { read_surface_mesh(stl); }), "not an STL file"));
}

TEST_CASE("hostile header counts: negative or beyond the file's size, before any allocation") {
  // [issue 21 item 4] A count the file cannot hold must not reserve gigabytes or loop for
  // hours: it is a one-line error naming the file, the line and the header.
  const fs::path neg_off = write_text("neg.off", "OFF\n-3 1 0\n0 0 0\n");
  CHECK(message_of<InputError>([&] { read_surface_mesh(neg_off); }) ==
        neg_off.string() + ":2: #vertices is negative (-3); fix the header");
  const fs::path huge_off = write_text("huge.off", "OFF\n3 4000000000000 0\n0 0 0\n");
  const std::string off_msg = message_of<InputError>([&] { read_surface_mesh(huge_off); });
  CHECK(off_msg.rfind(huge_off.string() + ":2: #faces announces 4000000000000 faces", 0) == 0);
  CHECK(contains(off_msg, "fix the header"));

  const fs::path huge_msh = write_text(
      "huge.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n9223372036854775807\n1 0 0 0\n");
  const std::string msh_msg = message_of<InputError>([&] { read_volume_mesh(huge_msh); });
  CHECK(msh_msg.rfind(huge_msh.string() + ":5: the number of nodes announces", 0) == 0);
  const fs::path neg_msh4 =
      write_text("neg4.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 -4 1 4\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(neg_msh4); }),
                 ":5: numNodes is negative (-4)"));
  // Beyond long long altogether: not a number the header can mean.
  const fs::path over = write_text("over.node", "99999999999999999999999 3 0 0\n");
  write_text("over.ele", "0 4 0\n");
  CHECK(contains(message_of<InputError>([&] { read_volume_mesh(over); }), over.string() + ":1:"));
}

TEST_CASE("surface readers: OFF icosphere, OBJ and STL cubes") {
  const SurfaceMesh ico = read_surface_mesh(kData / "icosphere.off");
  CHECK(ico.num_vertices() == 162);
  CHECK(ico.num_triangles() == 320);
  CHECK_NOTHROW(validate_closed_surface(ico, "icosphere.off"));
  // Inscribed in the sphere of radius 0.5: a little less than 4/3 π r³ (0.5236); 2
  // subdivisions lose about 4 %.
  const double sphere = 4.0 / 3.0 * M_PI * 0.125;
  CHECK(enclosed_volume(ico) < sphere);
  CHECK(enclosed_volume(ico) > 0.95 * sphere);

  const SurfaceMesh obj = read_surface_mesh(kData / "cube.obj");
  const SurfaceMesh stl = read_surface_mesh(kData / "cube.stl");
  const SurfaceMesh bin = read_surface_mesh(kData / "cube_binary.stl");  // header "solid ..."
  for (const SurfaceMesh* s : {&obj, &stl, &bin}) {
    CHECK(s->num_vertices() == 8);    // STL corners merged exactly
    CHECK(s->num_triangles() == 12);  // 6 quads fan-split
    CHECK_NOTHROW(validate_closed_surface(*s, "cube"));
    CHECK(std::abs(enclosed_volume(*s) - 1.0) <= 1e-15);  // unit cube, exact arithmetic
  }
  CHECK(stl.vertices == bin.vertices);
  CHECK(stl.triangles == bin.triangles);

  // Counts on the header line, polygons, comments.
  const fs::path tet = write_text("tet.off",
                                  "OFF 4 4 0 # a tetrahedron\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                                  "3 0 2 1\n3 0 1 3\n3 1 2 3\n3 0 3 2\n");
  const SurfaceMesh t = read_surface_mesh(tet);
  CHECK(t.num_triangles() == 4);
  CHECK(enclosed_volume(t) == doctest::Approx(1.0 / 6.0).epsilon(1e-15));
}

TEST_CASE("an open surface: MeshError naming file and edge") {
  const fs::path p = kData / "open_cube.off";
  const SurfaceMesh s = read_surface_mesh(p);
  CHECK(s.num_triangles() == 10);
  const std::string msg = message_of<MeshError>([&] { validate_closed_surface(s, p.string()); });
  INFO(msg);
  CHECK(msg.rfind(p.string() + ": edge (", 0) == 0);
  CHECK(contains(msg, "belongs to only one triangle"));
  CHECK(contains(msg, "open"));
}
