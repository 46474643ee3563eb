// CLI tests of `tetfsi bench bfgs` (bench/bench_bfgs.cpp). The solid-integrator path: a soft
// bar held at its middle and stretched axially (tests/scenes/axial_bar.json, 20 steps
// of 2 ms and 2 of 20 ms); the coupled path: the shipped bar in water, coarse, 0.1 s. The JSON
// report is checked for its keys, for Newton's iteration count (at least 2 per step: a step
// converges once its second direction is small) and for the converged methods agreeing at the
// scene's step (to the RTOL of the iteration, not timed); then the one-line input errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::run_tetfsi;
using tetfsi::test::TempDir;

const fs::path k_bar = fs::path(TETFSI_SOURCE_DIR) / "tests" / "scenes" / "axial_bar.json";

}  // namespace

TEST_CASE("bench bfgs: an axial bar, three methods at dt and 10 dt: rows, agreement, goals") {
  TempDir dir("bench_bfgs");
  const auto r = run_tetfsi(
      dir.path, "bench bfgs '" + k_bar.string() + "' --json bfgs.json --history hist.csv");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("agreement") != std::string::npos);
  CHECK(r.out.find("goals:") != std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "bfgs.json"));
  INFO(j.dump(1));
  for (const char* key :
       {"scene", "mode", "dt", "ratio", "time", "probes", "rows", "agreement", "goals"}) {
    INFO(key);
    CHECK(j.contains(key));
  }
  CHECK(j["scene"] == "axial_bar");
  CHECK(j["mode"] == "solid");
  CHECK(j["dt"].get<double>() == 0.002);
  CHECK(j["ratio"].get<double>() == 10.0);
  CHECK(j["time"].get<double>() == doctest::Approx(0.04));
  // A at the bar's -x end, B at its +x end, on the axis's side of the middle
  CHECK(j["probes"]["A"]["rest"][0].get<double>() == doctest::Approx(-0.2));
  CHECK(j["probes"]["B"]["rest"][0].get<double>() == doctest::Approx(0.2));

  const nlohmann::json& rows = j["rows"];
  REQUIRE(rows.size() == 6);  // 3 methods × 2 steps
  int steps_total = 0;
  for (const nlohmann::json& row : rows) {
    INFO(row.dump());
    for (const char* key : {"method", "dt", "max_iterations", "avg_iterations", "converged",
                            "step_s", "evaluations_per_step", "steps", "completed", "failure"})
      REQUIRE(row.contains(key));
    const double h = row["dt"].get<double>();
    CHECK((h == doctest::Approx(0.002) || h == doctest::Approx(0.02)));
    CHECK(row["steps"] == (h < 0.01 ? 20 : 2));
    if (row["converged"].get<bool>()) {
      CHECK(row["failure"].is_null());
      CHECK(row["completed"] == row["steps"]);
      CHECK(row["max_iterations"].get<int>() >= 2);
      CHECK(row["avg_iterations"].get<double>() >= 2);
      CHECK(row["avg_iterations"].get<double>() <= row["max_iterations"].get<double>());
      CHECK(row["evaluations_per_step"].get<double>() >= row["avg_iterations"].get<double>());
      CHECK(row["step_s"].get<double>() > 0);
    } else {
      // e.g. "failed to converge in 30 iterations at step 2"
      CHECK(row["failure"].get<std::string>().find("at step ") != std::string::npos);
    }
    steps_total += row["completed"].get<int>() + 1;  // + step 0 in the history
  }
  // Newton converges at both steps, in at least 2 iterations every step.
  for (int k : {2, 5}) {
    INFO(rows[k].dump());
    CHECK(rows[k]["method"] == "newton");
    CHECK(rows[k]["converged"] == true);
    CHECK(rows[k]["max_iterations"].get<int>() >= 2);
  }
  CHECK(rows[0]["method"] == "bfgs");
  CHECK(rows[0]["converged"] == true);

  // The converged methods at the scene's step agree within 1 % of the largest displacement
  // (each is converged to RTOL = 1e-3 of the out-of-balance force).
  const nlohmann::json& same = j["agreement"]["same_dt"];
  REQUIRE(same.size() == 2);
  CHECK(same[0]["dt"].get<double>() == 0.002);
  CHECK(same[0]["methods"].size() >= 2);
  REQUIRE(same[0]["percent"].is_number());
  CHECK(same[0]["percent"].get<double>() < 1.0);
  CHECK(same[0]["met"] == true);
  CHECK(same[0]["scale"].get<double>() > 0.01);  // the ends move by centimetres
  REQUIRE(j["agreement"]["across_dt"].is_array());
  CHECK(j["agreement"]["across_dt"].size() == 5);  // 3 same-method + 2 against newton
  for (const char* goal :
       {"bfgs_at_most_5_iterations", "bfgs_at_most_4_average_3", "modified_newton_converges_at_dt",
        "agreement_same_dt", "agreement_across_dt"})
    CHECK(j["goals"][goal].is_boolean());

  // The history: step 0 and every completed step of every run, 8 fields each.
  const std::vector<std::string> hist = lines_of(read_text(dir.path / "hist.csv"));
  REQUIRE(hist.size() == static_cast<size_t>(steps_total) + 1);
  CHECK(hist[0] == "method,dt,step,t,dA_x,dB_x,uA_x,uB_x");
  CHECK(hist[1] == "bfgs,0.002,0,0,0,0,4,4");  // at rest, the initial velocity
  for (size_t k = 1; k < hist.size(); ++k) {
    INFO(hist[k]);
    CHECK(std::count(hist[k].begin(), hist[k].end(), ',') == 7);
  }
  CHECK(hist.back().rfind("newton,0.02,2,0.04", 0) == 0);
}

