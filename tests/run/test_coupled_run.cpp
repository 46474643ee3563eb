/// @file test_coupled_run.cpp
/// Two-way coupled runs through the run loop (run/run.cpp, in-process: load_scene with
/// --set overrides, then run_scene, as `tetfsi run` does): tests/scenes/
/// soft_box_in_water.json, a soft box (2000 kg/m³) sinking in water, 3 steps on a coarse fluid
/// mesh. Checks the coupling columns of stats.csv, the interface stream against the fluid and
/// body streams, summary.json's coupling block, and that the box sinks slower than in free
/// fall (buoyancy, added mass) but does sink — simultaneous and splitting; "none" keeps the
/// one-way output.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLDataParser.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/output.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;
using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;

namespace {

const fs::path kScene = fs::path(TETFSI_SOURCE_DIR) / "tests" / "scenes" / "soft_box_in_water.json";
constexpr int kSteps = 3;
constexpr double kDt = 0.01;

RunResult run(const fs::path& out, const std::vector<std::string>& overrides) {
  RunOptions opt;
  opt.out_dir = out;
  opt.progress = ProgressMode::Off;
  const RunResult r = run_scene(load_scene(kScene, overrides), opt);
  INFO("run error: " << r.error);
  REQUIRE(r.completed);
  REQUIRE(r.steps_done == kSteps);
  return r;
}

using Stats = std::map<std::string, std::vector<double>>;

/// stats.csv as columns: name → one value per step.
Stats read_stats(const fs::path& p) {
  const Stats cols = tetfsi::test::read_csv_columns(p);
  REQUIRE(!cols.empty());
  for (const auto& [name, v] : cols) REQUIRE(v.size() == kSteps);
  return cols;
}

/// Times of a .pvd (VTK's XML parser); REQUIREs that it parses.
std::vector<double> pvd_times(const fs::path& p, std::vector<std::string>* files = nullptr) {
  INFO("collection " << p);
  vtkNew<vtkXMLDataParser> parser;
  parser->SetFileName(p.c_str());
  REQUIRE(parser->Parse() == 1);
  vtkXMLDataElement* coll = parser->GetRootElement()->FindNestedElementWithName("Collection");
  REQUIRE(coll != nullptr);
  std::vector<double> times;
  for (int i = 0; i < coll->GetNumberOfNestedElements(); ++i) {
    times.push_back(std::stod(coll->GetNestedElement(i)->GetAttribute("timestep")));
    if (files) files->emplace_back(coll->GetNestedElement(i)->GetAttribute("file"));
  }
  return times;
}

/// z displacement (m) of the box's centre of mass in the frame of the last step, from the
/// frame's points and rest positions: Σ_t V0_t (c_t − C_t) / Σ_t V0_t over its tets (c, C
/// the deformed and rest centroids), which is the lumped-mass centre of mass.
double com_dz(const fs::path& out) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName((out / "box" / fmt::format("box_{:06d}.vtu", kSteps)).c_str());
  r->Update();
  REQUIRE(r->GetErrorCode() == 0);
  vtkUnstructuredGrid* g = r->GetOutput();
  vtkDataArray* X = g->GetPointData()->GetArray("rest_position");
  REQUIRE(X != nullptr);
  double volume = 0.0, moment = 0.0;
  for (vtkIdType t = 0; t < g->GetNumberOfCells(); ++t) {
    vtkIdType n = 0;
    const vtkIdType* pts = nullptr;
    g->GetCellPoints(t, n, pts);
    REQUIRE(n == 4);
    double x[4][3], e[3][3], dz = 0.0;
    for (int k = 0; k < 4; ++k) {
      X->GetTuple(pts[k], x[k]);
      double p[3];
      g->GetPoint(pts[k], p);
      dz += 0.25 * (p[2] - x[k][2]);
    }
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) e[k][c] = x[k + 1][c] - x[0][c];
    const double v = std::abs(e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                              e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                              e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0])) /
                     6.0;
    volume += v;
    moment += v * dz;
  }
  REQUIRE(volume == doctest::Approx(0.2 * 0.2 * 0.2));
  return moment / volume;
}

