// Tests of io/output.cpp: .vtu / .vti frames read back with VTK's own readers, .pvd
// collections parsed with VTK's XML parser, stats.csv shape, output-folder layout and atomic
// writes.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLDataParser.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "io/output.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "mesh/quality.hpp"
#include "mesh/tet_mesh.hpp"
#include "scene/scene.hpp"
#include "solid/world.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;

namespace {

/// A fresh, empty folder for one test case (removed by the destructor).
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name) {
    path = fs::temp_directory_path() / fmt::format("tetfsi_test_output_{}_{}", name, getpid());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

/// A 3×2×1-cell box (24 nodes, 36 tets) with a smooth nonzero displacement and velocity, an
/// applied force on one node, node 0 pinned and node 1 fixed in z.
solid::SolidBody make_test_body(double phase = 0.0) {
  mesh::VolumeMesh m = mesh::make_box(Vec3(0, 0, 0), Vec3(1.5, 1.0, 0.5), Vec3i(3, 2, 1));
  solid::Material mat;
  mat.density = 800.0;
  mat.youngs_modulus = 2e5;
  solid::SolidBody b("block", std::move(m), mat);
  const MatX3& X = b.rest_positions();
  for (Index i = 0; i < b.num_nodes(); ++i) {
    b.displacement.row(i) = Vec3(0.01 * X(i, 0) * X(i, 2) + phase,
                                 -0.02 * std::sin(X(i, 1) + phase), 0.03 * X(i, 0) * X(i, 0));
    b.velocity.row(i) = Vec3(std::cos(0.3 * i + phase), 1e-3 * i, -2.5 + 0.1 * X(i, 2));
  }
  b.applied_force.row(5) = Vec3(1.0, -2.0, 3.0);
  b.pin_node(0);
  b.fix_dof(1, 2);
  return b;
}

/// Restores the thread count in force at construction.
struct ThreadCountGuard {
  int saved = thread_count();
  ~ThreadCountGuard() { set_thread_count(saved); }
};

/// Read a .vtu with VTK's reader; fails the test if the reader reports an error.
vtkSmartPointer<vtkUnstructuredGrid> read_vtu(const fs::path& p) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkSmartPointer<vtkUnstructuredGrid> g = r->GetOutput();
  REQUIRE(g != nullptr);
  return g;
}

/// A fluid mesh of the box [0, 1] × [0, 1] × [0, 0.5] (2 × 2 × 2 cells, 48 tets, 27 vertices)
/// whose bottom faces (z = 0, 8 triangles of total area 1 m²) are made Solid faces of body 1
/// by hand, as the remesher would tag them; their vertices get vertex_body = 1. One vertex is
/// moved off the lattice so the quality fields vary from tet to tet.
mesh::TetMesh make_fluid_mesh() {
  mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 0.5), Vec3i(2, 2, 2));
  box.vertices.row(13) += Vec3(0.05, -0.03, 0.02).transpose();  // the centre vertex
  mesh::TetMesh m = mesh::build_tet_mesh(box.vertices, box.tets);
  Index k = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (!m.is_boundary(f) || std::abs(m.face_centroids(f, 2)) > 1e-12) continue;
    m.face_kind[static_cast<size_t>(f)] = mesh::FaceKind::Solid;
    m.face_body[f] = 1;
    m.face_triangle[f] = 10 + k;
    m.face_bary.row(f) = Vec3(0.2, 0.3, 0.5).transpose() + Vec3(0.01, -0.01, 0.0).transpose() * k;
    for (int c = 0; c < 3; ++c) m.vertex_body[m.faces(f, c)] = 1;
    ++k;
  }
  REQUIRE(k == 8);
  return m;
}

/// Read a .vtp with VTK's reader; fails the test if the reader reports an error.
vtkSmartPointer<vtkPolyData> read_vtp(const fs::path& p) {
  vtkNew<vtkXMLPolyDataReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkSmartPointer<vtkPolyData> g = r->GetOutput();
  REQUIRE(g != nullptr);
  return g;
}

/// Max |a − b| between a 1-component VTK array and `v`.
double max_diff(vtkDataArray* a, const VecX& v) {
  REQUIRE(a != nullptr);
  REQUIRE(a->GetNumberOfComponents() == 1);
  REQUIRE(a->GetNumberOfTuples() == v.size());
  double m = 0.0;
  for (Index i = 0; i < v.size(); ++i) m = std::max(m, std::abs(a->GetComponent(i, 0) - v[i]));
  return m;
}

/// Max |a − b| between a 3-component VTK array and n × 3 row-major data.
double max_diff(vtkDataArray* a, const double* data, Index n) {
  REQUIRE(a != nullptr);
  REQUIRE(a->GetNumberOfComponents() == 3);
  REQUIRE(a->GetNumberOfTuples() == n);
  double m = 0.0;
  for (Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) m = std::max(m, std::abs(a->GetComponent(i, k) - data[3 * i + k]));
  return m;
}

struct ParsedPvd {
  std::string type;
  std::vector<double> times;
  std::vector<std::string> files;
};

/// Parse a .pvd with VTK's XML parser (the one ParaView's readers are built on).
ParsedPvd parse_pvd(const fs::path& p) {
  vtkNew<vtkXMLDataParser> parser;
  parser->SetFileName(p.c_str());
  REQUIRE(parser->Parse() == 1);
  vtkXMLDataElement* root = parser->GetRootElement();
  REQUIRE(root != nullptr);
  REQUIRE(std::string(root->GetName()) == "VTKFile");
  ParsedPvd out;
  out.type = root->GetAttribute("type") ? root->GetAttribute("type") : "";
  vtkXMLDataElement* coll = root->FindNestedElementWithName("Collection");
  REQUIRE(coll != nullptr);
  for (int i = 0; i < coll->GetNumberOfNestedElements(); ++i) {
    vtkXMLDataElement* ds = coll->GetNestedElement(i);
    REQUIRE(std::string(ds->GetName()) == "DataSet");
    REQUIRE(ds->GetAttribute("timestep") != nullptr);
    REQUIRE(ds->GetAttribute("file") != nullptr);
    out.times.push_back(std::stod(ds->GetAttribute("timestep")));
    out.files.emplace_back(ds->GetAttribute("file"));
  }
  return out;
}

std::vector<std::string> read_lines(const fs::path& p) {
  std::ifstream f(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(f, l);) lines.push_back(l);
  return lines;
}

size_t count_fields(const std::string& csv_line) {
  return static_cast<size_t>(std::count(csv_line.begin(), csv_line.end(), ',')) + 1;
}

bool has_tmp_files(const fs::path& dir) {
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.path().extension() == ".tmp") return true;
  return false;
}