TEST_CASE("bench bfgs: a run that does not converge stops there and says so") {
  // At most 3 iterations: enough at dt (2-3), not at 10 dt (5 and more).
  TempDir dir("bench_bfgs_fail");
  const auto r = run_tetfsi(dir.path, "bench bfgs '" + k_bar.string() +
                                          "' --json bfgs.json --set solid.max_iterations=3");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);  // the goals are reported, not enforced
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "bfgs.json"));
  INFO(j.dump(1));
  CHECK(j["tolerances"]["max_iterations"] == 3);
  const nlohmann::json& rows = j["rows"];
  REQUIRE(rows.size() == 6);
  for (int k = 3; k < 6; ++k) {
    INFO(rows[k].dump());
    CHECK(rows[k]["converged"] == false);
    CHECK(rows[k]["completed"] == 0);
    CHECK(rows[k]["failure"] == "failed to converge in 3 iterations at step 1");
    CHECK(rows[k]["max_iterations"].is_null());
    CHECK(rows[k]["step_s"].is_null());
  }
  CHECK(r.out.find("failed to converge in 3 iterations at step 1") != std::string::npos);
  CHECK(j["goals"]["bfgs_at_most_5_iterations"] == false);
  CHECK(j["goals"]["bfgs_at_most_4_average_3"] == false);
  CHECK(j["goals"]["modified_newton_converges_at_dt"] == true);  // 2-3 iterations at dt
  CHECK(j["agreement"]["same_dt"][1]["percent"].is_null());      // no converged method at 10 dt
  CHECK(j["goals"]["agreement_across_dt"] == false);
}

