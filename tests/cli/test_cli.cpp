// End-to-end tests of the `tetfsi` executable (cli/main.cpp): runs it as a user would, on
// tiny scenes written to a temporary folder, and checks exit codes, stderr and the output
// folder. TETFSI_EXE is the path of the built executable (tests/CMakeLists.txt, tetfsi_runs_cli).
#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLDataParser.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "scene/scene_keys.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;
using Result = tetfsi::test::CliResult;

/// Run `tetfsi <args>` in `cwd` (tests/test_util.hpp); `limits` is a shell prefix such as
/// "ulimit -v 4000000;".
Result run_cli(const fs::path& cwd, const std::string& args, const std::string& limits = "") {
  return ::tetfsi::test::run_tetfsi(cwd, args, limits);
}

/// A 2×2×2-cell box (27 nodes, 48 tets) of soft rubber, bottom face pinned, under gravity.
nlohmann::json tiny_scene(int steps = 5) {
  return nlohmann::json::parse(fmt::format(R"({{
    "name": "tiny",
    "time": {{ "dt": 0.01, "steps": {} }},
    "output": {{ "every": 1, "compression": "lz4" }},
    "bodies": [ {{
      "name": "block",
      "mesh": {{ "box": {{ "lo": [0, 0, 0], "hi": [1, 1, 1], "cells": [2, 2, 2] }} }},
      "material": {{ "density": 1000, "youngs_modulus": 1e5, "poisson_ratio": 0.3 }},
      "pins": [ {{ "box": {{ "lo": [-1, -1, -0.01], "hi": [2, 2, 0.01] }}, "axes": "xyz" }} ]
    }} ]
  }})",
                                           steps));
}

fs::path write_scene(const fs::path& dir, const nlohmann::json& j,
                     const std::string& file = "tiny.json") {
  const fs::path p = dir / file;
  std::ofstream(p) << j.dump(2);
  return p;
}

struct Pvd {
  std::vector<double> times;
  std::vector<std::string> files;
};

/// Parse a .pvd with VTK's XML parser; `ok` is false if it does not parse.
Pvd parse_pvd(const fs::path& p, bool& ok) {
  Pvd out;
  vtkNew<vtkXMLDataParser> parser;
  parser->SetFileName(p.c_str());
  ok = parser->Parse() == 1;
  if (!ok) return out;
  vtkXMLDataElement* coll = parser->GetRootElement()->FindNestedElementWithName("Collection");
  ok = coll != nullptr;
  if (!ok) return out;
  for (int i = 0; i < coll->GetNumberOfNestedElements(); ++i) {
    out.times.push_back(std::stod(coll->GetNestedElement(i)->GetAttribute("timestep")));
    out.files.emplace_back(coll->GetNestedElement(i)->GetAttribute("file"));
  }
  return out;
}

/// Number of points of a .vtu (−1 if VTK cannot read it).
long vtu_points(const fs::path& p) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  if (r->GetErrorCode() != 0 || !r->GetOutput()) return -1;
  return static_cast<long>(r->GetOutput()->GetNumberOfPoints());
}

/// Fluid runs: at most 4 GB of address space and 5 minutes, so that a remesher that runs
/// away fails the test instead of taking the machine down.
const std::string kFluidLimits = "ulimit -v 4000000; timeout 300";

/// Total area of the boundary of the tet mesh in a .vtu (the deformed body of a frame, m²):
/// the triangles that belong to exactly one tet. (Computed here rather than with tetfsi's
/// mesh library, so that the check does not share code with what it checks.)
double vtu_boundary_area(const fs::path& p) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkUnstructuredGrid* g = r->GetOutput();
  std::map<std::array<vtkIdType, 3>, int> count;
  for (vtkIdType t = 0; t < g->GetNumberOfCells(); ++t) {
    vtkIdType n = 0;
    const vtkIdType* pts = nullptr;
    g->GetCellPoints(t, n, pts);
    REQUIRE(n == 4);
    for (int k = 0; k < 4; ++k) {
      std::array<vtkIdType, 3> f;
      for (int c = 0, m = 0; c < 4; ++c)
        if (c != k) f[static_cast<size_t>(m++)] = pts[c];
      std::sort(f.begin(), f.end());
      ++count[f];
    }
  }
  double area = 0.0;
  for (const auto& [f, n] : count) {
    if (n != 1) continue;
    double a[3], b[3], c[3];
    g->GetPoint(f[0], a);
    g->GetPoint(f[1], b);
    g->GetPoint(f[2], c);
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double w[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                         u[0] * v[1] - u[1] * v[0]};
    area += 0.5 * std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  }
  return area;
}

/// Σ of a 1-component cell array of a .vtp, and its cell count.
double vtp_cell_sum(const fs::path& p, const char* array, long* cells = nullptr) {
  vtkNew<vtkXMLPolyDataReader> r;
  r->SetFileName(p.c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkDataArray* a = r->GetOutput()->GetCellData()->GetArray(array);
  REQUIRE(a != nullptr);
  double s = 0.0;
  for (vtkIdType i = 0; i < a->GetNumberOfTuples(); ++i) s += a->GetComponent(i, 0);
  if (cells) *cells = static_cast<long>(r->GetOutput()->GetNumberOfCells());
  return s;
}

std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ss(line);
  for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
  return f;
}

}  // namespace