std::string read_text(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A 3 × 4 × 5-cell grid frame from (−0.5, 0.25, 1/3) with spacing (0.6 / 3, 0.2, 0.3) m
/// whose cell fields are distinct functions of the cell index c = i + 3 (j + 4 k), every 7th
/// cell solid (1/3, 0.6 / 3 and the fields are not short decimals, so a bit-exact read-back
/// means every bit went through);
/// and as its interface the four outward triangles of a tetrahedron, two per body, with one
/// NaN pressure jump (a side without fluid).
GridFrameFields make_grid_frame() {
  GridFrameFields g;
  g.origin = Vec3(-0.5, 0.25, 1.0 / 3.0);
  g.spacing = Vec3(0.6 / 3.0, 0.2, 0.3);
  g.cells = {3, 4, 5};
  const Index nc = 60;
  g.pressure.resize(nc);
  g.density.resize(nc);
  g.temperature.resize(nc);
  g.divergence.resize(nc);
  g.vorticity.resize(nc);
  g.velocity.resize(nc, 3);
  g.solid.resize(nc);
  for (Index c = 0; c < nc; ++c) {
    g.pressure[c] = 1000.0 + c / 3.0;
    g.density[c] = std::sin(0.7 * c);
    g.temperature[c] = 293.15 + std::sqrt(static_cast<double>(c));
    g.divergence[c] = -1e-9 * c / 7.0;
    g.vorticity[c] = std::exp(0.05 * c);
    g.velocity.row(c) = Vec3(c / 11.0, -c / 13.0, std::cos(c));
    g.solid[static_cast<size_t>(c)] = c % 7 == 0 ? 1 : 0;
  }
  g.surface_points.resize(4, 3);
  g.surface_points << 0.1, 0.4, 1.2, 0.3, 0.4, 1.2, 0.1, 0.6, 1.2, 0.1, 0.4, 1.4;
  g.surface_triangles.resize(4, 3);
  g.surface_triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;  // normals −z, −y, −x, (1,1,1)/√3
  g.surface_body = VecXi(4);
  g.surface_body << 0, 0, 1, 1;
  g.surface_pressure = VecX(4);
  g.surface_pressure << 101325.0 / 3.0, -7.25, 0.0, 1e5 / 7.0;
  g.surface_pressure_jump = VecX(4);
  g.surface_pressure_jump << 12.5 / 3.0, std::nan(""), 0.0, -3.75;
  g.surface_force.resize(4, 3);
  for (Index p = 0; p < 4; ++p) g.surface_force.row(p) = Vec3(p / 3.0, -0.5 * p, 1.0 + p / 9.0);
  return g;
}

/// Read a .vti with VTK's reader; fails the test if the reader reports an error.
vtkSmartPointer<vtkImageData> read_vti(const fs::path& p) {
  vtkNew<vtkXMLImageDataReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkSmartPointer<vtkImageData> g = r->GetOutput();
  REQUIRE(g != nullptr);
  return g;
}

}  // namespace

TEST_CASE("write_body_vtu: every array reads back as written, for every compression") {
  TempDir dir("vtu");
  const Vec3 g(0.0, 0.0, -9.81);
  const solid::SolidBody body = make_test_body();
  const Index nv = body.num_nodes();
  const Index nt = body.num_tets();
  const VecX fe = body.external_forces(g);
  const MatX3 x = body.positions();
  const solid::TetFields fields = body.elasticity().tet_fields(x);

  for (const char* name : {"lz4", "zlib", "none"}) {
    CAPTURE(name);
    const Compression c = parse_compression(name);
    CHECK(to_string(c) == name);
    const fs::path p = dir.path / fmt::format("block_{}.vtu", name);
    write_body_vtu(p, body, g, c);
    CHECK(!has_tmp_files(dir.path));

    // The header names the compressor VTK used (none: no compressor attribute).
    const std::string text = read_text(p);
    const std::string head = text.substr(0, text.find("<AppendedData"));
    if (c == Compression::LZ4) CHECK(head.find("vtkLZ4DataCompressor") != std::string::npos);
    if (c == Compression::ZLib) CHECK(head.find("vtkZLibDataCompressor") != std::string::npos);
    if (c == Compression::None) CHECK(head.find("compressor=") == std::string::npos);
    CHECK(head.find("format=\"appended\"") != std::string::npos);
    CHECK(text.find("encoding=\"raw\"") != std::string::npos);

    auto grid = read_vtu(p);
    REQUIRE(grid->GetNumberOfPoints() == nv);
    REQUIRE(grid->GetNumberOfCells() == nt);

    // Points are the deformed positions X + d.
    double dx = 0.0;
    for (Index i = 0; i < nv; ++i) {
      double q[3];
      grid->GetPoint(i, q);
      for (int k = 0; k < 3; ++k) dx = std::max(dx, std::abs(q[k] - x(i, k)));
    }
    CHECK(dx <= 1e-12);

    // Cells are the body's tets, in order.
    bool cells_ok = true;
    for (Index t = 0; t < nt; ++t) {
      cells_ok = cells_ok && grid->GetCellType(t) == VTK_TETRA;
      vtkIdType npts = 0;
      const vtkIdType* pts = nullptr;
      grid->GetCellPoints(t, npts, pts);
      cells_ok = cells_ok && npts == 4;
      for (int k = 0; k < 4 && cells_ok; ++k) cells_ok = pts[k] == body.tets()(t, k);
    }
    CHECK(cells_ok);

    vtkPointData* pd = grid->GetPointData();
    CHECK(max_diff(pd->GetArray("displacement"), body.displacement.data(), nv) <= 1e-12);
    CHECK(max_diff(pd->GetArray("velocity"), body.velocity.data(), nv) <= 1e-12);
    CHECK(max_diff(pd->GetArray("external_force"), fe.data(), nv) <= 1e-12);
    CHECK(max_diff(pd->GetArray("rest_position"), body.rest_positions().data(), nv) <= 1e-12);
    // The applied force shows up on top of gravity at node 5.
    CHECK(pd->GetArray("external_force")->GetComponent(5, 0) ==
          doctest::Approx(1.0).epsilon(1e-12));

    vtkDataArray* fixed = pd->GetArray("fixed");
    REQUIRE(fixed != nullptr);
    CHECK(fixed->GetDataType() == VTK_UNSIGNED_CHAR);
    REQUIRE(fixed->GetNumberOfTuples() == nv);
    CHECK(fixed->GetComponent(0, 0) == 1.0);  // pinned
    CHECK(fixed->GetComponent(1, 0) == 1.0);  // z fixed only: still "any DOF fixed"
    double others = 0.0;
    for (Index i = 2; i < nv; ++i) others += fixed->GetComponent(i, 0);
    CHECK(others == 0.0);

    vtkCellData* cd = grid->GetCellData();
    const std::pair<const char*, const VecX*> cell_arrays[] = {
        {"green_strain_norm", &fields.green_strain_norm},
        {"von_mises_stress", &fields.von_mises_stress},
        {"volume_ratio", &fields.volume_ratio}};
    for (const auto& [aname, values] : cell_arrays) {
      CAPTURE(aname);
      vtkDataArray* a = cd->GetArray(aname);
      REQUIRE(a != nullptr);
      REQUIRE(a->GetNumberOfTuples() == nt);
      CHECK(a->GetNumberOfComponents() == 1);
      double d = 0.0;
      for (Index t = 0; t < nt; ++t)
        d = std::max(d, std::abs(a->GetComponent(t, 0) - (*values)[t]));
      CHECK(d <= 1e-12 * (1.0 + values->cwiseAbs().maxCoeff()));
    }
    // The body is deformed: strain is nonzero somewhere.
    CHECK(fields.green_strain_norm.maxCoeff() > 1e-4);
  }
}

TEST_CASE("write_body_vtu: an unwritable path is one InputError naming the file") {
  const solid::SolidBody body = make_test_body();
  const fs::path p = fs::path("/nonexistent_tetfsi_dir/sub/block.vtu");
  try {
    write_body_vtu(p, body, Vec3::Zero(), Compression::LZ4);
    FAIL("expected an InputError");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("block.vtu") != std::string::npos);
    CHECK(msg.find('\n') == std::string::npos);
  }
}