TEST_CASE("bench bfgs: the coarse bar in water, coupling.scheme = method at dt and 3 dt") {
  // data/scenes/bar.json (two-way, open at the top) with a 1 x 1 x 6 cell bar in a coarse
  // fluid mesh, 0.1 s: 3 steps of 1/30 s and 1 of 0.1 s per method.
  TempDir dir("bench_bfgs_coupled");
  const fs::path bar = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "bar.json";
  const auto r = run_tetfsi(dir.path, "bench bfgs '" + bar.string() +
                                          "' --time 0.1 --ratio 3 --json bfgs.json"
                                          " --set 'bodies.0.mesh.box.cells=[1,1,6]'"
                                          " --set fluid.mesh.surface_size=0.1"
                                          " --set fluid.mesh.far_size=0.2");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "bfgs.json"));
  INFO(j.dump(1));
  CHECK(j["mode"] == "coupled");
  CHECK(j["ratio"].get<double>() == 3.0);
  const nlohmann::json& rows = j["rows"];
  REQUIRE(rows.size() == 6);
  for (const nlohmann::json& row : rows) {
    INFO(row.dump());
    REQUIRE(row.contains("fluid_solves_per_step"));
    CHECK(row["steps"] == (row["dt"].get<double>() < 0.05 ? 3 : 1));
    if (!row["converged"].get<bool>()) continue;
    CHECK(row["max_iterations"].get<int>() >= 2);
    // newton: one fluid solve per residual evaluation and one per increment; the others
    // solve at most once per evaluation (line-search trials are combined from solved points)
    const double solves = row["fluid_solves_per_step"].get<double>(),
                 evals = row["evaluations_per_step"].get<double>();
    if (row["method"] == "newton")
      CHECK(solves >= 2 * evals - 1e-9);
    else
      CHECK(solves <= evals + 1e-9);
    CHECK(solves >= 1.0);
  }
  for (int k : {2, 5}) {
    INFO(rows[k].dump());
    CHECK(rows[k]["method"] == "newton");
    CHECK(rows[k]["converged"] == true);
  }
  // At 1/30 s the converged methods agree within 5 % of the largest displacement: each
  // stops at RTOL = 1e-3 of the out-of-balance force, and the bar moves by millimetres only.
  const nlohmann::json& same = j["agreement"]["same_dt"][0];
  REQUIRE(same["percent"].is_number());
  CHECK(same["percent"].get<double>() < 5.0);
}

TEST_CASE("bench bfgs: a missing scene, bad options and a static scene are one-line errors") {
  TempDir dir("bench_bfgs_err");
  const auto missing = run_tetfsi(dir.path, "bench bfgs no_such_scene.json");
  CHECK(missing.code == 1);
  REQUIRE(missing.err_lines().size() == 1);
  CHECK(missing.err_lines()[0].find("error: ") == 0);
  CHECK(missing.err_lines()[0].find("no_such_scene.json") != std::string::npos);

  // no SCENE: the default, data/scenes/shell_step.json relative to the working folder
  const auto none = run_tetfsi(dir.path, "bench bfgs --time 0.01");
  CHECK(none.code == 1);
  REQUIRE(none.err_lines().size() == 1);
  CHECK(none.err_lines()[0].find("shell_step.json") != std::string::npos);

  for (const std::string& bad : {std::string("--ratio 1"), std::string("--ratio 0.5"),
                                 std::string("--time 0"), std::string("--time -1")}) {
    INFO(bad);
    const auto r = run_tetfsi(dir.path, "bench bfgs '" + k_bar.string() + "' " + bad);
    CHECK(r.code == 1);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(r.err_lines()[0].find("error: bench bfgs: --") == 0);
  }
  const auto key = run_tetfsi(dir.path, "bench bfgs '" + k_bar.string() + "' --set solid.stol=1");
  CHECK(key.code == 1);
  REQUIRE(key.err_lines().size() == 1);
  CHECK(key.err_lines()[0].find("solid.stol: must be in (0, 1)") != std::string::npos);
  const auto stat = run_tetfsi(dir.path, "bench bfgs '" + k_bar.string() + "' --set mode=static");
  CHECK(stat.code == 1);
  REQUIRE(stat.err_lines().size() == 1);
  CHECK(stat.err_lines()[0].find("bench bfgs needs a dynamic scene") != std::string::npos);
  const auto opt = run_tetfsi(dir.path, "bench bfgs '" + k_bar.string() + "' --steps-down 2");
  CHECK(opt.code != 0);  // CLI11: not an option of bench bfgs
  CHECK(opt.err.find("steps-down") != std::string::npos);
}
