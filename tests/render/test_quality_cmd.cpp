// Tests of render/quality_cmd.cpp and render/raster.cpp: `tetfsi quality` run as a user would
// (TETFSI_EXE, tests/CMakeLists.txt) on .vtu files written here with VTK — a regular
// tet, Kuhn boxes from make_box, boxes with other cell types, an inverted tet, vertex_body
// arrays, a fluid frame from write_fluid_vtu — checking the report, the JSON against
// summarize_quality, the PNG's header, and one-line errors; plus the raster's text metrics and a
// PNG round trip.
#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <vtkCellType.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridWriter.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/output.hpp"
#include "mesh/generate.hpp"
#include "mesh/quality.hpp"
#include "mesh/tet_mesh.hpp"
#include "render/quality_cmd.hpp"
#include "render/raster.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;

namespace {

using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;
using Result = tetfsi::test::CliResult;

Result tetfsi_exe(const fs::path& cwd, const std::string& args) {
  return tetfsi::test::run_tetfsi(cwd, args);
}

const double kRegularDihedral = std::acos(1.0 / 3.0) * 180.0 / std::numbers::pi;  // 70.5288°

/// A cell that is not a tet: VTK type and point ids.
struct OtherCell {
  int type;
  std::vector<vtkIdType> ids;
};

/// Write points, tets (as VTK_TETRA, in the given vertex order), other cells and an optional
/// `vertex_body` point array as a .vtu (Float64 points, binary: the coordinates read back
/// exactly).
void write_vtu(const fs::path& path, const MatX3& x, const MatX4i& tets,
               const std::vector<OtherCell>& others = {}, const VecXi& vertex_body = VecXi()) {
  vtkNew<vtkUnstructuredGrid> grid;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  for (Index i = 0; i < x.rows(); ++i) points->InsertNextPoint(x(i, 0), x(i, 1), x(i, 2));
  grid->SetPoints(points);
  grid->Allocate(tets.rows() + static_cast<Index>(others.size()));
  for (Index t = 0; t < tets.rows(); ++t) {
    const vtkIdType ids[4] = {tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3)};
    grid->InsertNextCell(VTK_TETRA, 4, ids);
  }
  for (const OtherCell& c : others)
    grid->InsertNextCell(c.type, static_cast<vtkIdType>(c.ids.size()), c.ids.data());
  if (vertex_body.size() > 0) {
    vtkNew<vtkIntArray> body;
    body->SetName("vertex_body");
    body->SetNumberOfValues(vertex_body.size());
    for (Index i = 0; i < vertex_body.size(); ++i) body->SetValue(i, vertex_body(i));
    grid->GetPointData()->AddArray(body);
  }
  vtkNew<vtkXMLUnstructuredGridWriter> w;
  w->SetInputData(grid);
  w->SetFileName(path.c_str());
  w->SetDataModeToBinary();
  REQUIRE(w->Write() == 1);
}

/// The regular tet on alternate corners of the cube [-1, 1]³ (edge 2√2).
void regular_tet(MatX3& x, MatX4i& t) {
  x.resize(4, 3);
  x << 1, 1, 1, -1, 1, -1, 1, -1, -1, -1, -1, 1;
  t.resize(1, 4);
  t << 0, 1, 2, 3;
}

/// Width and height from a PNG's IHDR chunk; (0, 0) if the signature is not a PNG's.
std::pair<std::uint32_t, std::uint32_t> png_size(const fs::path& p) {
  const std::string s = read_text(p);
  const std::string sig = "\x89PNG\r\n\x1a\n";
  if (s.size() < 24 || s.compare(0, 8, sig) != 0 || s.compare(12, 4, "IHDR") != 0) return {0, 0};
  const auto be32 = [&](std::size_t i) {
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(s[i + k]);
    return v;
  };
  return {be32(16), be32(20)};
}

