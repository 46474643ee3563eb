// `tetfsi export` (render/export_cmd.hpp) on short runs of shipped scenes: the manifest's
// frames, steps and times are the run's .pvd's, each body's PLY has the vertices of its
// boundary, the .vdb files hold the smoke, --frames selects frames, the run's own files stay
// byte for byte as they were, and bad input is one line naming the folder, file or frame.
#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <fmt/format.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/export.hpp"
#include "render/export_cmd.hpp"
#include "render/frame_data.hpp"
#include "render/run_folder.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using json = nlohmann::json;
using tetfsi::test::contains;
using tetfsi::test::shipped_scene;
using tetfsi::test::TempDir;
using Result = tetfsi::test::CliResult;

namespace {

const std::string kLimits = "ulimit -v 4000000; timeout 120";

/// `tetfsi run <scene> --out o --progress off <extra>` in `dir`; REQUIREs exit code 0.
void run_scene(const fs::path& dir, const std::string& scene, const std::string& extra) {
  tetfsi::test::run_shipped_scene(dir, scene, extra, kLimits);
}

/// A coarse smoke_jet run: 6 steps, a frame every 2 (4 frames: steps 0, 2, 4, 6).
void coarse_jet(const fs::path& dir) {
  run_scene(dir, "smoke_jet.json",
            "--steps 6 --set output.every=2 --set fluid.mesh.surface_size=0.1 --set "
            "fluid.mesh.far_size=0.2 --set fluid.refine.size=0");
}

Result cli(const fs::path& dir, const std::string& args) {
  return tetfsi::test::run_tetfsi(dir, args, kLimits);
}

/// Every file under `dir` but those an export writes (vdb/, ply/, export.json) → its bytes.
std::map<std::string, std::string> run_files(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(e.path(), dir).string();
    if (!e.is_regular_file() || rel.rfind("vdb/", 0) == 0 || rel.rfind("ply/", 0) == 0 ||
        rel == "export.json")
      continue;
    out[rel] = tetfsi::test::read_text(e.path());
  }
  return out;
}

/// The frames of `folder`/export.json, read back through io's own parser.
std::vector<app::ExportedFrame> manifest_frames(const fs::path& folder) {
  const json j = json::parse(tetfsi::test::read_text(folder / "export.json"));
  std::vector<app::ExportedFrame> frames;
  for (const json& f : j.at("frames")) frames.push_back(app::exported_frame_from_json(f));
  return frames;
}

/// The vertices on the boundary of a tet mesh (on a face no other tet shares), counted here
/// from the tets alone.
size_t boundary_vertices(const MatX4i& tets) {
  std::map<std::array<int, 3>, int> faces;
  static const int kFace[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (Index t = 0; t < tets.rows(); ++t)
    for (const auto& f : kFace) {
      std::array<int, 3> key = {tets(t, f[0]), tets(t, f[1]), tets(t, f[2])};
      std::sort(key.begin(), key.end());
      ++faces[key];
    }
  std::set<int> vertices;
  for (const auto& [key, count] : faces)
    if (count == 1) vertices.insert(key.begin(), key.end());
  return vertices.size();
}

}  // namespace

TEST_CASE(
    "tetfsi export: a smoke_jet run's frames as .vdb and .ply, the manifest's frames, steps "
    "and times the .pvd's, the body's boundary vertices, the run's files unchanged") {
  TempDir dir("export_jet");
  coarse_jet(dir.path);
  const fs::path out = dir.path / "o";
  const auto before = run_files(out);
  const Result r = cli(dir.path, "export o");
  INFO("stdout: " << r.out << "\nstderr: " << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.err.empty());
  // One progress line per frame and the summary.
  const auto lines = tetfsi::test::lines_of(r.out);
  REQUIRE(lines.size() == 5);
  CHECK(lines[0].rfind("frame 0 [1/4] step 0 t=0 s: vdb ", 0) == 0);
  CHECK(lines[3].rfind("frame 3 [4/4] step 6 t=0.12 s: vdb ", 0) == 0);
  CHECK(contains(lines[3], "1 ply"));
  CHECK(lines[4].rfind("exported 4 frames (0..3) of smoke_jet into o: 4 vdb (", 0) == 0);
  CHECK(contains(lines[4], "voxels 0.1 m"));  // fluid.mesh.surface_size
  CHECK(run_files(out) == before);            // byte for byte

  const std::vector<std::pair<double, fs::path>> pvd = app::read_pvd(out / "paddle.pvd");
  const std::vector<app::ExportedFrame> frames = manifest_frames(out);
  REQUIRE(frames.size() == pvd.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    const app::ExportedFrame& f = frames[i];
    CHECK(f.frame == int(i));
    CHECK(f.step == app::step_of(pvd[i].second));
    CHECK(f.time == pvd[i].first);
    CHECK(f.vdb_file == fmt::format("vdb/fluid_{:06d}.vdb", i));
    REQUIRE(f.meshes.size() == 1);
    CHECK(f.meshes[0].name == "paddle");
    CHECK(f.meshes[0].file == fmt::format("ply/paddle_{:06d}.ply", i));
    const app::TetBodyFrame body = app::read_body_frame(pvd[i].second);
    CHECK(size_t(f.meshes[0].vertices) == boundary_vertices(body.tets));
    const app::ExportSurface ply = app::read_ply(out / f.meshes[0].file);
    CHECK(size_t(ply.points.rows()) == boundary_vertices(body.tets));
    CHECK(ply.triangles.rows() == f.meshes[0].triangles);
    CHECK(fs::exists(out / f.vdb_file));
  }
  // The last frame's .vdb: its step and time, and the smoke the jet blew in.
  const app::VdbFileSummary vdb = app::read_vdb_summary(out / frames.back().vdb_file);
  CHECK(vdb.step == 6);
  CHECK(vdb.time == doctest::Approx(0.12));
  const auto density = std::find_if(vdb.grids.begin(), vdb.grids.end(),
                                    [](const auto& g) { return g.name == "density"; });
  REQUIRE(density != vdb.grids.end());
  CHECK(density->active_voxels > 0);
  CHECK(density->max > 0.3);
  CHECK(frames.back().smoke_mass > 0.0);
  CHECK(frames.front().smoke_mass == 0.0);
}