TEST_CASE(
    "write_fluid_vtu: points and tets with volume and quality and touches_solid and vertex_body") {
  TempDir dir("fluid_vtu");
  const mesh::TetMesh m = make_fluid_mesh();
  const mesh::TetQuality q = mesh::tet_quality(m.vertices, m.tets);
  const Index nv = m.num_vertices(), nt = m.num_tets();
  for (const char* name : {"lz4", "zlib", "none"}) {
    CAPTURE(name);
    const fs::path p = dir.path / fmt::format("fluid_{}.vtu", name);
    write_fluid_vtu(p, m, parse_compression(name));
    CHECK(!has_tmp_files(dir.path));
    auto grid = read_vtu(p);
    REQUIRE(grid->GetNumberOfPoints() == nv);
    REQUIRE(grid->GetNumberOfCells() == nt);
    double dx = 0.0;
    for (Index i = 0; i < nv; ++i) {
      double x[3];
      grid->GetPoint(i, x);
      for (int k = 0; k < 3; ++k) dx = std::max(dx, std::abs(x[k] - m.vertices(i, k)));
    }
    CHECK(dx == 0.0);
    bool cells_ok = true;
    for (Index t = 0; t < nt; ++t) {
      cells_ok = cells_ok && grid->GetCellType(t) == VTK_TETRA;
      vtkIdType npts = 0;
      const vtkIdType* pts = nullptr;
      grid->GetCellPoints(t, npts, pts);
      cells_ok = cells_ok && npts == 4;
      for (int k = 0; k < 4 && cells_ok; ++k) cells_ok = pts[k] == m.tets(t, k);
    }
    CHECK(cells_ok);

    vtkCellData* cd = grid->GetCellData();
    CHECK(max_diff(cd->GetArray("volume"), m.volumes) == 0.0);
    CHECK(max_diff(cd->GetArray("q_min_dihedral_deg"), q.min_dihedral_deg) == 0.0);
    CHECK(max_diff(cd->GetArray("q_max_dihedral_deg"), q.max_dihedral_deg) == 0.0);
    CHECK(max_diff(cd->GetArray("q_radius_edge"), q.radius_edge) == 0.0);
    CHECK(max_diff(cd->GetArray("q_shape"), q.shape) == 0.0);
    // The moved vertex makes the figures differ between tets.
    CHECK(q.min_dihedral_deg.maxCoeff() - q.min_dihedral_deg.minCoeff() > 1.0);
    CHECK(cd->GetArray("volume")->GetDataType() == VTK_DOUBLE);

    // touches_solid: 1 exactly for the tets with a vertex on z = 0.
    vtkDataArray* touches = cd->GetArray("touches_solid");
    REQUIRE(touches != nullptr);
    CHECK(touches->GetDataType() == VTK_UNSIGNED_CHAR);
    REQUIRE(touches->GetNumberOfTuples() == nt);
    int touching = 0;
    bool touches_ok = true;
    for (Index t = 0; t < nt; ++t) {
      bool low = false;
      for (int k = 0; k < 4; ++k) low = low || m.vertices(m.tets(t, k), 2) == 0.0;
      touches_ok = touches_ok && touches->GetComponent(t, 0) == (low ? 1.0 : 0.0);
      touching += low ? 1 : 0;
    }
    CHECK(touches_ok);
    CHECK(touching > 0);
    CHECK(touching < nt);

    vtkDataArray* vb = grid->GetPointData()->GetArray("vertex_body");
    REQUIRE(vb != nullptr);
    CHECK(vb->GetDataType() == VTK_INT);
    REQUIRE(vb->GetNumberOfTuples() == nv);
    int on_solid = 0;
    bool vb_ok = true;
    for (Index i = 0; i < nv; ++i) {
      vb_ok = vb_ok && vb->GetComponent(i, 0) == m.vertex_body[i];
      on_solid += vb->GetComponent(i, 0) == 1.0 ? 1 : 0;
    }
    CHECK(vb_ok);
    CHECK(on_solid == 9);  // the 3 × 3 vertices of the bottom
    CHECK(vb->GetComponent(13, 0) == -1.0);
  }
}

TEST_CASE(
    "write_fluid_vtu of 48k tets with fields: bit-exact arrays, VTK's ranges, the same bytes at 1 "
    "and 3 threads, and vtu_check passes") {
  // Arrays of up to 1.2 MB: dozens of 32 KiB blocks each, compressed in parallel.
  TempDir dir("fluid_vtu_big");
  const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(20, 20, 20));
  const mesh::TetMesh m = mesh::build_tet_mesh(box.vertices, box.tets);
  const Index nv = m.num_vertices(), nt = m.num_tets();
  REQUIRE(nt == 48000);
  FluidFrameFields f;
  f.pressure = VecX::LinSpaced(nt, -3.0, 5.0);
  f.density = f.pressure.array().sin();
  f.temperature = 300.0 + f.pressure.array().cos();
  f.vorticity = f.pressure.array().abs();
  f.divergence = 1e-9 * f.pressure;
  f.cell_velocity = MatX3(nt, 3);
  for (Index t = 0; t < nt; ++t) f.cell_velocity.row(t) = mesh::tet_centroid(m, t).transpose();
  f.vertex_velocity = -m.vertices;
  const ThreadCountGuard guard;
  for (const char* name : {"lz4", "zlib", "none"}) {
    CAPTURE(name);
    std::string bytes[2];
    for (const int threads : {1, 3}) {
      set_thread_count(threads);
      const fs::path p = dir.path / fmt::format("fluid_{}_{}.vtu", name, threads);
      write_fluid_vtu(p, m, parse_compression(name), &f);
      std::ifstream in(p, std::ios::binary);
      bytes[threads == 1 ? 0 : 1].assign(std::istreambuf_iterator<char>(in), {});
      CHECK_NOTHROW(mesh::check_vtk_xml_header(p));
    }
    CHECK(bytes[0] == bytes[1]);
    CHECK(!has_tmp_files(dir.path));
    auto grid = read_vtu(dir.path / fmt::format("fluid_{}_3.vtu", name));
    REQUIRE(grid->GetNumberOfPoints() == nv);
    REQUIRE(grid->GetNumberOfCells() == nt);
    vtkCellData* cd = grid->GetCellData();
    CHECK(max_diff(cd->GetArray("pressure"), f.pressure) == 0.0);
    CHECK(max_diff(cd->GetArray("smoke_density"), f.density) == 0.0);
    CHECK(max_diff(cd->GetArray("temperature"), f.temperature) == 0.0);
    CHECK(max_diff(cd->GetArray("divergence"), f.divergence) == 0.0);
    CHECK(max_diff(cd->GetArray("volume"), m.volumes) == 0.0);
    CHECK(max_diff(cd->GetArray("velocity"), f.cell_velocity.data(), nt) == 0.0);
    CHECK(max_diff(grid->GetPointData()->GetArray("velocity"), f.vertex_velocity.data(), nv) ==
          0.0);
    bool cells_ok = grid->GetCellType(nt - 1) == VTK_TETRA;
    for (Index t = 0; t < nt && cells_ok; ++t) {
      vtkIdType npts = 0;
      const vtkIdType* pts = nullptr;
      grid->GetCellPoints(t, npts, pts);
      cells_ok = npts == 4;
      for (int k = 0; k < 4 && cells_ok; ++k) cells_ok = pts[k] == m.tets(t, k);
    }
    CHECK(cells_ok);
    // RangeMin / RangeMax as VTK writes them: the values' range, the norms' for vectors
    // (printed to 11 significant digits).
    const std::string& text = bytes[1];
    const std::size_t at = text.find("Name=\"velocity\" NumberOfComponents=\"3\"");
    REQUIRE(at != std::string::npos);
    const std::string tag = text.substr(at, text.find('>', at) - at);
    const double norm_max = f.vertex_velocity.rowwise().norm().maxCoeff();
    CHECK(tag.find(fmt::format("RangeMax=\"{:.11g}\"", norm_max)) != std::string::npos);
    CHECK(tag.find("RangeMin=\"0\"") != std::string::npos);  // the vertex at the origin
  }
  // A file that cannot be written: one line naming it, and nothing left behind.
  const fs::path bad = dir.path / "no_such_dir" / "fluid.vtu";
  CHECK_THROWS_WITH_AS(write_fluid_vtu(bad, m, Compression::LZ4, &f),
                       doctest::Contains(bad.string().c_str()), InputError);
  CHECK(!fs::exists(dir.path / "no_such_dir"));
}