Index sum(const nlohmann::json& counts) {
  Index n = 0;
  for (const auto& c : counts) n += c.get<Index>();
  return n;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("tetfsi quality: a regular tet reports 70.53 deg in the text and the JSON and a PNG") {
    TempDir dir("regular");
    MatX3 x;
    MatX4i t;
    regular_tet(x, t);
    write_vtu(dir.path / "regular.vtu", x, t);

    const Result r = tetfsi_exe(dir.path, "quality regular.vtu --json q.json --png q.png");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);
    CHECK(r.err.empty());
    const auto lines = lines_of(r.out);
    REQUIRE(lines.size() > 5);
    CHECK(lines[0] == "tetfsi quality: regular.vtu");
    CHECK(lines[1] == "  1 tet (VTK_TETRA cell), 4 points");
    CHECK(r.out.find("vertex_body: not in the file") != std::string::npos);
    CHECK(r.out.find("min dihedral angle     70.529 deg") != std::string::npos);
    CHECK(r.out.find("max dihedral angle     70.529 deg") != std::string::npos);
    CHECK(r.out.find("not computed") == std::string::npos);

    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    CHECK(j["file"] == "regular.vtu");
    CHECK(j["tets"] == 1);
    CHECK(j["points"] == 4);
    CHECK(j["skipped_cells"] == 0);
    CHECK(j["face_figures"] == true);
    CHECK(j["no_face_figures_reason"].is_null());
    CHECK(j["q_cells"] == 1);
    CHECK(j["q_faces"] == 4);
    CHECK(j["q_interior_faces"] == 0);
    CHECK(std::abs(j["q_min_dihedral_deg"].get<double>() - 70.5288) <= 1e-3);
    CHECK(std::abs(j["q_min_dihedral_deg"].get<double>() - kRegularDihedral) <= 1e-9);
    CHECK(std::abs(j["q_max_dihedral_deg"].get<double>() - kRegularDihedral) <= 1e-9);
    CHECK(j["q_min_shape"].get<double>() == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(j["q_max_radius_edge"].get<double>() ==
          doctest::Approx(std::sqrt(6.0) / 4.0).epsilon(1e-12));
    CHECK(j["q_volume"].get<double>() == doctest::Approx(8.0 / 3.0).epsilon(1e-12));
    CHECK(j["q_median_weight"].is_null());  // no interior faces: NaN becomes null
    // Every quality_columns name is there.
    for (const auto& [name, value] : mesh::quality_columns(mesh::QualitySummary{}))
      CHECK_MESSAGE(j.contains(name), name);
    const nlohmann::json& h = j["histograms"];
    CHECK(h["min_dihedral_deg"]["lo"] == 0.0);
    CHECK(h["min_dihedral_deg"]["hi"] == 90.0);
    REQUIRE(h["min_dihedral_deg"]["counts"].size() == 18);
    CHECK(h["min_dihedral_deg"]["counts"][14] == 1);  // [70, 75)
    CHECK(sum(h["max_dihedral_deg"]["counts"]) == 1);
    CHECK(h["shape"]["counts"][9] == 1);  // [0.9, 1]
    CHECK(sum(h["relative_dual"]["counts"]) == 0);

    const auto [w, ht] = png_size(dir.path / "q.png");
    CHECK(w == static_cast<std::uint32_t>(app::kQualityPngWidth));
    CHECK(ht == static_cast<std::uint32_t>(app::kQualityPngHeight));
    CHECK_FALSE(fs::exists(dir.path / "q.png.tmp"));
    CHECK_FALSE(fs::exists(dir.path / "q.json.tmp"));
  }

  TEST_CASE("tetfsi quality: a Kuhn box gives 45 and 90 deg and the face figures of TetMesh") {
    TempDir dir("box");
    const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(2, 1, 1), Vec3i(4, 2, 2));
    write_vtu(dir.path / "box.vtu", box.vertices, box.tets);
    const mesh::QualitySummary expect =
        mesh::summarize_quality(mesh::build_tet_mesh(box.vertices, box.tets));

    const Result r = tetfsi_exe(dir.path, "quality box.vtu --json q.json");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);
    CHECK(r.out.find(fmt::format("  {} tets (VTK_TETRA cells), {} points", box.num_tets(),
                                 box.num_vertices())) != std::string::npos);
    CHECK(r.out.find("min dihedral angle     45.000 deg") != std::string::npos);
    CHECK(r.out.find("max dihedral angle     90.000 deg") != std::string::npos);
    CHECK(r.out.find("interior faces with d_f <= 0:") != std::string::npos);
    CHECK(r.out.find(mesh::format_quality_report(expect)) != std::string::npos);

    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    CHECK(j["q_cells"] == box.num_tets());
    CHECK(std::abs(j["q_min_dihedral_deg"].get<double>() - 45.0) <= 1e-9);
    CHECK(std::abs(j["q_max_dihedral_deg"].get<double>() - 90.0) <= 1e-9);
    for (const auto& [name, value] : mesh::quality_columns(expect)) {
      INFO(name);
      if (std::isfinite(value))
        CHECK(j[name].get<double>() == doctest::Approx(value).epsilon(1e-12));
      else
        CHECK(j[name].is_null());
    }
    CHECK(j["q_faces"] == expect.faces);
    CHECK(j["q_interior_faces"] == expect.interior_faces);
    CHECK(j["q_nonpositive_dual"] == expect.nonpositive_dual);
    const nlohmann::json& h = j["histograms"];
    CHECK(h["relative_dual"]["counts"].get<std::vector<Index>>() ==
          expect.relative_dual_hist.counts);
    CHECK(sum(h["relative_dual"]["counts"]) == expect.interior_faces);
    CHECK(sum(h["shape"]["counts"]) == box.num_tets());
  }

  TEST_CASE("tetfsi quality: cells that are not tets are skipped and counted") {
    TempDir dir("mixed");
    const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(2, 2, 2));
    const std::vector<OtherCell> others = {{VTK_TRIANGLE, {0, 1, 3}},
                                           {VTK_LINE, {0, 1}},
                                           {VTK_TRIANGLE, {1, 2, 4}},
                                           {VTK_TRIANGLE, {3, 4, 6}}};
    write_vtu(dir.path / "mixed.vtu", box.vertices, box.tets, others);

    const Result r = tetfsi_exe(dir.path, "quality mixed.vtu --json q.json");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);
    CHECK(r.out.find("  48 tets (VTK_TETRA cells), 27 points") != std::string::npos);
    CHECK(r.out.find("skipped 4 cells that are not tets: 1 vtkLine (type 3), 3 vtkTriangle "
                     "(type 5)") != std::string::npos);
    CHECK(r.out.find("min dihedral angle     45.000 deg") != std::string::npos);
    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    CHECK(j["skipped_cells"] == 4);
    REQUIRE(j["skipped_cell_types"].size() == 2);
    CHECK(j["skipped_cell_types"][0]["type"] == 3);
    CHECK(j["skipped_cell_types"][0]["count"] == 1);
    CHECK(j["skipped_cell_types"][1]["name"] == "vtkTriangle");
    CHECK(j["skipped_cell_types"][1]["count"] == 3);
    CHECK(j["q_cells"] == 48);
    CHECK(j["face_figures"] == true);
  }

  TEST_CASE("tetfsi quality: an inverted tet gives cell figures only and says why") {
    TempDir dir("inverted");
    const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(3, 3, 3));
    MatX4i tets = box.tets;
    std::swap(tets(0, 1), tets(0, 2));  // tet 0 (in the corner cube) inverted
    // vertex_body: the box's surface vertices belong to body 0.
    VecXi body(box.num_vertices());
    for (Index i = 0; i < box.num_vertices(); ++i) {
      const Vec3 p = box.vertices.row(i);
      const bool surface = (p.array() < 1e-12).any() || (p.array() > 1.0 - 1e-12).any();
      body(i) = surface ? 0 : -1;
    }
    write_vtu(dir.path / "inverted.vtu", box.vertices, tets, {}, body);

    const Result r = tetfsi_exe(dir.path, "quality inverted.vtu --json q.json --png q.png");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);  // a bad mesh is a result, not an error
    CHECK(r.err.empty());
    CHECK(r.out.find("face figures (dual lengths, A_f/d_f) not computed: the tets are not a "
                     "valid, positively oriented mesh: tet 0 (vertices") != std::string::npos);
    CHECK(r.out.find("is not positively oriented") != std::string::npos);
    CHECK(r.out.find("build_tet_mesh") == std::string::npos);
    CHECK(r.out.find("vertex_body: 56 of 64 points on a solid surface") != std::string::npos);
    CHECK(r.out.find("inverted (volume <= 0): 1") != std::string::npos);
    CHECK(r.out.find("interior faces with d_f") == std::string::npos);

    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    CHECK(j["face_figures"] == false);
    CHECK(j["no_face_figures_reason"].get<std::string>().find("tet 0") != std::string::npos);
    CHECK(j["vertex_body"] == true);
    CHECK(j["q_inverted"] == 1);
    CHECK(j["q_cells"] == 162);
    CHECK(j["q_min_shape"].get<double>() < 0.0);
    for (const char* face_column : {"q_faces", "q_interior_faces", "q_nonpositive_dual",
                                    "q_tiny_dual", "q_max_weight", "q_median_weight"})
      CHECK_MESSAGE(j[face_column].is_null(), face_column);
    CHECK(j["histograms"]["relative_dual"].is_null());
    CHECK(sum(j["histograms"]["shape"]["counts"]) == 162);
    CHECK(j["histograms"]["shape"]["counts"][0] == 1);  // the inverted one, shape < 0
    // Away from the solid: only the 6 tets of the central cube, untouched Kuhn tets.
    CHECK(std::abs(j["q_min_dihedral_away_deg"].get<double>() - 45.0) <= 1e-9);

    const auto [w, h] = png_size(dir.path / "q.png");
    CHECK(w == static_cast<std::uint32_t>(app::kQualityPngWidth));
    CHECK(h == static_cast<std::uint32_t>(app::kQualityPngHeight));
  }

  TEST_CASE("tetfsi quality: vertex_body restricts the min dihedral away from solids") {
    TempDir dir("body");
    mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(3, 3, 3), Vec3i(3, 3, 3));
    // Slide corner vertex 0 along the corner cube's diagonal: the 6 tets around that
    // diagonal stay positive but get flatter; every other tet is a Kuhn tet (45°).
    box.vertices.row(0) = Vec3(0.7, 0.7, 0.7);  // min dihedral 23.2°
    VecXi body = VecXi::Constant(box.num_vertices(), -1);
    for (Index i = 0; i < box.num_vertices(); ++i) {
      const Vec3 p = box.vertices.row(i);
      if ((p.array() < 0.8).any() || (p.array() > 2.5).any()) body(i) = 2;
    }
    write_vtu(dir.path / "body.vtu", box.vertices, box.tets, {}, body);

    mesh::TetMesh m = mesh::build_tet_mesh(box.vertices, box.tets);
    m.vertex_body = body;
    const mesh::QualitySummary expect = mesh::summarize_quality(m);
    REQUIRE(expect.min_dihedral_deg < 30.0);

    const Result r = tetfsi_exe(dir.path, "quality body.vtu --json q.json");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);
    CHECK(r.out.find("vertex_body: 56 of 64 points on a solid surface") != std::string::npos);
    CHECK(r.out.find("min dihedral away from solids   45.000 deg") != std::string::npos);
    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    CHECK(j["q_min_dihedral_deg"].get<double>() ==
          doctest::Approx(expect.min_dihedral_deg).epsilon(1e-12));
    CHECK(std::abs(j["q_min_dihedral_away_deg"].get<double>() - 45.0) <= 1e-9);

    // Every vertex on a solid: no cell is away from one, the figure is NaN and JSON null.
    write_vtu(dir.path / "all_solid.vtu", box.vertices, box.tets, {},
              VecXi::Zero(box.num_vertices()));
    const Result all = tetfsi_exe(dir.path, "quality all_solid.vtu --json all.json");
    INFO(all.out, all.err);
    REQUIRE(all.code == 0);
    const std::string text = read_text(dir.path / "all.json");
    CHECK(text.find("NaN") == std::string::npos);
    const nlohmann::json ja = nlohmann::json::parse(text);
    CHECK(ja["q_min_dihedral_away_deg"].is_null());
    CHECK(ja["q_min_dihedral_deg"].is_number());
  }

  TEST_CASE("tetfsi quality: a fluid frame of write_fluid_vtu reads back with its vertex_body") {
    TempDir dir("fluid");
    mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(3, 3, 3), Vec3i(3, 3, 3));
    box.vertices.row(0) = Vec3(0.7, 0.7, 0.7);  // flattens the corner cube's tets
    mesh::TetMesh m = mesh::build_tet_mesh(box.vertices, box.tets);
    for (Index i = 0; i < m.num_vertices(); ++i) {
      const Vec3 p = m.vertices.row(i);
      m.vertex_body(i) = (p.array() < 0.8).any() || (p.array() > 2.5).any() ? 1 : -1;
    }
    app::write_fluid_vtu(dir.path / "fluid.vtu", m, app::Compression::LZ4);
    const mesh::QualitySummary expect = mesh::summarize_quality(m);
    REQUIRE(expect.min_dihedral_away_deg > expect.min_dihedral_deg + 10.0);

    const Result r = tetfsi_exe(dir.path, "quality fluid.vtu --json q.json");
    INFO(r.out, r.err);
    REQUIRE(r.code == 0);
    CHECK(r.out.find("vertex_body: 56 of 64 points on a solid surface") != std::string::npos);
    CHECK(r.out.find(mesh::format_quality_report(expect)) != std::string::npos);
    const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "q.json"));
    for (const auto& [name, value] : mesh::quality_columns(expect)) {
      INFO(name);
      if (std::isfinite(value))
        CHECK(j[name].get<double>() == doctest::Approx(value).epsilon(1e-12));
      else
        CHECK(j[name].is_null());
    }
  }

  TEST_CASE(
      "tetfsi quality: missing and non-VTU files and files without tets are one-line errors") {
    TempDir dir("errors");
    const auto one_line_error = [&](const std::string& args, const std::string& needle) {
      const Result r = tetfsi_exe(dir.path, args);
      INFO(args, r.out, r.err);
      CHECK(r.code == 1);
      const auto lines = lines_of(r.err);
      REQUIRE(lines.size() == 1);
      CHECK(lines[0].rfind("error: ", 0) == 0);
      CHECK(lines[0].find(needle) != std::string::npos);
    };
    one_line_error("quality missing.vtu", "missing.vtu: no such file");

    std::ofstream(dir.path / "notes.vtu") << "not a mesh\n";
    one_line_error("quality notes.vtu", "notes.vtu: not a VTK XML unstructured grid");

    std::ofstream(dir.path / "broken.vtu")
        << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\">\n"
           "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n";
    one_line_error("quality broken.vtu", "broken.vtu: VTK could not read the file");

    const mesh::VolumeMesh box = mesh::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1));
    write_vtu(dir.path / "surface.vtu", box.vertices, MatX4i(0, 4),
              {{VTK_TRIANGLE, {0, 1, 3}}, {VTK_TRIANGLE, {0, 3, 2}}});
    one_line_error("quality surface.vtu",
                   "surface.vtu: no tetrahedra (VTK_TETRA cells) in the file; it has 2 cells: 2 "
                   "vtkTriangle (type 5)");

    MatX3 x;
    MatX4i t;
    regular_tet(x, t);
    write_vtu(dir.path / "regular.vtu", x, t);
    one_line_error("quality regular.vtu --json no_such_folder/q.json",
                   "cannot write 'no_such_folder/q.json.tmp'");
    one_line_error("quality regular.vtu --png no_such_folder/q.png", "no_such_folder/q.png");
    CHECK(tetfsi_exe(dir.path, "quality").code != 0);  // FILE is required (CLI11's usage error)
  }

  TEST_CASE("quality png raster: text metrics and a PNG that reads back pixel for pixel") {
    CHECK(app::Image::text_width("", 2) == 0);
    CHECK(app::Image::text_width("A", 1) == 5);
    CHECK(app::Image::text_width("min 45", 2) == 2 * (6 * 6 - 1));
    CHECK(app::Image::text_height(3) == 24);

    app::Image img(40, 20, {255, 255, 255});
    img.fill_rect(0, 0, 10, 5, {200, 0, 0});    // top-left block
    img.fill_rect(-5, 18, 100, 30, {0, 0, 9});  // clipped to the bottom rows
    img.text(12, 2, "I", 1, {0, 100, 0});       // 'I': row 0 is ".###."
    CHECK(img.pixel(0, 0) == app::Rgb{200, 0, 0});
    CHECK(img.pixel(39, 19) == app::Rgb{0, 0, 9});
    CHECK(img.pixel(12, 2) == app::Rgb{255, 255, 255});
    CHECK(img.pixel(13, 2) == app::Rgb{0, 100, 0});
    CHECK(img.pixel(14, 4) == app::Rgb{0, 100, 0});  // the stem

    TempDir dir("raster");
    const fs::path p = dir.path / "img.png";
    app::write_png(p, img);
    CHECK(png_size(p) == std::make_pair(std::uint32_t{40}, std::uint32_t{20}));
    vtkNew<vtkPNGReader> reader;
    reader->SetFileName(p.c_str());
    reader->Update();
    vtkImageData* back = reader->GetOutput();
    REQUIRE(back->GetNumberOfScalarComponents() == 3);
    int mismatches = 0;
    for (int y = 0; y < 20; ++y)
      for (int x = 0; x < 40; ++x) {
        // VTK's image rows go bottom to top.
        const auto* v = static_cast<unsigned char*>(back->GetScalarPointer(x, 19 - y, 0));
        const app::Rgb c = img.pixel(x, y);
        mismatches += v[0] != c.r || v[1] != c.g || v[2] != c.b;
      }
    CHECK(mismatches == 0);
    CHECK_THROWS_AS(app::write_png(dir.path / "no_such_folder" / "x.png", img), InputError);
  }
}