TEST_CASE("tetfsi run: a 5-step scene writes frames, collection, stats and summary") {
  TempDir dir("run");
  write_scene(dir.path, tiny_scene(5));
  const Result r = run_cli(dir.path, "run tiny.json --progress plain");
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);

  const fs::path out = dir.path / "out" / "tiny";  // default: out/<scene name>
  CHECK(fs::exists(out / "scene.resolved.json"));
  CHECK(fs::exists(out / "summary.json"));
  REQUIRE(fs::exists(out / "stats.csv"));
  REQUIRE(fs::exists(out / "block.pvd"));

  const auto stats = lines_of(read_text(out / "stats.csv"));
  REQUIRE(stats.size() == 6);  // header + 5 steps
  CHECK(stats[0].rfind("step,time,dt,", 0) == 0);
  CHECK(stats[5].rfind("5,", 0) == 0);

  bool ok = false;
  const Pvd pvd = parse_pvd(out / "block.pvd", ok);
  REQUIRE(ok);
  REQUIRE(pvd.times.size() == 6);  // frame 0 and one per step
  for (int i = 0; i <= 5; ++i) {
    CHECK(pvd.times[i] == doctest::Approx(0.01 * i).epsilon(1e-12));
    CHECK(pvd.files[i] == fmt::format("block/block_{:06d}.vtu", i));
    CHECK(vtu_points(out / pvd.files[i]) == 27);
  }

  const auto resolved = nlohmann::json::parse(read_text(out / "scene.resolved.json"));
  CHECK(resolved["bodies"][0]["name"] == "block");
  const auto summary = nlohmann::json::parse(read_text(out / "summary.json"));
  CHECK(summary["completed"] == true);
  CHECK(summary["steps"] == 5);
  CHECK(summary["frames_written"] == 6);
  // Under gravity with a pinned base the block sags: it moved, and the summary says so.
  CHECK(summary["bodies"][0]["max_displacement"].get<double>() > 0.0);
  CHECK(r.out.find("5/5 steps") != std::string::npos);
  CHECK(r.out.find("max |d|") != std::string::npos);
}

TEST_CASE("tetfsi run: --set, --steps, --end-time and output.every change the run") {
  TempDir dir("overrides");
  write_scene(dir.path, tiny_scene(5));

  SUBCASE("--set time.steps=3") {
    const Result r = run_cli(dir.path, "run tiny.json --out o --progress off --set time.steps=3");
    INFO("stderr: " << r.err);
    REQUIRE(r.code == 0);
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 4);
  }
  SUBCASE("--steps 2 overrides the scene and is recorded in scene.resolved.json") {
    const Result r = run_cli(dir.path, "run tiny.json --out o --progress off --steps 2");
    INFO("stderr: " << r.err);
    REQUIRE(r.code == 0);
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 3);
    const auto resolved = nlohmann::json::parse(read_text(dir.path / "o" / "scene.resolved.json"));
    CHECK(resolved["time"]["steps"] == 2);
  }
  SUBCASE("--end-time 0.035 takes ceil(0.035 / 0.01) = 4 steps") {
    const Result r = run_cli(dir.path, "run tiny.json --out o --progress off --end-time 0.035");
    INFO("stderr: " << r.err);
    REQUIRE(r.code == 0);
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 5);
  }
  SUBCASE("output.every=2: frames at steps 0, 2, 4 and always the last one (5)") {
    const Result r = run_cli(dir.path, "run tiny.json --out o --progress off --set output.every=2");
    INFO("stderr: " << r.err);
    REQUIRE(r.code == 0);
    bool ok = false;
    const Pvd pvd = parse_pvd(dir.path / "o" / "block.pvd", ok);
    REQUIRE(ok);
    CHECK(pvd.files == std::vector<std::string>{"block/block_000000.vtu", "block/block_000002.vtu",
                                                "block/block_000004.vtu",
                                                "block/block_000005.vtu"});
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 6);  // stats every step
  }
  SUBCASE("--steps and --end-time together are a usage error") {
    const Result r = run_cli(dir.path, "run tiny.json --steps 2 --end-time 1");
    CHECK(r.code != 0);
    CHECK(!fs::exists(dir.path / "out"));
  }
}