TEST_CASE("write_interface_vtp: the Solid faces only with compact points and their arrays") {
  TempDir dir("interface_vtp");
  const mesh::TetMesh m = make_fluid_mesh();
  std::vector<Index> solid;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.face_kind[static_cast<size_t>(f)] == mesh::FaceKind::Solid) solid.push_back(f);
  REQUIRE(solid.size() == 8);
  for (const char* name : {"lz4", "zlib", "none"}) {
    CAPTURE(name);
    const fs::path p = dir.path / fmt::format("interface_{}.vtp", name);
    write_interface_vtp(p, m, parse_compression(name));
    CHECK(!has_tmp_files(dir.path));
    auto poly = read_vtp(p);
    REQUIRE(poly->GetNumberOfCells() == 8);
    CHECK(poly->GetNumberOfPolys() == 8);
    CHECK(poly->GetNumberOfPoints() == 9);  // only the bottom's vertices

    vtkDataArray* fv = poly->GetPointData()->GetArray("fluid_vertex");
    REQUIRE(fv != nullptr);
    REQUIRE(fv->GetNumberOfTuples() == 9);
    vtkCellData* cd = poly->GetCellData();
    for (const char* a : {"body", "triangle", "area", "dual_length", "normal", "bary"})
      REQUIRE(cd->GetArray(a) != nullptr);
    CHECK(cd->GetArray("body")->GetDataType() == VTK_INT);
    CHECK(cd->GetArray("triangle")->GetDataType() == VTK_INT);
    CHECK(cd->GetArray("normal")->GetNumberOfComponents() == 3);
    CHECK(cd->GetArray("bary")->GetNumberOfComponents() == 3);

    double total_area = 0.0, diff = 0.0;
    bool cells_ok = true;
    for (Index i = 0; i < 8; ++i) {
      const Index f = solid[static_cast<size_t>(i)];
      // Each triangle is the face with its stored vertex order (so its normal is n_f), and
      // every point sits where its fluid vertex is.
      vtkIdType npts = 0;
      const vtkIdType* pts = nullptr;
      poly->GetCellPoints(i, npts, pts);
      cells_ok = cells_ok && npts == 3;
      for (int k = 0; k < 3 && cells_ok; ++k) {
        const Index v = static_cast<Index>(fv->GetComponent(pts[k], 0));
        cells_ok = v == m.faces(f, k);
        double x[3];
        poly->GetPoint(pts[k], x);
        for (int c = 0; c < 3; ++c) diff = std::max(diff, std::abs(x[c] - m.vertices(v, c)));
      }
      CHECK(cd->GetArray("body")->GetComponent(i, 0) == 1.0);
      CHECK(cd->GetArray("triangle")->GetComponent(i, 0) == m.face_triangle[f]);
      CHECK(cd->GetArray("area")->GetComponent(i, 0) == m.face_areas[f]);
      CHECK(cd->GetArray("dual_length")->GetComponent(i, 0) == m.dual_lengths[f]);
      for (int c = 0; c < 3; ++c) {
        diff = std::max(
            diff, std::abs(cd->GetArray("normal")->GetComponent(i, c) - m.face_normals(f, c)));
        diff =
            std::max(diff, std::abs(cd->GetArray("bary")->GetComponent(i, c) - m.face_bary(f, c)));
      }
      // Bottom faces: the normal points out of the fluid, down into the "solid".
      CHECK(cd->GetArray("normal")->GetComponent(i, 2) == doctest::Approx(-1.0).epsilon(1e-12));
      total_area += cd->GetArray("area")->GetComponent(i, 0);
    }
    CHECK(cells_ok);
    CHECK(diff == 0.0);
    CHECK(total_area == doctest::Approx(1.0).epsilon(1e-12));
  }

  // A mesh without solid faces gives an empty file that reads back.
  const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1));
  const mesh::TetMesh plain = mesh::build_tet_mesh(box.vertices, box.tets);
  write_interface_vtp(dir.path / "empty.vtp", plain, Compression::LZ4);
  auto empty = read_vtp(dir.path / "empty.vtp");
  CHECK(empty->GetNumberOfCells() == 0);
  CHECK(empty->GetNumberOfPoints() == 0);

  // An unwritable path is one InputError naming the file.
  try {
    write_interface_vtp("/nonexistent_tetfsi_dir/i.vtp", m, Compression::LZ4);
    FAIL("expected an InputError");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("i.vtp") != std::string::npos);
    CHECK(std::string(e.what()).find('\n') == std::string::npos);
  }
}

TEST_CASE("parse_compression rejects unknown names") {
  CHECK_THROWS_AS(parse_compression("gzip"), InputError);
  CHECK(file_safe_name("my body/1") == "my_body_1");
  CHECK(file_safe_name("") == "body");
}

TEST_CASE("PvdWriter: times and files read back after every frame") {
  TempDir dir("pvd");
  const fs::path pvd = dir.path / "block.pvd";
  PvdWriter w(pvd);
  CHECK(!fs::exists(pvd));  // nothing before the first frame
  const std::vector<double> times = {0.0, 0.5, 1.25, 0.1 + 0.2};
  for (size_t i = 0; i < times.size(); ++i) {
    w.add(times[i], fmt::format("block/block_{:06d}.vtu", i));
    // After every frame the file on disk is a complete collection of frames 0..i.
    const ParsedPvd p = parse_pvd(pvd);
    CHECK(p.type == "Collection");
    REQUIRE(p.times.size() == i + 1);
    for (size_t k = 0; k <= i; ++k) {
      CHECK(p.times[k] == times[k]);  // 17 significant digits: bit-identical
      CHECK(p.files[k] == fmt::format("block/block_{:06d}.vtu", k));
    }
  }
  CHECK(!has_tmp_files(dir.path));
  // Special characters in file names are escaped and read back intact.
  PvdWriter w2(dir.path / "odd.pvd");
  w2.add(2.0, "a&b/<c>\"d\".vtu");
  CHECK(parse_pvd(dir.path / "odd.pvd").files.at(0) == "a&b/<c>\"d\".vtu");
}

TEST_CASE("StatsWriter: header, then one row per step with every column") {
  TempDir dir("stats");
  const fs::path p = dir.path / "stats.csv";
  {
    StatsWriter s(p);
    for (int step = 1; step <= 4; ++step) {
      StepStats r;
      r.step = step;
      r.dt = 0.01;
      r.time = step * r.dt;
      r.phases.add("assemble", 0.001);
      r.phases.add("solve", 0.002);
      r.phases.add("update", 0.0005);
      r.phases.add("total", 0.004);
      r.solver_iterations = 1;
      r.kinetic_energy = 1.0;
      r.elastic_energy = 2.0;
      r.gravity_potential = -0.5;
      r.equilibrium_iterations = step + 1;
      r.equilibrium_evaluations = 3 * step;
      s.write(r);
      // Flushed per row: visible while the writer is still open.
      CHECK(read_lines(p).size() == static_cast<size_t>(step) + 1);
    }
  }
  const auto lines = read_lines(p);
  REQUIRE(lines.size() == 5);
  CHECK(lines[0] ==
        "step,time,dt,assemble,solve,update,output,total,solver_iterations,solver_residual,"
        "contacts,kinetic_energy,elastic_energy,gravity_potential,total_energy,"
        "equilibrium_iterations,equilibrium_evaluations");
  const size_t ncols = StatsWriter::columns().size();
  CHECK(ncols == 17);
  for (const auto& l : lines) CHECK(count_fields(l) == ncols);
  CHECK(lines[2].rfind("2,0.02,", 0) == 0);
  // total_energy (1 + 2 − 0.5), then the equilibrium iterations and evaluations, last.
  CHECK(lines[4].ends_with(",2.5,5,12"));
  // The "output" phase was never timed: its column is 0.
  CHECK(lines[1].find(",0,") != std::string::npos);
}

