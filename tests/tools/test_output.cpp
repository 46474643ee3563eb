// Tests of tools/output.cpp: .vtu frames read back with VTK's own reader, .pvd collections
// parsed with VTK's XML parser, stats.csv shape, output-folder layout and atomic writes.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLDataParser.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "solid/world.hpp"
#include "tools/output.hpp"
#include "tools/scene.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::tools;

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
      s.write(r);
      // Flushed per row: visible while the writer is still open.
      CHECK(read_lines(p).size() == static_cast<size_t>(step) + 1);
    }
  }
  const auto lines = read_lines(p);
  REQUIRE(lines.size() == 5);
  CHECK(lines[0] ==
        "step,time,dt,assemble,solve,update,output,total,solver_iterations,solver_residual,"
        "contacts,kinetic_energy,elastic_energy,gravity_potential,total_energy");
  const size_t ncols = StatsWriter::columns().size();
  CHECK(ncols == 15);
  for (const auto& l : lines) CHECK(count_fields(l) == ncols);
  CHECK(lines[2].rfind("2,0.02,", 0) == 0);
  // total_energy is the last column: 1 + 2 − 0.5.
  CHECK(std::stod(lines[4].substr(lines[4].rfind(',') + 1)) == doctest::Approx(2.5));
  // The "output" phase was never timed: its column is 0.
  CHECK(lines[1].find(",0,") != std::string::npos);
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
    OutputWriter w(out, scene, world);
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
