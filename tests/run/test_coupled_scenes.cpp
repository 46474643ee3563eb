/// @file test_coupled_scenes.cpp
/// The shipped two-way scenes (data/scenes: smoke_sheets, paddle, toy, bar, balloon), each in
/// a small fast variant (coarse fluid mesh, a few steps, set by overrides as a user would on
/// the command line): they load, run two-way through the run loop, write every stream with
/// the same frames, keep finite energies, and the enclosed scenes keep their volume.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "run/run.hpp"
#include "scene/scene.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;

namespace {

struct Variant {
  const char* scene;
  std::vector<std::string> overrides;
  bool enclosed;  ///< a liquid sealed in a body: its volume is kept
};

/// Column `name` of stats.csv.
std::vector<double> column(const fs::path& csv, const std::string& name) {
  const auto cols = tetfsi::test::read_csv_columns(csv);
  const auto it = cols.find(name);
  REQUIRE(it != cols.end());
  return it->second;
}

/// Number of <DataSet> entries of a .pvd.
int pvd_frames(const fs::path& p) {
  const std::string s = read_text(p);
  int n = 0;
  for (size_t i = s.find("<DataSet"); i != std::string::npos; i = s.find("<DataSet", i + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE(
    "shipped two-way scenes: small variants run, write every stream and keep their "
    "physics") {
  const std::vector<std::string> coarse = {"fluid.mesh.surface_size=0.08",
                                           "fluid.mesh.far_size=0.25", "output.every=1"};
  const std::vector<Variant> variants = {
      {"smoke_sheets", {"fluid.refine.size=0"}, false},
      {"paddle", {"fluid.refine.size=0"}, false},
      {"toy", {"fluid.mesh.surface_size=0.05"}, true},
      {"bar", {}, false},
      {"balloon", {"fluid.mesh.surface_size=0.05"}, true},
  };
  for (const Variant& v : variants) {
    CAPTURE(v.scene);
    TempDir dir(std::string("coupled_scene_") + v.scene);
    std::vector<std::string> o = coarse;
    o.insert(o.end(), v.overrides.begin(), v.overrides.end());
    const fs::path file =
        fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / (std::string(v.scene) + ".json");
    RunOptions opt;
    opt.out_dir = dir.path;
    opt.progress = ProgressMode::Off;
    opt.steps = 3;
    const RunResult r = run_scene(load_scene(file, o), opt);
    INFO("run error: " << r.error);
    REQUIRE(r.completed);
    CHECK(r.steps_done == 3);
    // every stream has the initial frame and one per step
    CHECK(pvd_frames(dir.path / "fluid.pvd") == 4);
    CHECK(pvd_frames(dir.path / "interface.pvd") == 4);
    const fs::path csv = dir.path / "stats.csv";
    for (const char* c : {"coupled_residual", "total_energy_coupled", "interface_power"})
      for (double x : column(csv, c)) CHECK(std::isfinite(x));
    for (double x : column(csv, "coupled_residual")) CHECK(x < 1e-8);
    if (v.enclosed)
      for (double x : column(csv, "enclosed_volume_drift")) CHECK(x < 1e-9);
  }
}

TEST_CASE(
    "shipped toy: a coarse variant lands at the scene's dt without folding its wall and bounces") {
  // At the former dt of 1/60 s this variant (as the shipped toy) inverted elements of the
  // one-element wall in the landing step (t = 0.167 s) and the remesh of step 11 refused the
  // self-intersecting surface: the interface half cells' water moves with the inner wall
  // (coupling.interface_mass). The scene now steps 1/120 s; run it past the landing and the
  // first bounce (issue 22: the floor is unilateral, the shell's elasticity throws it back up).
  TempDir dir("coupled_scene_toy_landing");
  const fs::path file = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "toy.json";
  RunOptions opt;
  opt.out_dir = dir.path;
  opt.progress = ProgressMode::Off;
  opt.end_time = 0.35;
  const RunResult r = run_scene(load_scene(file, {"fluid.mesh.surface_size=0.05",
                                                  "fluid.mesh.far_size=0.25", "output.every=100"}),
                                opt);
  INFO("run error: " << r.error);
  REQUIRE(r.completed);
  CHECK(r.end_time > 0.34);
  REQUIRE(r.coupling.has_value());
  CHECK(r.coupling->unpredicted_meshes == 0);  // x* never folded either
  const fs::path csv = dir.path / "stats.csv";
  double contacts = 0.0, elastic = 0.0;
  for (double x : column(csv, "contacts")) contacts = std::max(contacts, x);
  for (double x : column(csv, "elastic_energy")) elastic = std::max(elastic, x);
  CHECK(contacts >= 5);  // it has landed (nodes on the floor)
  CHECK(elastic < 8.0);  // the fold showed as 18 J of elastic energy
  for (double x : column(csv, "enclosed_volume_drift")) CHECK(x < 1e-12);
  // It bounces: after its lowest node first reaches the floor (z = 0.2) it leaves it by ≥ 1 cm.
  const std::vector<double> low = column(csv, "toy_lowest");
  const std::vector<double> fke = column(csv, "fluid_kinetic_energy");
  size_t landed = 0;
  while (landed < low.size() && low[landed] > 0.2 + 1e-9) ++landed;
  REQUIRE(landed < low.size());
  const double rebound = *std::max_element(low.begin() + landed, low.end()) - 0.2;
  // the water keeps moving inside: the fluid's kinetic energy at the landing and at the end
  MESSAGE("toy: lands at step " << landed + 1 << ", its lowest node then rises " << rebound
                                << " m off the floor; fluid kinetic energy " << fke[landed]
                                << " J at the landing, " << fke.back() << " J at t = 0.35 s");
  CHECK(rebound >= 0.01);
  CHECK(fke.back() > 0.0);
}

TEST_CASE("shipped paddle: a coarse variant is pushed over by the jet and bounces on the floor") {
  // Issue 22: with a bilateral floor the paddle landed, stuck and slid along it upright. Now
  // it drops onto its edge and bounces, the jet's moment about the bottom edge beats its
  // weight's long before the jet could slide it (the scene's description), the floor lets the
  // far side go: it tips, slaps onto the floor (z = 0.1) and rebounds. All by the paddle's
  // own elasticity (restitution 0). Measured on this variant: a hop of 1.03-1.05 mm, 90
  // degrees. The tipping starts from an unstable balance, so when it slaps, how hard, and
  // the rebound depend on round-off: the centroid rose 0.15, 0.39 and 15 mm after the slap in
  // three runs whose dt differed by 1e-13 s (6.1 and 6.9 mm before the remesher's cells were
  // put in a canonical order), and whether the whole paddle leaves the floor again varies
  // too: both reported only. The hop is the check that the floor lets go.
  TempDir dir("coupled_scene_paddle_bounce");
  const fs::path file = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / "paddle.json";
  RunOptions opt;
  opt.out_dir = dir.path;
  opt.progress = ProgressMode::Off;  // the scene's 2 s
  const RunResult r =
      run_scene(load_scene(file, {"fluid.mesh.surface_size=0.05", "fluid.mesh.far_size=0.2",
                                  "fluid.refine.size=0", "output.every=1000"}),
                opt);
  INFO("run error: " << r.error);
  REQUIRE(r.completed);
  const fs::path csv = dir.path / "stats.csv";
  const std::vector<double> rot = column(csv, "paddle_rotation_deg");
  const std::vector<double> low = column(csv, "paddle_lowest");
  const std::vector<double> cz = column(csv, "paddle_centroid_height");
  size_t landed = 0;  // the first touch: its bottom edge on the floor
  while (landed < low.size() && low[landed] > 0.1 + 1e-9) ++landed;
  size_t flat = landed;  // the slap: the first step it lies within 10 degrees of flat
  while (flat < rot.size() && rot[flat] < 80.0) ++flat;
  REQUIRE(flat < rot.size());
  const double hop = *std::max_element(low.begin() + landed, low.begin() + flat) - 0.1;
  double lift = 0.0, rise = 0.0, lowest_cz = cz[flat];
  for (size_t i = flat; i < low.size(); ++i) {  // off the floor, and up from where it landed
    lift = std::max(lift, low[i] - 0.1);
    lowest_cz = std::min(lowest_cz, cz[i]);
    rise = std::max(rise, cz[i] - lowest_cz);
  }
  MESSAGE("paddle: lands on its edge at step "
          << landed + 1 << " and hops " << hop << " m; turned "
          << *std::max_element(rot.begin(), rot.end())
          << " degrees, within 10 degrees of flat at step " << flat + 1
          << "; then its lowest point left the floor by " << lift << " m and its centroid rose "
          << rise << " m");
  CHECK(hop >= 5e-4);  // the whole paddle off the floor after its first landing
  CHECK(*std::max_element(rot.begin(), rot.end()) >= 45.0);
}