TEST_CASE("StatsWriter with bodies: three columns per body after every other column") {
  TempDir dir("stats_bodies");
  const fs::path p = dir.path / "stats.csv";
  const std::vector<std::string> bodies = {"block", "spin_top"};
  for (const bool fluid : {false, true}) {
    for (const bool coupled : {false, true}) {
      CAPTURE(fluid);
      CAPTURE(coupled);
      const auto fixed = StatsWriter::columns(fluid, coupled);
      const auto cols = StatsWriter::columns(fluid, coupled, bodies);
      // The columns without bodies keep their names and positions; the bodies' come last.
      REQUIRE(cols.size() == fixed.size() + 6);
      CHECK(std::vector<std::string>(cols.begin(), cols.begin() + fixed.size()) == fixed);
      CHECK(std::vector<std::string>(cols.end() - 6, cols.end()) ==
            std::vector<std::string>{"block_lowest", "block_centroid_height", "block_rotation_deg",
                                     "spin_top_lowest", "spin_top_centroid_height",
                                     "spin_top_rotation_deg"});
    }
  }
  {
    StatsWriter s(p, false, false, std::nullopt, bodies);
    StepStats r;
    r.step = 1;
    r.bodies = {{-0.125, 0.5, 1e-3}, {0.1 + 0.2, 2.0, 179.5}};
    s.write(r);
    r.step = 2;
    r.bodies.clear();  // a row without poses: "nan" in every body column
    s.write(r);
    r.bodies = {{0, 0, 0}};  // not one per body
    CHECK_THROWS_AS(s.write(r), Error);
  }
  const auto lines = read_lines(p);
  REQUIRE(lines.size() == 3);
  const auto cols = StatsWriter::columns(false, false, bodies);
  std::string header;
  for (const auto& c : cols) header += (header.empty() ? "" : ",") + c;
  CHECK(lines[0] == header);
  for (const auto& l : lines) CHECK(count_fields(l) == cols.size());
  CHECK(lines[1].ends_with(",-0.125,0.5,0.001,0.30000000000000004,2,179.5"));  // 17 digits
  CHECK(lines[2].ends_with(",nan,nan,nan,nan,nan,nan"));
  // A resumed run with the same bodies continues the file; other bodies are another run.
  { StatsWriter s(p, false, false, 1, bodies); }
  CHECK_THROWS_AS(StatsWriter(p, false, false, 1, std::vector<std::string>{"block"}), InputError);
}

TEST_CASE("column_safe_name and stats_body_names: CSV-safe names, a clash is an input error") {
  CHECK(column_safe_name("toy") == "toy");
  CHECK(column_safe_name("my body,1;x.y-z\"q\"") == "my_body_1_x_y_z_q_");
  CHECK(column_safe_name("") == "body");
  solid::SolidWorld world;
  world.bodies.push_back(make_test_body());
  CHECK(stats_body_names(world) == std::vector<std::string>{"block"});
  const solid::SolidBody b = make_test_body();
  world.bodies.emplace_back("a-b", b.rest_mesh(), b.material());
  world.bodies.emplace_back("a.b", b.rest_mesh(), b.material());  // another file name: a.b.pvd
  std::string msg;
  try {
    stats_body_names(world);
  } catch (const InputError& e) {
    msg = e.what();
  }
  CHECK(msg.find("bodies 'a-b' and 'a.b' share the stats.csv column name 'a_b'") !=
        std::string::npos);
  // OutputWriter (and tetfsi validate, through output_file_names) says it before writing.
  TempDir dir("stats_clash");
  Scene scene;
  scene.name = "unit";
  CHECK_THROWS_AS(output_file_names(output_plan(scene), world), InputError);
  CHECK_THROWS_AS(OutputWriter(dir.path / "run", output_plan(scene), world), InputError);
  CHECK(!fs::exists(dir.path / "run"));
}

TEST_CASE("OutputWriter: layout of an output folder, 3 frames at t = 0, 0.5, 1.25") {
  TempDir dir("layout");
  const fs::path out = dir.path / "run";
  Scene scene;
  scene.name = "unit";
  scene.output.compression = "zlib";
  scene.resolved = {{"name", "unit"}, {"time", {{"dt", 0.25}}}};
  solid::SolidWorld world;
  world.bodies.push_back(make_test_body());
  world.gravity = Vec3(0, 0, -9.81);

  // A file that is not ours must survive (earlier runs are overwritten, never deleted).
  fs::create_directories(out);
  std::ofstream(out / "notes.txt") << "mine";

  const std::vector<double> times = {0.0, 0.5, 1.25};
  const std::vector<int> steps = {0, 2, 5};
  std::vector<MatX3> written_d;
  for (int pass = 0; pass < 2; ++pass) {  // the second pass overwrites the first run
    world.bodies[0] = make_test_body(0.1 * pass);
    OutputWriter w(out, output_plan(scene), world);
    CHECK(w.compression() == Compression::ZLib);
    written_d.clear();
    for (size_t f = 0; f < times.size(); ++f) {
      world.bodies[0].displacement.array() += 0.001 * static_cast<double>(f);
      written_d.push_back(world.bodies[0].displacement);
      w.write_frame(world, steps[f], times[f]);
      StepStats r;
      r.step = steps[f];
      r.time = times[f];
      w.write_stats(r);
    }
    CHECK(w.frames_written() == 3);
    REQUIRE(w.pvd_paths().size() == 1);
    CHECK(w.pvd_paths()[0] == out / "block.pvd");
  }

  CHECK(read_text(out / "notes.txt") == "mine");
  CHECK(!has_tmp_files(out));
  const auto resolved = nlohmann::json::parse(read_text(out / "scene.resolved.json"));
  CHECK(resolved["name"] == "unit");
  CHECK(read_lines(out / "stats.csv").size() == 4);  // the second run's header + 3 rows

  const ParsedPvd pvd = parse_pvd(out / "block.pvd");
  REQUIRE(pvd.times.size() == 3);  // not 6: the earlier run's entries are gone
  for (size_t f = 0; f < 3; ++f) {
    CHECK(pvd.times[f] == times[f]);
    CHECK(pvd.files[f] == fmt::format("block/block_{:06d}.vtu", steps[f]));
    auto grid = read_vtu(out / pvd.files[f]);
    CHECK(max_diff(grid->GetPointData()->GetArray("displacement"), written_d[f].data(),
                   world.bodies[0].num_nodes()) <= 1e-12);
  }
}

TEST_CASE("StatsWriter with a fluid: the remesh phase and the fluid and quality columns") {
  TempDir dir("stats_fluid");
  const fs::path p = dir.path / "stats.csv";
  const mesh::TetMesh m = make_fluid_mesh();
  const auto quality = mesh::quality_columns(mesh::summarize_quality(m));
  {
    StatsWriter s(p, true);
    CHECK(s.has_fluid());
    StepStats r;
    r.step = 1;
    r.dt = 0.01;
    r.time = 0.01;
    r.phases.add("remesh", 0.25);
    FluidStepStats f;
    f.cells = m.num_tets();
    f.vertices = m.num_vertices();
    f.steiner_points = 7;
    f.recovery_rounds = 2;
    f.remesh_incremental = 1;
    f.vertices_removed = 11;
    f.vertices_inserted = 13;
    f.remesh_s = 0.125;
    f.quality = quality;
    f.pressure_iterations = 17;
    f.divergence = 2.5e-9;
    f.inflow_flux = 0.08;
    f.outflow_flux = 0.0799;
    f.smoke_mass = 0.5;
    r.phases.add("pressure_solve", 0.5);
    r.fluid = f;
    s.write(r);
    r.step = 2;
    r.fluid.reset();  // a row without figures: "nan" in every fluid column
    s.write(r);
  }
  const auto lines = read_lines(p);
  REQUIRE(lines.size() == 3);
  const auto& cols = StatsWriter::columns(true);
  // + the phases remesh, transfer, forces, pressure_assembly, pressure_solve; 8 mesh columns,
  // the quality columns and 12 fluid-step columns
  CHECK(cols.size() == StatsWriter::columns().size() + 5 + 8 + quality.size() + 12);
  std::vector<std::string> header;
  {
    std::stringstream ss(lines[0]);
    for (std::string c; std::getline(ss, c, ',');) header.push_back(c);
  }
  CHECK(header == cols);
  CHECK(lines[0].rfind("step,time,dt,assemble,solve,update,remesh,transfer,forces,"
                       "pressure_assembly,pressure_solve,output,total,",
                       0) == 0);
  for (const char* c : {"fluid_cells", "fluid_vertices", "steiner_points", "recovery_rounds",
                        "remesh_s", "q_min_dihedral_deg", "q_slivers", "q_max_radius_edge",
                        "pressure_iterations", "divergence", "fluid_kinetic_energy", "smoke_mass",
                        "inflow_flux", "outflow_flux", "cfl", "traces_clamped"})
    CHECK(std::find(cols.begin(), cols.end(), c) != cols.end());
  std::vector<std::string> row;
  {
    std::stringstream ss(lines[1]);
    for (std::string c; std::getline(ss, c, ',');) row.push_back(c);
  }
  REQUIRE(row.size() == cols.size());
  auto value = [&](const std::string& name) {
    const auto it = std::find(cols.begin(), cols.end(), name);
    REQUIRE(it != cols.end());
    return std::stod(row[static_cast<size_t>(it - cols.begin())]);
  };
  CHECK(value("remesh") == 0.25);
  CHECK(value("fluid_cells") == 48);
  CHECK(value("fluid_vertices") == 27);
  CHECK(value("steiner_points") == 7);
  CHECK(value("recovery_rounds") == 2);
  CHECK(value("remesh_incremental") == 1);
  CHECK(value("vertices_removed") == 11);
  CHECK(value("vertices_inserted") == 13);
  CHECK(value("remesh_s") == 0.125);
  CHECK(value("pressure_solve") == 0.5);
  CHECK(value("pressure_iterations") == 17);
  CHECK(value("divergence") == 2.5e-9);
  CHECK(value("inflow_flux") == 0.08);
  CHECK(value("outflow_flux") == 0.0799);
  CHECK(value("smoke_mass") == 0.5);
  for (const auto& [name, v] : quality) {
    CAPTURE(name);
    if (std::isfinite(v)) CHECK(value(name) == v);  // 17 digits: bit-identical
  }
  CHECK(count_fields(lines[2]) == cols.size());
  CHECK(lines[2].find(",nan,") != std::string::npos);
  CHECK(lines[2].substr(lines[2].rfind(',') + 1) == "nan");
}

