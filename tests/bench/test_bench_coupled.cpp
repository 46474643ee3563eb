// CLI tests of `tetfsi bench coupled` (bench/bench_coupled.cpp): the shipped bar scene
// (data/scenes/bar.json) on a coarse mesh for 0.1 s with two halvings, the JSON report checked
// for its keys and sanity (not for speed or for which scheme is stable: benchmarks are never
// timed tests), and its input errors.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using tetfsi::test::positive_finite;
using tetfsi::test::read_text;
using tetfsi::test::run_tetfsi;
using tetfsi::test::TempDir;

const fs::path k_bar = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "bar.json";

/// The bar with a 1 × 1 × 6 cell body in a fluid mesh about twice as coarse as the scene's.
const std::string k_coarse =
    " --set 'bodies.0.mesh.box.cells=[1,1,6]' --set fluid.mesh.surface_size=0.1"
    " --set fluid.mesh.far_size=0.2";

}  // namespace

TEST_CASE("bench coupled: a coarse bar for 0.1 s, two halvings: every figure in the JSON") {
  TempDir dir("bench_coupled");
  const auto r = run_tetfsi(dir.path, "bench coupled '" + k_bar.string() +
                                          "' --time 0.1 --steps-down 2 --timed-steps 4"
                                          " --json coupled.json" +
                                          k_coarse);
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("largest stable h") != std::string::npos);
  CHECK(r.out.find("goals:") != std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "coupled.json"));
  INFO(j.dump(1));
  for (const char* key : {"stable_dt", "step_s", "runs"}) {
    INFO(key);
    REQUIRE(j.contains(key));
    for (const char* scheme : {"simultaneous", "splitting"}) {
      INFO(scheme);
      REQUIRE(j[key].contains(scheme));
    }
  }
  for (const char* scheme : {"simultaneous", "splitting"}) {
    INFO(scheme);
    // a stable step is one of 2 dt, dt, dt/2; null (none stable) is a valid result
    const nlohmann::json& h = j["stable_dt"][scheme];
    CHECK((h.is_null() || positive_finite(h)));
    if (!h.is_null()) CHECK(h.get<double>() <= 2 * j["dt"].get<double>() * (1 + 1e-12));
    const nlohmann::json& runs = j["runs"][scheme];
    REQUIRE(runs.is_array());
    CHECK(runs.size() >= 1);
    CHECK(runs.size() <= 3);
    for (const nlohmann::json& run : runs) CHECK(positive_finite(run["h"]));
  }
  // simultaneous runs at every h splitting is tried at (its energy reference)
  CHECK(j["runs"]["simultaneous"].size() >= j["runs"]["splitting"].size());
  CHECK(positive_finite(j["step_s"]["simultaneous"]));
  CHECK((j["step_s"]["splitting"].is_null() || positive_finite(j["step_s"]["splitting"])));
  for (const char* key :
       {"coupled_solve_s", "fluid_only_solve_s", "solve_ratio", "initial_energy"}) {
    INFO(key);
    REQUIRE(j.contains(key));
    CHECK(positive_finite(j[key]));
  }
  CHECK(j["solve_ratio"].get<double>() ==
        doctest::Approx(j["coupled_solve_s"].get<double>() / j["fluid_only_solve_s"].get<double>())
            .epsilon(1e-9));
  for (const char* key : {"cells", "pressure_unknowns", "solid_unknowns", "coupled_iterations",
                          "fluid_only_iterations"}) {
    INFO(key);
    CHECK(positive_finite(j["solve"][key]));
  }
}

TEST_CASE("bench coupled: the bar on the grid: its coupled solve against the grid projection") {
  TempDir dir("bench_coupled_grid");
  const auto r = run_tetfsi(dir.path, "bench coupled '" + k_bar.string() +
                                          "' --time 0.1 --steps-down 0 --timed-steps 4"
                                          " --json coupled.json --set fluid.discretization=grid"
                                          " --set fluid.grid.cell_size=0.08");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "coupled.json"));
  INFO(j.dump(1));
  CHECK(positive_finite(j["step_s"]["simultaneous"]));
  for (const char* key : {"coupled_solve_s", "fluid_only_solve_s", "solve_ratio"}) {
    INFO(key);
    CHECK(positive_finite(j[key]));
  }
  // the grid's cells (the box at 0.08 m), fewer pressure unknowns (the bar's cells are solid)
  const nlohmann::json& s = j["solve"];
  CHECK(s["cells"].get<double>() > s["pressure_unknowns"].get<double>());
  CHECK(positive_finite(s["pressure_unknowns"]));
  CHECK(positive_finite(s["solid_unknowns"]));
  CHECK(s["converged"] == true);
}

TEST_CASE("bench coupled: a missing scene and bad option values are one-line errors") {
  TempDir dir("bench_coupled_err");
  const auto missing = run_tetfsi(dir.path, "bench coupled no_such_scene.json");
  CHECK(missing.code == 1);
  REQUIRE(missing.err_lines().size() == 1);
  CHECK(missing.err_lines()[0].find("error: ") == 0);
  CHECK(missing.err_lines()[0].find("no_such_scene.json") != std::string::npos);

  for (const std::string& bad :
       {std::string("--time 0"), std::string("--steps-down -1"), std::string("--timed-steps 2")}) {
    INFO(bad);
    const auto r = run_tetfsi(dir.path, "bench coupled '" + k_bar.string() + "' " + bad);
    CHECK(r.code == 1);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(r.err_lines()[0].find("error: bench coupled: --") == 0);
  }
}
