/// @file test_bench_remesh.cpp
/// `tetfsi bench remesh` on its smallest case: the JSON's figures, the local recovery giving
/// the full recovery's mesh, and --repeat.
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
  const auto r = run_tetfsi(dir.path, "bench remesh --max-cells 40000 --repeat 2 --json r.json");
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
}