TEST_CASE("write_interface_vtp with fields: pressure of the face's fluid cell, normal velocity") {
  TempDir dir("interface_fields");
  const mesh::TetMesh m = make_fluid_mesh();
  FluidFrameFields f;
  f.pressure.resize(m.num_tets());
  for (Index t = 0; t < m.num_tets(); ++t) f.pressure[t] = 100.0 + t;
  f.face_velocity.resize(m.num_faces());
  for (Index k = 0; k < m.num_faces(); ++k) f.face_velocity[k] = 0.5 * k;
  const fs::path p = dir.path / "i.vtp";
  write_interface_vtp(p, m, Compression::LZ4, &f);
  auto poly = read_vtp(p);
  REQUIRE(poly->GetNumberOfCells() == 8);
  vtkDataArray* pressure = poly->GetCellData()->GetArray("pressure");
  vtkDataArray* un = poly->GetCellData()->GetArray("normal_velocity");
  REQUIRE(pressure != nullptr);
  REQUIRE(un != nullptr);
  Index i = 0;
  for (Index k = 0; k < m.num_faces(); ++k) {
    if (m.face_kind[static_cast<size_t>(k)] != mesh::FaceKind::Solid) continue;
    CAPTURE(k);
    CHECK(pressure->GetComponent(i, 0) == f.pressure[m.face_tets(k, 0)]);
    CHECK(un->GetComponent(i, 0) == f.face_velocity[k]);
    ++i;
  }
  // Without fields: neither array.
  write_interface_vtp(p, m, Compression::LZ4);
  CHECK(read_vtp(p)->GetCellData()->GetArray("pressure") == nullptr);
  // Fields of another mesh: an internal error naming the sizes.
  f.face_velocity.resize(3);
  CHECK_THROWS_AS(write_interface_vtp(p, m, Compression::LZ4, &f), Error);
}

TEST_CASE("OutputWriter: a frame that fails half-way is in no collection") {
  TempDir dir("layout_half_frame");
  const fs::path out = dir.path / "run";
  Scene scene;
  scene.name = "unit";
  scene.fluid = FluidSpec{};
  solid::SolidWorld world;
  world.bodies.push_back(make_test_body());
  const mesh::TetMesh m = make_fluid_mesh();
  OutputWriter w(out, output_plan(scene), world);
  w.write_frame(world, 0, 0.0, &m);
  FluidFrameFields bad;  // sized for no mesh: the fluid file of frame 1 cannot be written
  CHECK_THROWS_AS(w.write_frame(world, 1, 0.5, &m, &bad), Error);
  for (const char* pvd : {"block.pvd", "fluid.pvd", "interface.pvd"}) {
    CAPTURE(pvd);
    CHECK(parse_pvd(out / pvd).times == std::vector<double>{0.0});
  }
}

TEST_CASE("StatsWriter of a coupled run: its phases and the coupling columns") {
  TempDir dir("stats_coupled");
  const fs::path p = dir.path / "stats.csv";
  const auto& cols = StatsWriter::columns(true, true);
  const auto& fluid_cols = StatsWriter::columns(true);
  const auto& phases = StatsWriter::phase_columns(true, true);
  CHECK(phases == std::vector<std::string>{"remesh", "transfer", "forces", "coupled_assembly",
                                           "coupled_solve", "solid", "update", "output", "total"});
  // the fluid columns with the coupled phases, then the coupling columns
  CHECK(cols.size() ==
        fluid_cols.size() - StatsWriter::phase_columns(true).size() + phases.size() + 7);
  const std::vector<std::string> tail(cols.end() - 7, cols.end());
  CHECK(tail == std::vector<std::string>{"coupled_iterations", "coupled_residual",
                                         "interface_power", "total_energy_coupled",
                                         "enclosed_volume", "enclosed_volume_drift",
                                         "contact_rounds"});
  const mesh::TetMesh m = make_fluid_mesh();
  {
    StatsWriter s(p, true, true);
    CHECK(s.has_coupling());
    StepStats r;
    r.step = 1;
    r.phases.add("coupled_solve", 0.25);
    FluidStepStats f;
    f.quality = mesh::quality_columns(mesh::summarize_quality(m));
    r.fluid = f;
    CoupledStepStats c;
    c.iterations = 14;
    c.residual = 3e-11;
    c.interface_power = -1.25;
    c.total_energy = 0.5;
    c.enclosed_volume = 0.125;
    c.enclosed_volume_drift = 1e-9;
    r.coupled = c;
    s.write(r);
    r.coupled.reset();  // "nan" in the coupling columns
    s.write(r);
  }
  CHECK_FALSE(StatsWriter(dir.path / "no_fluid.csv", false, true).has_coupling());
  const auto lines = read_lines(p);
  REQUIRE(lines.size() == 3);
  std::vector<std::string> row;
  {
    std::stringstream ss(lines[1]);
    for (std::string c; std::getline(ss, c, ',');) row.push_back(c);
  }
  REQUIRE(row.size() == cols.size());
  auto value = [&](const std::string& name) {
    const auto it = std::find(cols.begin(), cols.end(), name);
    REQUIRE(it != cols.end());
    return std::stod(row[static_cast<size_t>(it - cols.begin())]);
  };
  CHECK(value("coupled_solve") == 0.25);
  CHECK(value("coupled_iterations") == 14);
  CHECK(value("coupled_residual") == 3e-11);
  CHECK(value("interface_power") == -1.25);
  CHECK(value("total_energy_coupled") == 0.5);
  CHECK(value("enclosed_volume") == 0.125);
  CHECK(value("enclosed_volume_drift") == 1e-9);
  CHECK(count_fields(lines[2]) == cols.size());
  CHECK(lines[2].substr(lines[2].rfind(',') + 1) == "nan");
}