/// Free fall over the run with the paper's trapezoidal rule (exact for constant g).
const double kFreeFall = 0.5 * 9.81 * (kSteps * kDt) * (kSteps * kDt);

void check_coupled_output(const fs::path& out, const std::string& scheme) {
  // stats.csv: the coupling columns and phases, finite in every row
  const Stats s = read_stats(out / "stats.csv");
  for (const char* c :
       {"coupled_iterations", "coupled_residual", "interface_power", "fluid_kinetic_energy",
        "kinetic_energy", "elastic_energy", "total_energy_coupled", "enclosed_volume",
        "enclosed_volume_drift", "coupled_assembly", "coupled_solve", "solid", "update", "remesh",
        "transfer", "forces", "box_lowest", "box_centroid_height", "box_rotation_deg"}) {
    CAPTURE(c);
    REQUIRE(s.count(c) == 1);
    for (double v : s.at(c)) CHECK(std::isfinite(v));
  }
  for (int i = 0; i < kSteps; ++i) {
    CAPTURE(i);
    const auto at = [&](const char* c) { return s.at(c)[static_cast<size_t>(i)]; };
    CHECK(at("total_energy_coupled") ==
          doctest::Approx(at("fluid_kinetic_energy") + at("kinetic_energy") + at("elastic_energy"))
              .epsilon(1e-12));
    CHECK(at("coupled_iterations") >= 1);
    CHECK(at("coupled_residual") < 1e-6);
    CHECK(at("fluid_kinetic_energy") > 0);  // the box pushes the water
    CHECK(at("enclosed_volume") == 0.0);    // no closed region of water
    CHECK(at("enclosed_volume_drift") == 0.0);
    CHECK(at("coupled_solve") > 0);
    if (scheme == "splitting") CHECK(at("solid") > 0);
    CHECK(at("box_lowest") < at("box_centroid_height"));
    if (i > 0)  // sinks
      CHECK(at("box_centroid_height") < s.at("box_centroid_height")[static_cast<size_t>(i - 1)]);
  }

  // the streams: frames 0..3 in every collection, the same times
  std::vector<std::string> files;
  const auto body = pvd_times(out / "box.pvd");
  const auto fluid = pvd_times(out / "fluid.pvd");
  const auto iface = pvd_times(out / "interface.pvd", &files);
  REQUIRE(body.size() == kSteps + 1);
  CHECK(fluid == body);
  CHECK(iface == body);
  for (size_t i = 0; i < files.size(); ++i) {
    CAPTURE(i);
    vtkNew<vtkXMLPolyDataReader> r;
    r->SetFileName((out / files[i]).c_str());
    r->Update();
    REQUIRE(r->GetErrorCode() == 0);
    vtkPolyData* p = r->GetOutput();
    CHECK(p->GetNumberOfCells() >= 6 * 9 * 2);  // at least the box's boundary triangles
    for (const char* a : {"pressure", "normal_velocity", "body"}) {
      CAPTURE(a);
      vtkDataArray* arr = p->GetCellData()->GetArray(a);
      REQUIRE(arr != nullptr);
      REQUIRE(arr->GetNumberOfTuples() == p->GetNumberOfCells());
      for (vtkIdType k = 0; k < arr->GetNumberOfTuples(); ++k)
        CHECK(std::isfinite(arr->GetComponent(k, 0)));
    }
    // After a step the pressure is zero at the open top (z = 1): on the box, between z =
    // 0.35 and 0.55, it is ρ g (1 − z) and a small dynamic part. (Frame 0, the fluid at rest
    // as fluid::FluidSimulation::initialize leaves it, has ρ g·x instead: zero at z = 0.)
    double range[2];
    p->GetCellData()->GetArray("pressure")->GetRange(range);
    CHECK(range[1] > range[0]);
    if (i > 0) {
      CHECK(range[0] > 0.5 * 1000.0 * 9.81 * 0.45);
      CHECK(range[1] < 1.5 * 1000.0 * 9.81 * 0.65);
    }
    // the faces move with the box: at rest at t = 0, sinking after
    p->GetCellData()->GetArray("normal_velocity")->GetRange(range);
    if (i == 0) CHECK(std::max(std::abs(range[0]), std::abs(range[1])) == 0.0);
    if (i > 0) CHECK(range[1] - range[0] > 0.0);
  }

  // summary.json: the coupling block
  const auto summary = nlohmann::json::parse(read_text(out / "summary.json"));
  REQUIRE(summary.contains("coupling"));
  const auto& c = summary["coupling"];
  CHECK(c["scheme"] == scheme);
  CHECK(c["solver"] == "schur_amg");
  CHECK(c["coupled_steps"] == kSteps);
  double iterations = 0.0, power = 0.0;
  for (int i = 0; i < kSteps; ++i) {
    iterations += s.at("coupled_iterations")[static_cast<size_t>(i)];
    power = std::max(power, std::abs(s.at("interface_power")[static_cast<size_t>(i)]));
  }
  CHECK(c["coupled_iterations"].get<double>() == iterations);
  CHECK(c["max_interface_power"].get<double>() == doctest::Approx(power));
  CHECK(c["unconverged_solves"] == 0);
  CHECK(c["max_volume_drift"] == 0.0);
  CHECK(summary["fluid"]["fluid_steps"] == kSteps);

  const auto resolved = nlohmann::json::parse(read_text(out / "scene.resolved.json"));
  CHECK(resolved["coupling"]["scheme"] == scheme);
  CHECK(resolved["fluid"]["enclosed_density"] == 0.0);
}

}  // namespace