TEST_CASE("tetfsi run: solid.integrator bfgs fills the equilibrium columns and summary block") {
  TempDir dir("equilibrium");
  write_scene(dir.path, tiny_scene(4));
  // The block sags under gravity from rest: BFGS iterates every step (2 at least: a step
  // converges once its second direction is small, core/equilibrium.hpp).
  const Result r =
      run_cli(dir.path, "run tiny.json --out o --progress off --set solid.integrator=bfgs");
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  const auto cols = tetfsi::test::read_csv_columns(dir.path / "o" / "stats.csv");
  REQUIRE(cols.count("equilibrium_iterations") == 1);
  REQUIRE(cols.count("equilibrium_evaluations") == 1);
  const std::vector<double>& it = cols.at("equilibrium_iterations");
  const std::vector<double>& ev = cols.at("equilibrium_evaluations");
  REQUIRE(it.size() == 4);
  for (size_t k = 0; k < it.size(); ++k) {
    INFO("step " << k + 1);
    CHECK(it[k] >= 2);
    CHECK(it[k] <= 30);
    CHECK(ev[k] >= it[k]);  // one residual per direction at least, the line searches' more
  }
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  REQUIRE(summary.contains("equilibrium"));
  const nlohmann::json& e = summary["equilibrium"];
  CHECK(e["method"] == "bfgs");
  CHECK(e["via"] == "solid.integrator");
  CHECK(e["steps"] == 4);
  CHECK(e["iteration_limit"] == 30);
  CHECK(e["max_iterations"] == *std::max_element(it.begin(), it.end()));
  double sum = 0.0, evals = 0.0;
  for (size_t k = 0; k < it.size(); ++k) sum += it[k], evals += ev[k];
  CHECK(e["avg_iterations"].get<double>() == doctest::Approx(sum / 4));
  CHECK(e["evaluations_per_step"].get<double>() == doctest::Approx(evals / 4));
  CHECK(r.out.find("equilibrium: bfgs (solid.integrator)") != std::string::npos);

  // The linearized integrator: the columns are there and 0, no block.
  const Result lin =
      run_cli(dir.path, "run tiny.json --out l --progress off --set solid.integrator=linearized");
  REQUIRE(lin.code == 0);
  const auto lcols = tetfsi::test::read_csv_columns(dir.path / "l" / "stats.csv");
  REQUIRE(lcols.count("equilibrium_iterations") == 1);
  for (double v : lcols.at("equilibrium_iterations")) CHECK(v == 0);
  for (double v : lcols.at("equilibrium_evaluations")) CHECK(v == 0);
  CHECK_FALSE(
      nlohmann::json::parse(read_text(dir.path / "l" / "summary.json")).contains("equilibrium"));
  CHECK(lin.out.find("equilibrium:") == std::string::npos);
}

TEST_CASE(
    "tetfsi run: stats.csv has each body's lowest point, centroid height and rotation, "
    "summary.json their extremes") {
  TempDir dir("body_pose");
  nlohmann::json s = tiny_scene(4);
  // A second body turning at 30 deg/s about x through its centre, its name not CSV-safe.
  nlohmann::json spin = s["bodies"][0];
  spin["name"] = "spin top";
  spin["mesh"]["box"]["lo"] = {2, 0, 0};
  spin["mesh"]["box"]["hi"] = {3, 1, 1};
  spin["pins"] = nlohmann::json::array();
  spin["kinematic"] = {{"angular_velocity_deg", {30, 0, 0}}};
  s["bodies"].push_back(spin);
  write_scene(dir.path, s);
  const Result r = run_cli(dir.path, "run tiny.json --out o --progress off");
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  const auto header = lines_of(read_text(dir.path / "o" / "stats.csv")).at(0);
  CHECK(
      header.ends_with(",block_lowest,block_centroid_height,block_rotation_deg,"
                       "spin_top_lowest,spin_top_centroid_height,spin_top_rotation_deg"));
  CHECK(header.rfind("step,time,dt,assemble,", 0) == 0);  // the fixed columns first, as before
  const auto cols = tetfsi::test::read_csv_columns(dir.path / "o" / "stats.csv");
  for (const char* body : {"block", "spin_top"}) {
    const std::string b = body;
    const auto& lowest = cols.at(b + "_lowest");
    const auto& centroid = cols.at(b + "_centroid_height");
    const auto& rotation = cols.at(b + "_rotation_deg");
    REQUIRE(lowest.size() == 4);
    for (size_t k = 0; k < 4; ++k) {
      CAPTURE(b);
      CAPTURE(k);
      CHECK(std::isfinite(lowest[k]));
      CHECK(std::isfinite(centroid[k]));
      CHECK(std::isfinite(rotation[k]));
      CHECK(lowest[k] <= centroid[k]);
      CHECK(rotation[k] >= 0.0);
      CHECK(rotation[k] <= 180.0);
    }
  }
  // The block is pinned at z = 0 and sags under gravity (−z): its lowest nodes stay at 0,
  // its centroid goes down from 0.5, it barely turns.
  for (size_t k = 0; k < 4; ++k) {
    CAPTURE(k);
    CHECK(cols.at("block_lowest")[k] == 0.0);
    CHECK(cols.at("block_centroid_height")[k] < 0.5);
    CHECK(cols.at("block_rotation_deg")[k] < 1.0);
    // The kinematic body: 0.3° per step about its centre; its lowest corner is
    // 0.5 (sin θ + cos θ) below the centre.
    const double deg = 0.3 * static_cast<double>(k + 1), th = deg * M_PI / 180.0;
    CHECK(std::abs(cols.at("spin_top_rotation_deg")[k] - deg) <= 1e-9);
    CHECK(std::abs(cols.at("spin_top_centroid_height")[k] - 0.5) <= 1e-12);
    CHECK(std::abs(cols.at("spin_top_lowest")[k] - (0.5 - 0.5 * (std::sin(th) + std::cos(th)))) <=
          1e-12);
  }
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  const auto& bodies = summary["bodies"];
  REQUIRE(bodies.size() == 2);
  for (size_t i = 0; i < 2; ++i) {
    const std::string b = i == 0 ? "block" : "spin_top";
    const auto& lowest = cols.at(b + "_lowest");
    const auto& rotation = cols.at(b + "_rotation_deg");
    CHECK(bodies[i]["min_lowest"].get<double>() == *std::min_element(lowest.begin(), lowest.end()));
    CHECK(bodies[i]["max_rotation_deg"].get<double>() ==
          *std::max_element(rotation.begin(), rotation.end()));
  }

  // Two bodies whose names give the same column name: a one-line error before any output.
  nlohmann::json clash = tiny_scene(2);
  nlohmann::json other = clash["bodies"][0];
  clash["bodies"][0]["name"] = "a-b";
  other["name"] = "a.b";
  other["mesh"]["box"]["lo"] = {2, 0, 0};
  other["mesh"]["box"]["hi"] = {3, 1, 1};
  clash["bodies"].push_back(other);
  write_scene(dir.path, clash, "clash.json");
  for (const std::string cmd : {"validate clash.json", "run clash.json --out c"}) {
    CAPTURE(cmd);
    const Result c = run_cli(dir.path, cmd + " --log-level warn");
    INFO("stderr: " << c.err);
    CHECK(c.code != 0);
    CHECK(c.err_lines().size() == 1);
    CHECK(c.err.find("bodies 'a-b' and 'a.b' share the stats.csv column name 'a_b'") !=
          std::string::npos);
  }
  CHECK(!fs::exists(dir.path / "c"));
}