TEST_CASE(
    "tetfsi export --frames: half-open ranges, open ends and one frame select the run's "
    "frames by index, --ply and --vdb alone, --to another folder") {
  TempDir dir("export_frames");
  coarse_jet(dir.path);
  auto numbers = [](const fs::path& folder) {
    std::vector<int> n;
    for (const app::ExportedFrame& f : manifest_frames(folder)) n.push_back(f.frame);
    return n;
  };
  const Result a = cli(dir.path, "export o --frames 1:3 --ply --to a");
  INFO("stdout: " << a.out << "\nstderr: " << a.err);
  REQUIRE(a.code == 0);
  CHECK(numbers(dir.path / "a") == std::vector<int>{1, 2});
  CHECK(fs::exists(dir.path / "a" / "ply" / "paddle_000002.ply"));
  CHECK_FALSE(fs::exists(dir.path / "a" / "ply" / "paddle_000003.ply"));
  CHECK_FALSE(fs::exists(dir.path / "a" / "vdb"));  // --ply alone
  CHECK_FALSE(fs::exists(dir.path / "o" / "export.json"));

  REQUIRE(cli(dir.path, "export o --frames 2: --vdb --to b").code == 0);
  CHECK(numbers(dir.path / "b") == std::vector<int>{2, 3});
  CHECK_FALSE(fs::exists(dir.path / "b" / "ply"));  // --vdb alone
  REQUIRE(cli(dir.path, "export o --frames :1 --ply --to c").code == 0);
  CHECK(numbers(dir.path / "c") == std::vector<int>{0});
  // Another export into the same folder keeps the frames already listed.
  REQUIRE(cli(dir.path, "export o --frames 3 --ply --to c").code == 0);
  CHECK(numbers(dir.path / "c") == std::vector<int>{0, 3});

  CHECK(app::parse_frame_range("", 13).begin == 0);
  CHECK(app::parse_frame_range("", 13).end == 13);
  CHECK(app::parse_frame_range("4", 13).end == 5);
  CHECK(app::parse_frame_range(" 2 : 5 ", 13).begin == 2);
  CHECK(app::parse_frame_range(":", 13).end == 13);
  CHECK(contains(tetfsi::test::message_of<InputError>([] { app::parse_frame_range("3:20", 13); }),
                 "the run has frames 0..12"));
  CHECK(contains(tetfsi::test::message_of<InputError>([] { app::parse_frame_range("13", 13); }),
                 "the run has frames 0..12"));
  for (const char* bad : {"a", "1:2:3", "-1", "1-3", "1,2", "9999999999"})
    CHECK(contains(tetfsi::test::message_of<InputError>([&] { app::parse_frame_range(bad, 13); }),
                   "--frames"));
}