TEST_CASE(
    "coupled run (simultaneous, the default): coupling columns, interface stream, the "
    "box sinks slower than in free fall") {
  TempDir dir("coupled_simultaneous");
  const RunResult r = run(dir.path / "o", {});
  REQUIRE(r.coupling);
  CHECK(r.coupling->scheme == "simultaneous");
  check_coupled_output(dir.path / "o", "simultaneous");
  // Buoyancy halves the pull (ρ_s = 2 ρ_w) and the added mass slows it further: a cube's
  // added mass is about 0.7 of the water it displaces, a = g (2 − 1) / (2 + 0.7) = 0.37 g.
  const double dz = com_dz(dir.path / "o");
  CHECK(dz < -0.25 * kFreeFall);
  CHECK(dz > -0.5 * kFreeFall);
  std::ostringstream text;
  print_summary(r, text);
  CHECK(text.str().find("coupling: simultaneous (schur_amg), 3 coupled steps") !=
        std::string::npos);
}

TEST_CASE("coupled run (splitting): the same output, the box sinks") {
  TempDir dir("coupled_splitting");
  const RunResult r = run(dir.path / "o", {"coupling.scheme=splitting"});
  REQUIRE(r.coupling);
  CHECK(r.coupling->scheme == "splitting");
  CHECK(r.coupling->solid_iterations > 0);
  check_coupled_output(dir.path / "o", "splitting");
  // The held pressure carries the buoyancy and, one step late, the added mass.
  const double dz = com_dz(dir.path / "o");
  CHECK(dz < -0.25 * kFreeFall);
  CHECK(dz > -0.6 * kFreeFall);
}

TEST_CASE(
    "coupled run: scheme none is the one-way run (the box falls freely, no coupling "
    "output)") {
  TempDir dir("coupled_none");
  const RunResult r = run(dir.path / "o", {"coupling.scheme=none"});
  CHECK_FALSE(r.coupling);
  const auto header = lines_of(read_text(dir.path / "o" / "stats.csv")).at(0);
  std::vector<std::string> cols;
  {
    std::stringstream ss(header);
    for (std::string c; std::getline(ss, c, ',');) cols.push_back(c);
  }
  CHECK(cols == StatsWriter::columns(true, false, {"box"}));
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK_FALSE(summary.contains("coupling"));
  const auto resolved = nlohmann::json::parse(read_text(dir.path / "o" / "scene.resolved.json"));
  CHECK(resolved["coupling"]["scheme"] == "none");
  CHECK(com_dz(dir.path / "o") == doctest::Approx(-kFreeFall).epsilon(1e-9));
}