TEST_CASE("tetfsi run: static mode writes frame 0 and the equilibrium at pseudo-time 1") {
  TempDir dir("static");
  nlohmann::json s = tiny_scene(5);
  s["mode"] = "static";
  write_scene(dir.path, s);
  const Result r = run_cli(dir.path, "run tiny.json --out o --progress off");
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  bool ok = false;
  const Pvd pvd = parse_pvd(dir.path / "o" / "block.pvd", ok);
  REQUIRE(ok);
  CHECK(pvd.times == std::vector<double>{0.0, 1.0});
  CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 2);
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["completed"] == true);
  CHECK(summary["solver_iterations"].get<int>() >= 1);
}

TEST_CASE("tetfsi validate: summary of a good scene, one-line error for an unknown key") {
  TempDir dir("validate");
  write_scene(dir.path, tiny_scene());
  const Result good = run_cli(dir.path, "validate tiny.json");
  INFO("stderr: " << good.err);
  CHECK(good.code == 0);
  CHECK(good.out.find("27 nodes") != std::string::npos);
  CHECK(good.out.find("48 tets") != std::string::npos);
  CHECK(good.out.find("27 fixed DOFs") != std::string::npos);  // 9 bottom nodes × 3
  const auto out_lines = lines_of(good.out);
  REQUIRE(!out_lines.empty());
  CHECK(out_lines.back() == "ok");

  nlohmann::json bad = tiny_scene();
  bad["bodies"][0]["material"].erase("poisson_ratio");
  bad["bodies"][0]["material"]["poison_ratio"] = 0.3;
  write_scene(dir.path, bad, "bad.json");
  const Result r = run_cli(dir.path, "validate bad.json");
  CHECK(r.code != 0);
  const auto lines = r.err_lines();
  REQUIRE(lines.size() == 1);
  CHECK(lines[0].rfind("error: ", 0) == 0);
  CHECK(lines[0].find("poison_ratio") != std::string::npos);
  CHECK(lines[0].find("did you mean") != std::string::npos);

  // --set goes through the same checks.
  const Result r2 = run_cli(dir.path, "validate tiny.json --set time.stpes=3");
  CHECK(r2.code != 0);
  REQUIRE(r2.err_lines().size() == 1);
  CHECK(r2.err.find("stpes") != std::string::npos);
}

TEST_CASE("tetfsi: a missing scene file is a one-line error") {
  TempDir dir("missing");
  for (const char* cmd : {"run nowhere.json", "validate nowhere.json"}) {
    CAPTURE(cmd);
    const Result r = run_cli(dir.path, cmd);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].rfind("error: ", 0) == 0);
    CHECK(lines[0].find("nowhere.json") != std::string::npos);
  }
}

