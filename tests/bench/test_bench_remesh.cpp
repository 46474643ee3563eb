/// @file test_bench_remesh.cpp
/// `tetfsi bench remesh` on its smallest case: the JSON's figures, the local recovery giving
/// the full recovery's mesh, --repeat, and the moving case (full and incremental paths).
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace {

using tetfsi::test::positive_finite;
using tetfsi::test::read_text;
using tetfsi::test::run_tetfsi;
using tetfsi::test::TempDir;

}  // namespace

TEST_CASE("bench remesh: the 30k case twice - local recovery = full - phases that add up") {
  TempDir dir("bench_remesh");
  const std::string sheet =
      (std::filesystem::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "remesh_sheet.json").string();
  const auto r = run_tetfsi(dir.path,
                            "bench remesh --max-cells 40000 --repeat 2 --json r.json "
                            "--moving-steps 4 --moving-scene '" +
                                sheet + "'");
  INFO(r.out);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("fastest of 2 runs") != std::string::npos);
  const nlohmann::json j = nlohmann::json::parse(read_text(dir.path / "r.json"));
  REQUIRE(j["cases"].size() == 1);
  const nlohmann::json& c = j["cases"][0];
  INFO(c.dump());
  CHECK(c["same_as_full_recovery"].get<bool>());
  CHECK(c["cells"].get<double>() > 30000);
  CHECK(c["cells"].get<double>() < 60000);
  for (const char* key : {"remesh_s", "delaunay_s", "ratio", "recovery_full_s"}) {
    INFO(key);
    CHECK(positive_finite(c[key]));
  }
  // The recovery's parts lie within it, and the phases within the remesh.
  const nlohmann::json& p = c["phases"];
  const double parts = p["recovery_check"].get<double>() + p["recovery_insert"].get<double>() +
                       p["recovery_slivers"].get<double>();
  CHECK(parts <= p["recovery"].get<double>() * (1 + 1e-9));
  CHECK(parts > 0);
  double phases = 0;
  for (const char* key : {"placement", "delaunay", "recovery", "classify", "build"})
    phases += p[key].get<double>();
  CHECK(phases <= c["remesh_s"].get<double>() * (1 + 1e-9));
  CHECK(c["recovery_rounds"].get<int>() > 0);
  CHECK(c["cleanup_rounds"].get<int>() >= 0);

  // The moving case: both paths, the same meshes; the full one never incremental.
  const nlohmann::json& m = j["moving"];
  INFO(m.dump());
  CHECK(m["steps"] == 4);
  CHECK(m["same"].get<bool>());
  CHECK(m["cells"].get<double>() > 10000);
  CHECK(m["full"]["incremental_steps"] == 0);
  CHECK(m["full"]["touched_fraction"] == 0.0);
  CHECK(m["incremental"]["incremental_steps"].get<int>() >= 0);
  CHECK(m["incremental"]["incremental_steps"].get<int>() <= 3);
  for (const char* path : {"full", "incremental"}) {
    INFO(path);
    CHECK(positive_finite(m[path]["remesh_s"]));
    CHECK(positive_finite(m[path]["delaunay_s"]));
    CHECK(m[path]["delaunay_s"].get<double>() < m[path]["remesh_s"].get<double>());
  }
  CHECK(r.out.find("moving: the sheet of") != std::string::npos);
}

TEST_CASE("bench remesh: a moving scene that is missing or has no tet fluid is a one-line error") {
  TempDir dir("bench_remesh_moving");
  const auto missing = run_tetfsi(dir.path, "bench remesh --max-cells 1 --moving-scene nope.json");
  CHECK(missing.code == 1);
  REQUIRE(missing.err_lines().size() == 1);
  CHECK(missing.err_lines()[0].find("nope.json") != std::string::npos);
  const std::string bar =
      (std::filesystem::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "smoke_sheets_grid.json")
          .string();
  const auto grid = run_tetfsi(dir.path, "bench remesh --max-cells 1 --moving-scene '" + bar + "'");
  CHECK(grid.code == 1);
  REQUIRE(grid.err_lines().size() == 1);
  CHECK(grid.err_lines()[0].find("needs a scene with a tet fluid") != std::string::npos);
}
