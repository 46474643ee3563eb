// CLI tests of `tetfsi bench step` (bench/bench_step.cpp): a small fluid scene written to a
// temporary folder, three mesh sizes given by --sizes, the JSON report checked for its shape
// and sanity (not for speed: benchmarks are never timed tests).
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using tetfsi::test::positive_finite;
using tetfsi::test::read_text;
using tetfsi::test::run_tetfsi;
using tetfsi::test::TempDir;

/// A unit box of air with a jet on −x and an open +x side around a 0.2 m block that turns at
/// 90°/s (kinematic): about 4k–9k fluid cells at scales 2 … 1.3.
const char* const k_jet_scene = R"({
  "name": "bench_jet",
  "time": { "dt": 0.01, "steps": 3 },
  "bodies": [ {
    "name": "block",
    "mesh": { "box": { "lo": [0.4, 0.4, 0.4], "hi": [0.6, 0.6, 0.6], "cells": [2, 2, 2] } },
    "material": { "density": 1000, "youngs_modulus": 1e5, "poisson_ratio": 0.3 },
    "kinematic": { "angular_velocity_deg": [0, 0, 90] }
  } ],
  "fluid": {
    "domain": { "lo": [0, 0, 0], "hi": [1, 1, 1], "default": "wall",
                "patches": [
                  { "name": "jet", "kind": "inflow", "side": "-x", "lo": [0.3, 0.3],
                    "hi": [0.7, 0.7], "speed": 1, "smoke": 1 },
                  { "name": "out", "kind": "open", "side": "+x", "lo": [0, 0], "hi": [1, 1] } ] },
    "mesh": { "surface_size": 0.05, "far_size": 0.1, "grading": 0.5 }
  }
})";

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

}  // namespace

TEST_CASE("bench step: three sizes, JSON with cells increasing and positive figures") {
  TempDir dir("bench_step");
  write(dir.path / "jet.json", k_jet_scene);
  const auto r = run_tetfsi(dir.path, "bench step jet.json --sizes 2,1.6,1.3 --json step.json");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("floor_s") != std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "step.json"));
  REQUIRE(j.contains("cases"));
  const nlohmann::json& cases = j["cases"];
  REQUIRE(cases.is_array());
  REQUIRE(cases.size() == 3);
  double last_cells = 0;
  for (const nlohmann::json& c : cases) {
    INFO(c.dump());
    for (const char* key : {"cells", "step_s", "floor_s", "ratio", "iterations"}) {
      INFO(key);
      REQUIRE(c.contains(key));
      CHECK(positive_finite(c[key]));
    }
    REQUIRE(c.contains("phases"));
    // forces may round to well under a millisecond but is measured, so still > 0
    for (const char* key : {"remesh", "transfer", "forces", "assembly", "solve", "output"}) {
      INFO(key);
      REQUIRE(c["phases"].contains(key));
      CHECK(positive_finite(c["phases"][key]));
    }
    CHECK(c["cells"].get<double>() > last_cells);
    last_cells = c["cells"].get<double>();
    CHECK(c["ratio"].get<double>() ==
          doctest::Approx(c["step_s"].get<double>() / c["floor_s"].get<double>()).epsilon(1e-9));
  }
  CHECK(cases[0]["scale"].get<double>() == doctest::Approx(2.0));
}

TEST_CASE("bench step: a scene without fluid is a one-line error - --steps 1 is a usage error") {
  TempDir dir("bench_step_err");
  nlohmann::json j = nlohmann::json::parse(k_jet_scene);
  j.erase("fluid");
  write(dir.path / "solid.json", j.dump());
  const auto r = run_tetfsi(dir.path, "bench step solid.json --sizes 2");
  CHECK(r.code == 1);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(r.err_lines()[0].find("error: solid.json: bench step needs a fluid scene") == 0);

  write(dir.path / "jet.json", k_jet_scene);
  const auto u = run_tetfsi(dir.path, "bench step jet.json --steps 1");
  CHECK(u.code != 0);
  CHECK(u.code != 1);  // CLI11's usage exit code, not a tetfsi error
  CHECK(u.err.find("--steps") != std::string::npos);
}