TEST_CASE(
    "tetfsi export: not a run, no frames, frames outside the run, a missing or damaged "
    "frame file, --vdb without a fluid and an unwritable target are one-line errors") {
  TempDir dir("export_errors");
  coarse_jet(dir.path);
  tetfsi::test::check_one_line_error(cli(dir.path, "export nope"),
                                     {"no such output folder 'nope'", "tetfsi run"});
  tetfsi::test::check_one_line_error(cli(dir.path, "export o/fluid"), {"'o/fluid' holds no run"});
  tetfsi::test::check_one_line_error(cli(dir.path, "export o --frames 2:9"),
                                     {"--frames 2:9", "the run has frames 0..3"});
  tetfsi::test::check_one_line_error(cli(dir.path, "export o --frames 3:3"),
                                     {"--frames 3:3", "selects no frame"});
  tetfsi::test::check_one_line_error(cli(dir.path, "export o --subsamples 0"), {"--subsamples"});
  tetfsi::test::check_one_line_error(cli(dir.path, "export o --voxel-size -1"), {"--voxel-size"});
  // An unwritable target: a file where the folder should be.
  { std::ofstream(dir.path / "a_file") << "x"; }
  tetfsi::test::check_one_line_error(cli(dir.path, "export o --to a_file/sub"),
                                     {"a_file/sub", "--to"});

  // A run whose collections list no frame.
  fs::copy(dir.path / "o", dir.path / "empty", fs::copy_options::recursive);
  for (const char* pvd : {"paddle.pvd", "fluid.pvd"})
    std::ofstream(dir.path / "empty" / pvd) << "<VTKFile type=\"Collection\"><Collection>"
                                               "</Collection></VTKFile>\n";
  tetfsi::test::check_one_line_error(cli(dir.path, "export empty"), {"'empty' has no frames"});

  // A frame file missing, another one damaged: the message names the frame, step and file.
  fs::copy(dir.path / "o", dir.path / "broken", fs::copy_options::recursive);
  fs::remove(dir.path / "broken" / "paddle" / "paddle_000004.vtu");
  tetfsi::test::check_one_line_error(
      cli(dir.path, "export broken --to x"),
      {"frame 2 (step 4)", "paddle_000004.vtu", "missing", "--frames"});
  std::ofstream(dir.path / "broken" / "fluid" / "fluid_000002.vtu") << "<VTKFile garbage";
  tetfsi::test::check_one_line_error(cli(dir.path, "export broken --vdb --frames 1 --to y"),
                                     {"frame 1 (step 2)", "fluid_000002.vtu"});
  const Result ok = cli(dir.path, "export broken --frames :1 --to z");  // the good frame
  INFO("stderr: " << ok.err);
  CHECK(ok.code == 0);

  // A run without a fluid: --vdb alone is an error, the default exports the bodies.
  TempDir solid("export_solid");
  run_scene(solid.path, "sheets_drop.json", "--steps 2 --set output.every=1");
  tetfsi::test::check_one_line_error(cli(solid.path, "export o --vdb"),
                                     {"--vdb", "has no fluid", "--ply"});
  const Result s = cli(solid.path, "export o");
  INFO("stdout: " << s.out << "\nstderr: " << s.err);
  REQUIRE(s.code == 0);
  const std::vector<app::ExportedFrame> frames = manifest_frames(solid.path / "o");
  REQUIRE(frames.size() == 3);
  REQUIRE(frames[2].meshes.size() == 2);
  CHECK(frames[2].meshes[0].name == "lower");
  CHECK(frames[2].meshes[1].name == "upper");
  CHECK(frames[2].vdb_file.empty());
}

TEST_CASE(
    "tetfsi export: a grid liquid's cells as voxels and its surface as a PLY facing out of "
    "the water, the same PLY as the run's own export") {
  TempDir dir("export_liquid");
  run_scene(dir.path, "dam_break.json",
            "--steps 10 --set output.every=10 --set fluid.grid.cells=[36,12,15] --set "
            "'output.export=[\"ply\"]'");
  const Result r = cli(dir.path, "export o --to e --voxel-size 0.2");
  INFO("stdout: " << r.out << "\nstderr: " << r.err);
  REQUIRE(r.code == 0);
  CHECK(contains(r.out, "voxels: the grid's cells"));
  CHECK(contains(r.err, "hint: the fluid is a grid"));  // --voxel-size does not apply
  const std::vector<app::ExportedFrame> frames = manifest_frames(dir.path / "e");
  REQUIRE(frames.size() == 2);
  REQUIRE(frames[1].meshes.size() == 1);
  CHECK(frames[1].meshes[0].name == "liquid");
  // One construction of the liquid's surface: the export of the run's files writes the PLY the
  // run itself wrote (from the .vti's φ, which holds the run's doubles), byte for byte.
  for (const app::ExportedFrame& f : frames)
    for (const app::ExportedFrame::Mesh& m : f.meshes) {
      CAPTURE(m.file);
      CHECK(tetfsi::test::read_text(dir.path / "e" / m.file) ==
            tetfsi::test::read_text(dir.path / "o" / m.file));
    }
  const app::ExportSurface s = app::read_ply(dir.path / "e" / frames[0].meshes[0].file);
  CHECK(s.points.rows() == frames[0].meshes[0].vertices);
  // The water column's top: its triangles' normals point up (out of the water).
  const double top = s.points.col(2).maxCoeff();
  int up = 0, down = 0;
  for (Index t = 0; t < s.triangles.rows(); ++t) {
    const Vec3 a = s.points.row(s.triangles(t, 0)), b = s.points.row(s.triangles(t, 1)),
               c = s.points.row(s.triangles(t, 2));
    if (std::min({a.z(), b.z(), c.z()}) < top - 1e-6) continue;
    ((b - a).cross(c - a).z() > 0 ? up : down) += 1;
  }
  INFO("top triangles facing up " << up << ", down " << down);
  CHECK(up > 0);
  CHECK(down == 0);
  // The .vdb: the liquid's level set beside the fog volumes.
  const app::VdbFileSummary vdb = app::read_vdb_summary(dir.path / "e" / frames[1].vdb_file);
  CHECK(std::any_of(vdb.grids.begin(), vdb.grids.end(),
                    [](const auto& g) { return g.name == "surface"; }));
}
