// CLI tests of `tetfsi bench integrators` (bench/bench_integrators.cpp) on the shipped linear
// swing (data/bench/swing_linear.json, a stiff undamped cantilever at 30 steps per period),
// shortened to 0.34 s (4 whole periods): the rows, the measured period, and the physics the table
// is for: the paper's linearised trapezoid damps (numerical damping ratio ~ωh/4), the Newton-
// iterated trapezoid and the linearised midpoint rule keep amplitude and energy. Not timed.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;

TEST_CASE("bench integrators: the linear swing and five integrators at dt and 2 dt") {
  tetfsi::test::TempDir dir("bench_integrators");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "data" / "bench" / "swing_linear.json";
  const auto r = tetfsi::test::run_tetfsi(
      dir.path, "bench integrators '" + scene.string() +
                    "' --set time.end_time=0.34 --json bi.json --log-level warn");
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(tetfsi::test::read_text(dir.path / "bi.json"));
  REQUIRE(j["scenes"].size() == 1);
  const auto& s = j["scenes"][0];
  // The beam's first bending mode: T = 0.0743 s measured at 60 steps per period (newton).
  CHECK(s["period"].get<double>() == doctest::Approx(0.0743).epsilon(0.02));
  REQUIRE(s["rows"].size() == 10);
  std::map<std::string, nlohmann::json> at_dt;
  for (const auto& row : s["rows"]) {
    CHECK(row["completed"] == true);
    CHECK(row["periods"] == 4);
    if (row["dt"].get<double>() == doctest::Approx(0.0025))
      at_dt[row["integrator"].get<std::string>()] = row;
  }
  REQUIRE(at_dt.size() == 5);
  // The paper's form loses most of the energy in 4 periods (exp(-2ζωt) with ζ ~ ωh/4 = 0.05).
  CHECK(at_dt["linearized/paper"]["energy_drift"].get<double>() < -0.5);
  CHECK(at_dt["linearized/paper"]["amplitude_ratio"].get<double>() < 0.5);
  // Newton keeps energy to 1e-3 of the swing's kinetic energy and the amplitude to 5 %.
  CHECK(std::abs(at_dt["newton"]["max_energy_error"].get<double>()) < 1e-3);
  CHECK(at_dt["newton"]["amplitude_ratio"].get<double>() > 0.95);
  CHECK(std::abs(at_dt["linearized/midpoint"]["max_energy_error"].get<double>()) < 1e-2);
  CHECK(at_dt["linearized/paper"]["cost_vs_paper"] == 1.0);
  CHECK(r.out.find("A_last/A_1") != std::string::npos);
}

TEST_CASE("bench integrators: a one-way fluid scene or a static scene is a one-line error") {
  tetfsi::test::TempDir dir("bench_integrators_bad");
  const fs::path scenes = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes";
  for (const char* bad : {"remesh_sheet.json", "csm1.json"}) {
    const auto r = tetfsi::test::run_tetfsi(
        dir.path, "bench integrators '" + (scenes / bad).string() + "' --log-level warn");
    INFO(bad, r.err);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].find("bench integrators needs a dynamic scene without a fluid") !=
          std::string::npos);
  }
}

TEST_CASE("bench integrators: a two-way swing in air and the four coupling schemes at dt and 2 dt" *
          doctest::test_suite("long")) {
  // data/bench/swing_air.json made the linear swing (E = 2e8 Pa, T = 0.074 s) on a coarse
  // fluid mesh, 0.25 s (3 whole periods): the simultaneous solve with the paper's linearised
  // trapezoid damps, with the midpoint rule and the Newton-iterated step it keeps the energy
  // to what the air's semi-Lagrangian transfer takes.
  tetfsi::test::TempDir dir("bench_integrators_two_way");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "data" / "bench" / "swing_air.json";
  const auto r = tetfsi::test::run_tetfsi(
      dir.path, "bench integrators '" + scene.string() +
                    "' --set bodies.0.material.youngs_modulus=2e8 --set time.dt=0.0025 --set "
                    "time.end_time=0.25 --set fluid.mesh.surface_size=0.2 --set "
                    "fluid.mesh.far_size=0.5 --json bi.json --log-level warn");
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(tetfsi::test::read_text(dir.path / "bi.json"));
  const auto& s = j["scenes"][0];
  REQUIRE(s["rows"].size() == 8);
  std::map<std::string, nlohmann::json> at_dt;
  for (const auto& row : s["rows"]) {
    CHECK(row["completed"] == true);
    if (row["dt"].get<double>() == doctest::Approx(0.0025))
      at_dt[row["integrator"].get<std::string>()] = row;
  }
  REQUIRE(at_dt.size() == 4);
  MESSAGE("energy drift / KE at dt: paper "
          << at_dt["simultaneous/paper"]["energy_drift"] << ", midpoint "
          << at_dt["simultaneous/midpoint"]["energy_drift"] << ", newton "
          << at_dt["newton"]["energy_drift"] << ", bfgs " << at_dt["bfgs"]["energy_drift"]);
  CHECK(at_dt["simultaneous/paper"]["energy_drift"].get<double>() < -0.2);
  CHECK(at_dt["simultaneous/midpoint"]["max_energy_error"].get<double>() < 0.03);
  CHECK(at_dt["newton"]["max_energy_error"].get<double>() < 0.03);
  CHECK(at_dt["simultaneous/paper"]["cost_vs_paper"] == 1.0);
  CHECK(r.out.find("coupling.scheme") != std::string::npos);
}