TEST_CASE("OutputWriter with a fluid: fluid.pvd and interface.pvd next to the body's") {
  TempDir dir("layout_fluid");
  const fs::path out = dir.path / "run";
  Scene scene;
  scene.name = "unit";
  scene.fluid = FluidSpec{};
  solid::SolidWorld world;
  world.bodies.push_back(make_test_body());
  const mesh::TetMesh m = make_fluid_mesh();
  {
    OutputWriter w(out, output_plan(scene), world);
    CHECK(w.has_fluid());
    w.write_frame(world, 0, 0.0, &m);
    w.write_frame(world, 3, 0.5);  // no fluid mesh given: a body-only frame
    w.write_frame(world, 6, 1.0, &m);
  }
  CHECK(!has_tmp_files(out));
  CHECK(parse_pvd(out / "block.pvd").times == std::vector<double>{0.0, 0.5, 1.0});
  const ParsedPvd fluid = parse_pvd(out / "fluid.pvd");
  CHECK(fluid.times == std::vector<double>{0.0, 1.0});
  CHECK(fluid.files ==
        std::vector<std::string>{"fluid/fluid_000000.vtu", "fluid/fluid_000006.vtu"});
  const ParsedPvd iface = parse_pvd(out / "interface.pvd");
  CHECK(iface.times == std::vector<double>{0.0, 1.0});
  CHECK(iface.files == std::vector<std::string>{"interface/interface_000000.vtp",
                                                "interface/interface_000006.vtp"});
  CHECK(read_vtu(out / fluid.files[1])->GetNumberOfCells() == 48);
  CHECK(read_vtp(out / iface.files[1])->GetNumberOfCells() == 8);
  CHECK(read_lines(out / "stats.csv").at(0).find("q_min_dihedral_deg") != std::string::npos);

  // Without a fluid: none of it, and the stats header is the solid-only one.
  const fs::path plain = dir.path / "plain";
  {
    Scene s2;
    s2.name = "unit";
    OutputWriter w(plain, output_plan(s2), world);
    CHECK_FALSE(w.has_fluid());
    w.write_frame(world, 0, 0.0, &m);  // a mesh given anyway is ignored
  }
  CHECK(!fs::exists(plain / "fluid.pvd"));
  CHECK(!fs::exists(plain / "fluid"));
  CHECK(!fs::exists(plain / "interface"));
  CHECK(read_lines(plain / "stats.csv").at(0).find("remesh") == std::string::npos);

  // A body whose file name is one of the fluid streams' is refused in a fluid scene.
  solid::SolidWorld clash;
  clash.bodies.push_back(make_test_body());
  clash.bodies.emplace_back("fluid", mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1)),
                            solid::Material{});
  try {
    OutputWriter w(dir.path / "clash", output_plan(scene), clash);
    FAIL("expected an InputError");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("body 'fluid'") != std::string::npos);
    CHECK(msg.find("rename the body") != std::string::npos);
  }
}