TEST_CASE("tetfsi run: a failing step leaves a readable collection and a non-zero exit") {
  TempDir dir("fail");
  // The linearised midpoint rule at a step far beyond its stability: the energy grows
  // without bound and the divergence check (or a non-finite state) stops the run.
  nlohmann::json s = tiny_scene(10);
  s["gravity"] = {0.0, 0.0, -1e4};
  s["time"]["dt"] = 1.0;
  s["solid"]["trapezoid"] = "midpoint";
  s["output"]["every"] = 10;  // the last good step is written as a frame anyway
  write_scene(dir.path, s);
  const Result r = run_cli(dir.path, "run tiny.json --out o --progress off --log-level off");
  CHECK(r.code != 0);
  const auto lines = r.err_lines();
  REQUIRE(lines.size() == 1);
  CHECK(lines[0].rfind("error: step ", 0) == 0);

  bool ok = false;
  const Pvd pvd = parse_pvd(dir.path / "o" / "block.pvd", ok);
  REQUIRE(ok);
  REQUIRE(!pvd.files.empty());
  CHECK(pvd.times[0] == 0.0);
  for (const auto& f : pvd.files) CHECK(vtu_points(dir.path / "o" / f) == 27);
  for (const auto& e : fs::recursive_directory_iterator(dir.path / "o"))
    CHECK(e.path().extension() != ".tmp");
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["completed"] == false);
  CHECK(summary["error"].is_string());
  // stats.csv holds exactly the completed steps; the collection ends at the last of them.
  const int steps = summary["steps"].get<int>();
  CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 1 + static_cast<size_t>(steps));
  CHECK(pvd.files.back() == fmt::format("block/block_{:06d}.vtu", steps));
}

TEST_CASE("tetfsi run: Ctrl-C stops after the current step with a complete output folder") {
  TempDir dir("interrupt");
  nlohmann::json s = tiny_scene(1000000);  // far longer than the test waits
  s["output"]["every"] = 1000;
  write_scene(dir.path, s);
  const std::string cmd = fmt::format(
      "cd '{}' && ('{}' run tiny.json --out o --progress off >out.txt 2>err.txt & p=$!; "
      "sleep 1; kill -INT $p; wait $p; echo $? >code.txt)",
      dir.path.string(), TETFSI_EXE);
  REQUIRE(std::system(cmd.c_str()) == 0);
  CHECK(std::stoi(read_text(dir.path / "code.txt")) == 130);
  const auto err = lines_of(read_text(dir.path / "err.txt"));
  REQUIRE(!err.empty());
  CHECK(err.back().rfind("error: interrupted after step ", 0) == 0);
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["interrupted"] == true);
  CHECK(summary["completed"] == false);
  const size_t steps = summary["steps"].get<size_t>();
  CHECK(steps >= 1);
  CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == steps + 1);
  bool ok = false;
  const Pvd pvd = parse_pvd(dir.path / "o" / "block.pvd", ok);
  REQUIRE(ok);
  for (const auto& f : pvd.files) CHECK(vtu_points(dir.path / "o" / f) == 27);
  // The collection ends at the last completed step, though it is not a multiple of 1000.
  CHECK(pvd.files.back() == fmt::format("block/block_{:06d}.vtu", steps));
  CHECK(pvd.times.back() == doctest::Approx(0.01 * static_cast<double>(steps)).epsilon(1e-12));
}

TEST_CASE("tetfsi scene --keys prints the key tables, --markdown docs/user/scene_keys.md's") {
  TempDir dir("keys");
  const Result text = run_cli(dir.path, "scene --keys");
  CHECK(text.code == 0);
  CHECK(text.out == tetfsi::app::scene_keys_text());
  CHECK(text.out.find("time.dt") != std::string::npos);
  const Result md = run_cli(dir.path, "scene --keys --markdown");
  CHECK(md.code == 0);
  CHECK(md.out == tetfsi::app::scene_keys_markdown());
  CHECK(run_cli(dir.path, "scene").code != 0);  // --keys is required
  const Result help = run_cli(dir.path, "--help");
  CHECK(help.out.find("scene") != std::string::npos);
}

TEST_CASE("tetfsi --help, --version and usage errors") {
  TempDir dir("help");
  const Result help = run_cli(dir.path, "--help");
  CHECK(help.code == 0);
  for (const char* word : {"run", "validate", "bench", "--log-level"})
    CHECK(help.out.find(word) != std::string::npos);
  const Result run_help = run_cli(dir.path, "run --help");
  CHECK(run_help.code == 0);
  for (const char* word : {"--out", "--set", "--steps", "--end-time", "--progress"})
    CHECK(run_help.out.find(word) != std::string::npos);

  const Result version = run_cli(dir.path, "--version");
  CHECK(version.code == 0);
  CHECK(version.out.rfind("tetfsi ", 0) == 0);

  CHECK(run_cli(dir.path, "").code != 0);  // a subcommand is required
  CHECK(run_cli(dir.path, "frobnicate").code != 0);
  CHECK(run_cli(dir.path, "run x.json --progress loud").code != 0);
  const Result lvl = run_cli(dir.path, "validate x.json --log-level chatty");
  CHECK(lvl.code == 1);
  CHECK(lvl.err_lines().size() == 1);
}