TEST_CASE("bench step: a grid scene is timed on two grids against its floor and the tet mesh") {
  TempDir dir("bench_step_grid");
  nlohmann::json j = nlohmann::json::parse(k_jet_scene);
  j["fluid"]["discretization"] = "grid";
  j["fluid"]["grid"] = {{"cells", {20, 20, 20}}};
  write(dir.path / "grid.json", j.dump());
  const auto r = run_tetfsi(dir.path, "bench step grid.json --sizes 2,1.25 --json step.json");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("g/tet") != std::string::npos);
  const nlohmann::json out = nlohmann::json::parse(read_text(dir.path / "step.json"));
  CHECK(out["discretization"] == "grid");
  const nlohmann::json& cases = out["cases"];
  REQUIRE(cases.size() == 2);
  // 10³ and 16³ cells; the block (0.2 m of the 1 m box) is not fluid
  CHECK(cases[0]["grid_cells"] == 1000);
  CHECK(cases[1]["grid_cells"] == 4096);
  for (const nlohmann::json& c : cases) {
    INFO(c.dump());
    CHECK(c["cells"].get<double>() < c["grid_cells"].get<double>());
    CHECK(c["cells"].get<double>() > 0.95 * c["grid_cells"].get<double>());
    for (const char* key : {"step_s", "floor_s", "poisson_s", "solve_ratio", "grid_over_tet"}) {
      INFO(key);
      CHECK(positive_finite(c[key]));
    }
    for (const char* key : {"transfer", "forces", "assembly", "solve", "output"}) {
      INFO(key);
      CHECK(positive_finite(c["phases"][key]));
    }
    CHECK(c["solve_ratio"].get<double>() ==
          doctest::Approx(c["phases"]["solve"].get<double>() / c["poisson_s"].get<double>())
              .epsilon(1e-9));
    // the tet counterpart has about the grid's fluid cells (within the remesher's reach)
    CHECK(positive_finite(c["tet"]["step_s"]));
    CHECK(c["tet"]["cells"].get<double>() > 0.5 * c["cells"].get<double>());
    CHECK(c["tet"]["cells"].get<double>() < 2.0 * c["cells"].get<double>());
    CHECK(c["grid_over_tet"].get<double>() ==
          doctest::Approx(c["step_s"].get<double>() / c["tet"]["step_s"].get<double>())
              .epsilon(1e-9));
  }
}

TEST_CASE("bench step: a liquid scene adds its phases and the two level sets on its particles") {
  // data/scenes/dam_break.json on its grid halved per axis (36 x 12 x 15 cells), 3 steps
  TempDir dir("bench_step_liquid");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "dam_break.json";
  const auto r = run_tetfsi(
      dir.path, "bench step \"" + scene.string() + "\" --sizes 2 --steps 3 --json step.json");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("vdb/us") != std::string::npos);
  const nlohmann::json out = nlohmann::json::parse(read_text(dir.path / "step.json"));
  REQUIRE(out["cases"].size() == 1);
  const nlohmann::json& c = out["cases"][0];
  INFO(c.dump());
  REQUIRE(c.contains("liquid"));
  const nlohmann::json& l = c["liquid"];
  // the column is 6 x 12 x 12 cells of 8 particles (a/h = 6)
  CHECK(l["particles"].get<double>() == 6 * 12 * 12 * 8);
  for (const char* key : {"advect_s", "surface_s", "p2g_s", "solve_s", "particle_volume"}) {
    INFO(key);
    CHECK(positive_finite(l[key]));
  }
  CHECK(l["surface_over_solve"].get<double>() ==
        doctest::Approx(l["surface_s"].get<double>() / l["solve_s"].get<double>()).epsilon(1e-9));
  // two steps after the release the column has barely moved: the kernel level set reads the
  // particles' volume to 2 %, the union of spheres (which sits a fraction of a cell off a
  // flat face) to 10 %, and both see the same block's surface area to 15 %
  CHECK(l["level_set"]["volume_ratio"].get<double>() == doctest::Approx(1.0).epsilon(0.02));
  const nlohmann::json& vdb = l["openvdb"];
  CHECK(vdb["skipped"] == 0);
  CHECK(vdb["active_voxels"].get<double>() > 0);
  CHECK(positive_finite(vdb["reading"]["seconds"]));
  CHECK(vdb["reading"]["volume_ratio"].get<double>() == doctest::Approx(1.0).epsilon(0.1));
  CHECK(vdb["reading"]["area"].get<double>() ==
        doctest::Approx(l["level_set"]["area"].get<double>()).epsilon(0.15));
}