TEST_CASE("write_grid_vti: dimensions, origin, spacing and every cell array bit-exact") {
  TempDir dir("grid_vti");
  const GridFrameFields g = make_grid_frame();
  const Index nc = 60;
  for (const char* name : {"none", "lz4", "zlib"}) {
    CAPTURE(name);
    const Compression c = parse_compression(name);
    const fs::path p = dir.path / fmt::format("fluid_{}.vti", name);
    write_grid_vti(p, g, c);
    CHECK(!has_tmp_files(dir.path));
    const std::string text = read_text(p);
    const std::string head = text.substr(0, text.find("<AppendedData"));
    CHECK(head.find("type=\"ImageData\"") != std::string::npos);
    if (c == Compression::LZ4) CHECK(head.find("vtkLZ4DataCompressor") != std::string::npos);
    if (c == Compression::None) CHECK(head.find("compressor=") == std::string::npos);
    CHECK(head.find("format=\"appended\"") != std::string::npos);

    auto image = read_vti(p);
    int dims[3];
    image->GetDimensions(dims);
    CHECK(dims[0] == 4);  // points = cells + 1
    CHECK(dims[1] == 5);
    CHECK(dims[2] == 6);
    CHECK(image->GetNumberOfCells() == nc);
    double origin[3], spacing[3];
    image->GetOrigin(origin);
    image->GetSpacing(spacing);
    for (int a = 0; a < 3; ++a) {
      CHECK(origin[a] == g.origin[a]);
      CHECK(spacing[a] == g.spacing[a]);
    }

    vtkCellData* cd = image->GetCellData();
    const std::pair<const char*, const VecX*> scalars[] = {{"pressure", &g.pressure},
                                                           {"smoke_density", &g.density},
                                                           {"temperature", &g.temperature},
                                                           {"divergence", &g.divergence},
                                                           {"vorticity", &g.vorticity}};
    for (const auto& [aname, values] : scalars) {
      CAPTURE(aname);
      vtkDataArray* a = cd->GetArray(aname);
      REQUIRE(a != nullptr);
      CHECK(a->GetDataType() == VTK_DOUBLE);
      CHECK(max_diff(a, *values) == 0.0);
    }
    vtkDataArray* u = cd->GetArray("velocity");
    CHECK(max_diff(u, g.velocity.data(), nc) == 0.0);
    vtkDataArray* solid = cd->GetArray("solid");
    REQUIRE(solid != nullptr);
    CHECK(solid->GetDataType() == VTK_UNSIGNED_CHAR);
    REQUIRE(solid->GetNumberOfTuples() == nc);
    bool solid_ok = true;
    for (Index k = 0; k < nc; ++k)
      solid_ok = solid_ok && solid->GetComponent(k, 0) == g.solid[static_cast<size_t>(k)];
    CHECK(solid_ok);

    // x fastest: VTK's cell (i, j, k) is ours i + nx (j + ny k), and it sits where that cell
    // of the grid is.
    for (const std::array<int, 3>& ijk :
         {std::array<int, 3>{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {2, 3, 4}, {1, 2, 3}}) {
      CAPTURE(ijk[0]);
      CAPTURE(ijk[1]);
      CAPTURE(ijk[2]);
      int q[3] = {ijk[0], ijk[1], ijk[2]};
      const vtkIdType id = image->ComputeCellId(q);
      const Index c = ijk[0] + 3 * (ijk[1] + 4 * ijk[2]);
      CHECK(id == c);
      CHECK(cd->GetArray("pressure")->GetComponent(id, 0) == g.pressure[c]);
      CHECK(cd->GetArray("temperature")->GetComponent(id, 0) == g.temperature[c]);
      for (int a = 0; a < 3; ++a) CHECK(u->GetComponent(id, a) == g.velocity(c, a));
      double bounds[6];
      image->GetCellBounds(id, bounds);
      for (int a = 0; a < 3; ++a) {
        CHECK(bounds[2 * a] == doctest::Approx(g.origin[a] + ijk[a] * g.spacing[a]));
        CHECK(bounds[2 * a + 1] == doctest::Approx(g.origin[a] + (ijk[a] + 1) * g.spacing[a]));
      }
    }
  }
}

TEST_CASE(
    "write_grid_interface_vtp: the surface triangles with pressure, jump, area, normal and "
    "the fluid force") {
  TempDir dir("grid_interface");
  const GridFrameFields g = make_grid_frame();
  for (const char* name : {"none", "lz4"}) {
    CAPTURE(name);
    const fs::path p = dir.path / fmt::format("interface_{}.vtp", name);
    write_grid_interface_vtp(p, g, parse_compression(name));
    CHECK(!has_tmp_files(dir.path));
    auto poly = read_vtp(p);
    REQUIRE(poly->GetNumberOfPolys() == 4);
    REQUIRE(poly->GetNumberOfCells() == 4);
    REQUIRE(poly->GetNumberOfPoints() == 4);
    bool cells_ok = true;
    for (Index t = 0; t < 4; ++t) {
      vtkIdType npts = 0;
      const vtkIdType* pts = nullptr;
      poly->GetCellPoints(t, npts, pts);
      cells_ok = cells_ok && npts == 3;
      for (int k = 0; k < 3 && cells_ok; ++k) cells_ok = pts[k] == g.surface_triangles(t, k);
    }
    CHECK(cells_ok);
    double dx = 0.0;
    for (Index i = 0; i < 4; ++i) {
      double x[3];
      poly->GetPoint(i, x);
      for (int k = 0; k < 3; ++k) dx = std::max(dx, std::abs(x[k] - g.surface_points(i, k)));
    }
    CHECK(dx == 0.0);

    vtkCellData* cd = poly->GetCellData();
    for (const char* a : {"body", "pressure", "pressure_jump", "area", "normal"})
      REQUIRE(cd->GetArray(a) != nullptr);
    CHECK(cd->GetArray("body")->GetDataType() == VTK_INT);
    CHECK(cd->GetArray("normal")->GetNumberOfComponents() == 3);
    vtkDataArray* jump = cd->GetArray("pressure_jump");
    for (Index t = 0; t < 4; ++t) {
      CAPTURE(t);
      CHECK(cd->GetArray("body")->GetComponent(t, 0) == g.surface_body[t]);
      CHECK(cd->GetArray("pressure")->GetComponent(t, 0) == g.surface_pressure[t]);
      if (std::isnan(g.surface_pressure_jump[t]))
        CHECK(std::isnan(jump->GetComponent(t, 0)));
      else
        CHECK(jump->GetComponent(t, 0) == g.surface_pressure_jump[t]);
    }
    // Areas (0.2 m legs): three right triangles of 0.02 m², the slanted one √3/2 · 0.04.
    vtkDataArray* area = cd->GetArray("area");
    for (Index t = 0; t < 3; ++t) CHECK(area->GetComponent(t, 0) == doctest::Approx(0.02));
    CHECK(area->GetComponent(3, 0) == doctest::Approx(0.02 * std::sqrt(3.0)));
    // Outward unit normals.
    vtkDataArray* normal = cd->GetArray("normal");
    const double r = 1.0 / std::sqrt(3.0);
    const double expected[4][3] = {{0, 0, -1}, {0, -1, 0}, {-1, 0, 0}, {r, r, r}};
    double dn = 0.0;
    for (Index t = 0; t < 4; ++t)
      for (int k = 0; k < 3; ++k)
        dn = std::max(dn, std::abs(normal->GetComponent(t, k) - expected[t][k]));
    CHECK(dn <= 1e-12);
    // The fluid's nodal force as point data, bit-exact.
    vtkDataArray* force = poly->GetPointData()->GetArray("fluid_force");
    CHECK(max_diff(force, g.surface_force.data(), 4) == 0.0);
  }

  // No triangles: an empty file that reads back.
  GridFrameFields empty = make_grid_frame();
  empty.surface_points.resize(0, 3);
  empty.surface_triangles.resize(0, 3);
  empty.surface_body.resize(0);
  empty.surface_pressure.resize(0);
  empty.surface_pressure_jump.resize(0);
  empty.surface_force.resize(0, 3);
  write_grid_interface_vtp(dir.path / "empty.vtp", empty, Compression::LZ4);
  auto e = read_vtp(dir.path / "empty.vtp");
  CHECK(e->GetNumberOfCells() == 0);
  CHECK(e->GetNumberOfPoints() == 0);
}

TEST_CASE("write_grid_vti / write_grid_interface_vtp: a size mismatch throws before any file") {
  TempDir dir("grid_sizes");
  const fs::path vti = dir.path / "f.vti";
  const fs::path vtp = dir.path / "i.vtp";
  auto expect_error = [&](auto write, const fs::path& p, const GridFrameFields& g,
                          const std::vector<std::string>& words) {
    try {
      write(p, g, Compression::LZ4);
      FAIL("expected an InternalError");
    } catch (const InternalError& e) {
      const std::string msg = e.what();
      CAPTURE(msg);
      CHECK(msg.find('\n') == std::string::npos);
      for (const std::string& w : words) CHECK(msg.find(w) != std::string::npos);
    }
    CHECK(!fs::exists(p));
    CHECK(!has_tmp_files(dir.path));
  };
  const auto vti_writer = [](const fs::path& p, const GridFrameFields& g, Compression c) {
    write_grid_vti(p, g, c);
  };
  const auto vtp_writer = [](const fs::path& p, const GridFrameFields& g, Compression c) {
    write_grid_interface_vtp(p, g, c);
  };
  {
    GridFrameFields g = make_grid_frame();
    g.pressure.resize(59);
    expect_error(vti_writer, vti, g, {"'pressure'", "59", "60 cells", "3 × 4 × 5"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.velocity.resize(61, 3);
    expect_error(vti_writer, vti, g, {"'velocity'", "61", "60 cells"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.solid.pop_back();
    expect_error(vti_writer, vti, g, {"'solid'", "59"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.cells = {3, 0, 5};
    expect_error(vti_writer, vti, g, {"cells", "3 × 0 × 5"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.spacing[1] = 0.0;
    expect_error(vti_writer, vti, g, {"spacing"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.surface_pressure.resize(3);
    expect_error(vtp_writer, vtp, g, {"'surface_pressure'", "3", "4 surface_triangles"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.surface_force.resize(5, 3);
    expect_error(vtp_writer, vtp, g, {"'surface_force'", "5", "4 surface_points"});
  }
  {
    GridFrameFields g = make_grid_frame();
    g.surface_triangles(2, 1) = 4;
    expect_error(vtp_writer, vtp, g, {"surface_triangles row 2", "(0, 4, 2)", "4 surface_points"});
  }
}

TEST_CASE("OutputWriter::write_grid_frame: fluid.pvd lists the .vti, interface.pvd the .vtp") {
  TempDir dir("layout_grid");
  const fs::path out = dir.path / "run";
  Scene scene;
  scene.name = "unit";
  scene.fluid = FluidSpec{};
  solid::SolidWorld world;
  world.bodies.push_back(make_test_body());
  GridFrameFields g = make_grid_frame();
  {
    OutputWriter w(out, output_plan(scene), world);
    w.write_grid_frame(world, 0, 0.0, g);
    g.pressure.array() += 1.0;
    w.write_grid_frame(world, 4, 0.25, g);
    CHECK(w.frames_written() == 2);

    // A frame with inconsistent grid sizes throws before any of its files is written, and
    // is in no collection.
    GridFrameFields bad = g;
    bad.surface_body.resize(1);
    CHECK_THROWS_AS(w.write_grid_frame(world, 8, 0.5, bad), InternalError);
    CHECK(!fs::exists(out / "block" / "block_000008.vtu"));
    CHECK(!fs::exists(out / "fluid" / "fluid_000008.vti"));
    CHECK(w.frames_written() == 2);
  }
  CHECK(!has_tmp_files(out));
  for (const char* pvd : {"block.pvd", "fluid.pvd", "interface.pvd"}) {
    CAPTURE(pvd);
    CHECK(parse_pvd(out / pvd).times == std::vector<double>{0.0, 0.25});
  }
  const ParsedPvd fluid = parse_pvd(out / "fluid.pvd");
  CHECK(fluid.files ==
        std::vector<std::string>{"fluid/fluid_000000.vti", "fluid/fluid_000004.vti"});
  const ParsedPvd iface = parse_pvd(out / "interface.pvd");
  CHECK(iface.files == std::vector<std::string>{"interface/interface_000000.vtp",
                                                "interface/interface_000004.vtp"});
  CHECK(parse_pvd(out / "block.pvd").files.at(1) == "block/block_000004.vtu");
  auto image = read_vti(out / fluid.files[1]);
  CHECK(image->GetNumberOfCells() == 60);
  CHECK(max_diff(image->GetCellData()->GetArray("pressure"), g.pressure) == 0.0);
  CHECK(read_vtp(out / iface.files[1])->GetNumberOfCells() == 4);

  // A scene without a fluid has no fluid.pvd to list a grid frame in.
  Scene plain;
  plain.name = "unit";
  OutputWriter w(dir.path / "plain", output_plan(plain), world);
  CHECK_THROWS_AS(w.write_grid_frame(world, 0, 0.0, g), InternalError);
  CHECK(!fs::exists(dir.path / "plain" / "block" / "block_000000.vtu"));
}