TEST_CASE("the shipped csm1 scene: point A of the last frame within 3% of Turek-Hron CSM1") {
  // The user's view of docs/dev/validation_plan.md "Solid" CSM1: run data/scenes/csm1.json as
  // shipped (560 x 32 x 1 cells, ≈ 15 s), read the last frame with VTK, take the node whose rest
  // position is A = (0.6, 0.2, 0) and compare its displacement with the reference
  // u_x = −7.187e-3 m, u_y = −66.10e-3 m [Turek & Hron 2006]. Measured: 0.51% / 0.23%.
  TempDir dir("csm1");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "csm1.json";
  const Result r =
      run_cli(dir.path, fmt::format("run '{}' --out o --progress off", scene.string()));
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  bool ok = false;
  const Pvd pvd = parse_pvd(dir.path / "o" / "flag.pvd", ok);
  REQUIRE(ok);
  REQUIRE(pvd.files.size() == 2);
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  reader->SetFileName((dir.path / "o" / pvd.files.back()).c_str());
  reader->Update();
  vtkUnstructuredGrid* grid = reader->GetOutput();
  REQUIRE(grid != nullptr);
  vtkDataArray* rest = grid->GetPointData()->GetArray("rest_position");
  vtkDataArray* disp = grid->GetPointData()->GetArray("displacement");
  REQUIRE(rest != nullptr);
  REQUIRE(disp != nullptr);
  vtkIdType a = -1;
  double best = 1e300;
  for (vtkIdType i = 0; i < grid->GetNumberOfPoints(); ++i) {
    const double* X = rest->GetTuple3(i);
    const double dist = std::hypot(X[0] - 0.6, X[1] - 0.2, X[2]);
    if (dist < best) best = dist, a = i;
  }
  REQUIRE(best < 1e-9);
  const double* d = disp->GetTuple3(a);
  // The frame's points are the deformed positions: rest + displacement.
  const double* x = grid->GetPoint(a);
  CHECK(x[0] == doctest::Approx(0.6 + d[0]).epsilon(1e-12));
  CHECK(x[1] == doctest::Approx(0.2 + d[1]).epsilon(1e-12));
  const double ex = std::abs(d[0] + 7.187e-3) / 7.187e-3, ey = std::abs(d[1] + 66.10e-3) / 66.10e-3;
  MESSAGE("csm1 scene: u_x(A) = " << d[0] << " (err " << ex << "), u_y(A) = " << d[1] << " (err "
                                  << ey << ")");
  CHECK(ex < 0.03);
  CHECK(ey < 0.03);
}

TEST_CASE("tetfsi run: remesh_sheet writes the fluid mesh and its interface with every frame") {
  // The shipped scene, 3 steps with a frame each, at coarse fluid sizes (a few seconds),
  // one-way: each mesh is built around the sheet of its frame. (Two-way simultaneous, the
  // default, builds it around the predicted sheet x + h u instead, tests/run/
  // test_coupled_run.cpp.)
  TempDir dir("remesh_sheet");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "remesh_sheet.json";
  const Result r = run_cli(dir.path,
                           fmt::format("run '{}' --out o --progress off --steps 3 --set "
                                       "output.every=1 --set fluid.mesh.surface_size=0.1 --set "
                                       "fluid.mesh.far_size=0.4 --set coupling.scheme=none",
                                       scene.string()),
                           kFluidLimits);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  const fs::path out = dir.path / "o";
  CHECK(r.out.find("fluid: 4 remeshes") != std::string::npos);
  const Result v = run_cli(dir.path, fmt::format("validate '{}'", scene.string()));
  CHECK(v.code == 0);
  CHECK(v.out.find("fluid: box [-0.2, -0.2, -0.5]..[1.2, 1.2, 0.3], wall by default, 1 patch") !=
        std::string::npos);

  bool ok = false;
  const Pvd sheet = parse_pvd(out / "sheet.pvd", ok);
  REQUIRE(ok);
  const Pvd fluid = parse_pvd(out / "fluid.pvd", ok);
  REQUIRE(ok);
  const Pvd iface = parse_pvd(out / "interface.pvd", ok);
  REQUIRE(ok);
  REQUIRE(fluid.times.size() == 4);
  CHECK(fluid.times == sheet.times);
  CHECK(iface.times == sheet.times);
  for (int i = 0; i < 4; ++i) {
    CAPTURE(i);
    CHECK(fluid.files[i] == fmt::format("fluid/fluid_{:06d}.vtu", i));
    CHECK(iface.files[i] == fmt::format("interface/interface_{:06d}.vtp", i));

    // The fluid mesh with its quality arrays.
    vtkNew<vtkXMLUnstructuredGridReader> reader;
    reader->SetFileName((out / fluid.files[i]).c_str());
    reader->Update();
    REQUIRE(reader->GetErrorCode() == 0);
    vtkUnstructuredGrid* g = reader->GetOutput();
    CHECK(g->GetNumberOfCells() > 1000);
    for (const char* a : {"volume", "q_min_dihedral_deg", "q_max_dihedral_deg", "q_radius_edge",
                          "q_shape", "touches_solid"}) {
      CAPTURE(a);
      REQUIRE(g->GetCellData()->GetArray(a) != nullptr);
      CHECK(g->GetCellData()->GetArray(a)->GetNumberOfTuples() == g->GetNumberOfCells());
    }
    vtkDataArray* vb = g->GetPointData()->GetArray("vertex_body");
    REQUIRE(vb != nullptr);
    double range[2];
    vb->GetRange(range);
    CHECK(range[0] == -1.0);  // fluid samples
    CHECK(range[1] == 0.0);   // and vertices on the sheet (body 0)

    // The interface faces tile the sheet's boundary at that frame: their area is the area of
    // the deformed sheet's boundary triangles (2 · 1 · 1 + 4 · 1 · 0.02 = 2.08 m² flat).
    long faces = 0;
    const double area = vtp_cell_sum(out / iface.files[i], "area", &faces);
    CHECK(faces >= 2 * 20 * 20 * 2);  // at least the sheet's own boundary triangles
    const double sheet_area = vtu_boundary_area(out / sheet.files[i]);
    if (i == 0) CHECK(sheet_area == doctest::Approx(2.08).epsilon(1e-12));
    CHECK(area == doctest::Approx(sheet_area).epsilon(1e-9));
    CHECK(vtp_cell_sum(out / iface.files[i], "body") == 0.0);
  }

  // stats.csv: the remesh phase, the fluid figures and the quality summary every step.
  const auto stats = lines_of(read_text(out / "stats.csv"));
  REQUIRE(stats.size() == 4);
  const auto cols = csv_fields(stats[0]);
  for (const char* c :
       {"remesh", "fluid_cells", "fluid_vertices", "steiner_points", "recovery_rounds", "remesh_s",
        "q_min_dihedral_deg", "q_slivers", "q_max_weight"})
    CHECK(std::find(cols.begin(), cols.end(), c) != cols.end());
  const auto row = csv_fields(stats[3]);
  REQUIRE(row.size() == cols.size());
  const size_t cells_col =
      static_cast<size_t>(std::find(cols.begin(), cols.end(), "fluid_cells") - cols.begin());
  CHECK(std::stol(row[cells_col]) > 1000);

  const auto summary = nlohmann::json::parse(read_text(out / "summary.json"));
  CHECK(summary["completed"] == true);
  CHECK(summary["fluid"]["remeshes"] == 4);
  CHECK(summary["fluid"]["cells"].get<long>() == std::stol(row[cells_col]));
}