TEST_CASE(
    "coupled run on the grid (fluid.discretization grid): .vti frames in fluid.pvd, the "
    "interface's triangles in interface.pvd, the box sinks as on the tet mesh, every scheme "
    "runs") {
  for (const std::string scheme : {"simultaneous", "splitting", "bfgs", "newton"}) {
    CAPTURE(scheme);
    TempDir dir("coupled_grid_" + scheme);
    const fs::path out = dir.path / "o";
    const RunResult r = run(out, {"fluid.discretization=grid", "fluid.grid.cell_size=0.05",
                                  "coupling.scheme=" + scheme});
    REQUIRE(r.coupling);
    std::vector<std::string> files;
    const std::vector<double> times = pvd_times(out / "fluid.pvd", &files);
    REQUIRE(times.size() == kSteps + 1);
    for (const std::string& f : files) {
      CHECK(f.size() > 4);
      CHECK(f.substr(f.size() - 4) == ".vti");
      CHECK(fs::exists(out / f));
    }
    CHECK(pvd_times(out / "interface.pvd") == times);
    // 20^3 cells, the box's 0.2 m cube resolved by 4 cells a side
    const auto summary = nlohmann::json::parse(read_text(out / "summary.json"));
    CHECK(summary["fluid"]["cells"].get<double>() == doctest::Approx(8000 - 64).epsilon(0.01));
    const auto resolved = nlohmann::json::parse(read_text(out / "scene.resolved.json"));
    CHECK(resolved["fluid"]["discretization"] == "grid");
    CHECK(resolved["fluid"]["grid"]["cells"] == nlohmann::json::array({20, 20, 20}));
    // buoyancy and the added mass: between a quarter and a half of free fall (the paper's
    // J; splitting and the iterated schemes' added mass comes a step late or by iteration)
    const double dz = com_dz(out);
    CHECK(dz < -0.25 * kFreeFall);
    CHECK(dz > -0.6 * kFreeFall);
  }
}

TEST_CASE("grid scenes: a bad grid is a one-line error naming the key") {
  const auto error = [](const std::vector<std::string>& set) {
    try {
      load_scene(kScene, set);
    } catch (const tetfsi::InputError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  CHECK(error({"fluid.discretization=grid"}).find("needs fluid.grid with cell_size") !=
        std::string::npos);
  CHECK(error({"fluid.discretization=grid", "fluid.grid.cell_size=0"})
            .find("fluid.grid.cell_size: must be in [1e-9, 1e6]") != std::string::npos);
  CHECK(error({"fluid.discretization=grid", "fluid.grid.cell_size=0.001"})
            .find("more than fluid.grid.max_cells") != std::string::npos);
  CHECK(error({"fluid.discretization=grid", "fluid.grid.cell_size=0.1", "fluid.grid.cells=[5,5,5]"})
            .find("disagrees with cell_size") != std::string::npos);
  CHECK(error({"fluid.discretization=grid", "fluid.grid.cell_size=0.1", "fluid.refine.size=0.1"})
            .find("fluid.refine: is a key of the tet mesh") != std::string::npos);
  CHECK(error({"fluid.discretization=cubes"}).find("fluid.discretization") != std::string::npos);
  // a body smaller than a cell on two axes: refused when the run starts, naming the body
  RunOptions opt;
  TempDir dir("grid_coarse");
  opt.out_dir = dir.path / "o";
  opt.progress = ProgressMode::Off;
  const RunResult r =
      run_scene(load_scene(kScene, {"fluid.discretization=grid", "fluid.grid.cells=[2,2,2]"}), opt);
  CHECK_FALSE(r.completed);
  CHECK(r.error.find("smaller than a grid cell") != std::string::npos);
  CHECK(r.error.find("'box'") != std::string::npos);
}