TEST_CASE("tetfsi run: a body outside the fluid box is a one-line error naming the body") {
  TempDir dir("fluid_outside");
  SUBCASE("already at t = 0: frame 0 of the body and no step") {
    nlohmann::json s = tiny_scene(5);
    s["fluid"] = {{"domain", {{"lo", {-0.5, -0.5, -0.5}}, {"hi", {1.5, 1.5, 0.9}}}},
                  {"mesh", {{"surface_size", 0.25}, {"far_size", 0.5}}}};
    write_scene(dir.path, s);
    const Result r =
        run_cli(dir.path, "run tiny.json --out o --progress off --log-level off", kFluidLimits);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].rfind("error: step 0 (t = 0 s) failed: body 'block' (bodies[0]) is not "
                         "strictly inside the fluid box",
                         0) == 0);
    CHECK(lines[0].find("enlarge fluid.domain") != std::string::npos);
    bool ok = false;
    const Pvd pvd = parse_pvd(dir.path / "o" / "block.pvd", ok);
    REQUIRE(ok);
    CHECK(pvd.times == std::vector<double>{0.0});
    CHECK(!fs::exists(dir.path / "o" / "fluid.pvd"));  // no fluid mesh could be built
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 1);
    const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
    CHECK(summary["completed"] == false);
    CHECK(summary["steps"] == 0);
    CHECK(summary["error"].get<std::string>().find("body 'block'") != std::string::npos);
  }
  SUBCASE("falling out during the run: the frames up to the last good step stay") {
    // An unpinned block falling at 1 m/s leaves the box (its bottom 5 cm below it) after
    // about 5 steps of 0.01 s.
    nlohmann::json s = tiny_scene(20);
    s["bodies"][0]["pins"] = nlohmann::json::array();
    s["bodies"][0]["initial_velocity"] = {0.0, 0.0, -1.0};
    s["output"]["every"] = 2;
    s["fluid"] = {{"domain", {{"lo", {-0.5, -0.5, -0.05}}, {"hi", {1.5, 1.5, 1.5}}}},
                  {"mesh", {{"surface_size", 0.25}, {"far_size", 0.5}}}};
    write_scene(dir.path, s);
    const Result r =
        run_cli(dir.path, "run tiny.json --out o --progress off --log-level off", kFluidLimits);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].rfind("error: step ", 0) == 0);
    CHECK(lines[0].find("failed: body 'block' (bodies[0]) is not strictly inside the fluid box") !=
          std::string::npos);
    const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
    CHECK(summary["completed"] == false);
    const int steps = summary["steps"].get<int>();
    CHECK(steps >= 3);
    CHECK(steps <= 6);
    CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() ==
          1 + static_cast<size_t>(steps));
    // Body and fluid collections both end at the last good step, with the same times.
    bool ok = false;
    const Pvd body = parse_pvd(dir.path / "o" / "block.pvd", ok);
    REQUIRE(ok);
    const Pvd fluid = parse_pvd(dir.path / "o" / "fluid.pvd", ok);
    REQUIRE(ok);
    CHECK(fluid.times == body.times);
    CHECK(body.files.back() == fmt::format("block/block_{:06d}.vtu", steps));
    CHECK(fluid.files.back() == fmt::format("fluid/fluid_{:06d}.vtu", steps));
    for (const auto& e : fs::recursive_directory_iterator(dir.path / "o"))
      CHECK(e.path().extension() != ".tmp");
  }
}

TEST_CASE("tetfsi validate and run: a fluid scene without bodies") {
  TempDir dir("fluid_only");
  nlohmann::json s = nlohmann::json::parse(R"({
    "name": "smoke_box",
    "time": { "dt": 0.01, "steps": 2 },
    "fluid": {
      "domain": { "lo": [0, 0, 0], "hi": [1, 1, 1], "default": "wall",
                  "patches": [ { "name": "jet", "kind": "inflow", "side": "-z",
                                 "lo": [0.4, 0.4], "hi": [0.6, 0.6], "speed": 1, "smoke": 1 } ] },
      "mesh": { "surface_size": 0.25, "far_size": 0.5 },
      "sources": [ { "box": { "lo": [0.4, 0.4, 0.1], "hi": [0.6, 0.6, 0.2] } } ]
    }
  })");
  write_scene(dir.path, s, "smoke.json");
  const Result v = run_cli(dir.path, "validate smoke.json");
  INFO("stderr: " << v.err);
  CHECK(v.code == 0);
  CHECK(v.out.find("bodies: none") != std::string::npos);
  CHECK(v.out.find("fluid physics: density 1.2 kg/m^3, gravity off, reconstruction whitney, "
                   "pressure solver amg, 1 source") != std::string::npos);
  CHECK(lines_of(v.out).back() == "ok");

  const Result r =
      run_cli(dir.path, "run smoke.json --out o --progress off --log-level warn", kFluidLimits);
  INFO("run stderr: " << r.err);
  REQUIRE(r.code == 0);
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["completed"] == true);
  CHECK(summary["steps"] == 2);
  CHECK(summary["bodies"] == nlohmann::json::array());
  CHECK(summary["fluid"]["remeshes"] == 3);
  CHECK(summary["energy"]["total"] == 0.0);
  bool ok = false;
  const Pvd fluid = parse_pvd(dir.path / "o" / "fluid.pvd", ok);
  REQUIRE(ok);
  CHECK(fluid.times.size() == 3);
  CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 3);
  const auto resolved = nlohmann::json::parse(read_text(dir.path / "o" / "scene.resolved.json"));
  CHECK(resolved["bodies"] == nlohmann::json::array());
  CHECK(resolved["fluid"]["domain"]["patches"][0]["speed"] == 1.0);
  CHECK(resolved["fluid"]["sources"][0]["name"] == "source0");
}

TEST_CASE("tetfsi validate and run: a kinematic body follows its motion inside the fluid") {
  TempDir dir("kinematic");
  nlohmann::json s = tiny_scene(4);
  auto& b = s["bodies"][0];
  b["pins"] = nlohmann::json::array();
  b["kinematic"] = {{"velocity", {0.5, 0, 0}}, {"angular_velocity_deg", {0, 0, 30}}};
  s["fluid"] = {{"domain", {{"lo", {-0.5, -0.5, -0.5}}, {"hi", {1.8, 1.5, 1.5}}}},
                {"mesh", {{"surface_size", 0.25}, {"far_size", 0.5}}}};
  write_scene(dir.path, s);
  const Result v = run_cli(dir.path, "validate tiny.json");
  INFO("stderr: " << v.err);
  CHECK(v.code == 0);
  CHECK(v.out.find("body 'block': 27 nodes, 48 tets, mass 1000 kg, kinematic: velocity "
                   "[0.5, 0, 0] m/s, angular velocity [0, 0, 30] deg/s about "
                   "[0.5, 0.5, 0.5]") != std::string::npos);

  const Result r =
      run_cli(dir.path, "run tiny.json --out o --progress off --log-level warn", kFluidLimits);
  INFO("run stderr: " << r.err);
  REQUIRE(r.code == 0);
  // Node displacements are v t + (R(t) − I)(X − c) at t = 0.04 s (c the box centre); the
  // largest over the 27 grid nodes (z plays no part in a rotation about z):
  const double t = 0.04, theta = 30.0 * M_PI / 180.0 * t;
  double expected = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double x = 0.5 * i - 0.5, y = 0.5 * j - 0.5;  // X − c
      const double dx = 0.5 * t + std::cos(theta) * x - std::sin(theta) * y - x;
      const double dy = std::sin(theta) * x + std::cos(theta) * y - y;
      expected = std::max(expected, std::hypot(dx, dy));
    }
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["completed"] == true);
  CHECK(summary["solver_iterations"] == 0);  // nothing was solved
  CHECK(summary["bodies"][0]["max_displacement"].get<double>() ==
        doctest::Approx(expected).epsilon(1e-12));
  CHECK(summary["energy"]["elastic"].get<double>() == doctest::Approx(0.0));
  CHECK(summary["fluid"]["remeshes"] == 5);
}
