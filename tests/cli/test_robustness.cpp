// Issue 21's reproducers (tests/scenes/robustness/): each hostile input or unstable run
// ends with one line naming the file, key, element or step, a non-zero exit and the output
// written so far intact.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;

namespace {

using tetfsi::test::contains;
using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;
using Result = tetfsi::test::CliResult;
using tetfsi::test::run_tetfsi;

const fs::path k_scenes = fs::path(TETFSI_SOURCE_DIR) / "tests" / "scenes" / "robustness";

}  // namespace

TEST_CASE("divergence: the midpoint cantilever stops at the step it diverges, non-zero exit") {
  TempDir dir("diverge");
  const std::string scene = (k_scenes / "diverging_cantilever.json").string();
  const Result r = run_tetfsi(dir.path, fmt::format("run '{}' --out o --progress off", scene));
  CHECK(r.code != 0);
  const auto lines = r.err_lines();
  REQUIRE(!lines.empty());
  const std::string& last = lines.back();
  CHECK(last.rfind("error: step ", 0) == 0);
  CHECK(contains(last, "the bodies diverged"));
  CHECK(contains(last, "solid.trapezoid"));
  const auto summary = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"));
  CHECK(summary["completed"] == false);
  const int steps = summary["steps"].get<int>();
  CHECK(steps > 20);  // it ran stably for a while
  CHECK(steps < 120);
  // The summary and the last frame are the last good state: the 1 m beam's displacement
  // stays below its length plus its sag, not metres beyond.
  CHECK(summary["bodies"][0]["max_displacement"].get<double>() < 2.0);
  // stats.csv holds the completed steps only, and their energy is bounded by the budget.
  CHECK(lines_of(read_text(dir.path / "o" / "stats.csv")).size() == 1 + static_cast<size_t>(steps));

  // The paper's (damping) linearisation of the same scene never trips the check.
  const Result ok = run_tetfsi(
      dir.path, fmt::format("run '{}' --out p --progress off --set solid.trapezoid=paper", scene));
  CHECK(ok.code == 0);
  CHECK(!contains(ok.err, "error"));
}

TEST_CASE("damaged VTU files: one line naming the file, no allocation the file cannot back") {
  TempDir dir("vtu");
  // Each reproducer once made VTK allocate or read without bound (or abort on a bad_alloc):
  // a 4-billion-component array, a 4-billion-point piece, an appended block header claiming
  // more blocks than the file holds, LZ4 blocks full of garbage, and a zlib file with one of
  // its DataArray lines twice.
  const std::pair<const char*, const char*> cases[] = {
      {"bar_components.vtu", "NumberOfComponents=\"4294967295\", expected 1 to 4096"},
      {"bar_point_count.vtu", "NumberOfPoints=\"4294967295\"> is more than a 2189-byte file"},
      {"lz4_block_count.vtu", "runs past the end of the file"},
      {"lz4_garbage.vtu", "block 0 of DataArray 'rest_position' does not decompress"},
      // found by the fuzz harness: a DataArray line duplicated crashed VTK (SIGSEGV)
      {"duplicate_array.vtu", "piece 0 has two DataArrays named 'volume_ratio' in one section"},
  };
  for (const auto& [file, what] : cases) {
    const std::string path = (k_scenes / file).string();
    const Result r = run_tetfsi(dir.path, fmt::format("quality '{}'", path), "ulimit -v 4000000;");
    INFO(file, ": ", r.err);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].rfind("error: " + path + ": ", 0) == 0);
    CHECK(contains(lines[0], what));
  }
}

TEST_CASE("a self-intersecting body surface is a one-line error before meshing") {
  TempDir dir("selfx");
  const std::string scene = (k_scenes / "self_intersecting_body.json").string();
  for (const char* cmd : {"validate", "run --out o"}) {
    const Result r = run_tetfsi(dir.path, fmt::format("{} '{}' --log-level warn", cmd, scene));
    INFO(cmd, ": ", r.err);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(contains(lines[0], "bodies[0] 'cube'"));
    CHECK(contains(lines[0], "self_intersecting_cube.obj: the surface intersects itself (7 pairs"));
    CHECK(contains(lines[0], "repair it"));
  }
}

TEST_CASE("validate makes run's step-0 checks: the same one-line error, nothing written (item 7)") {
  TempDir dir("validate0");
  const std::string scene = (k_scenes / "two_boxes_in_water.json").string();
  for (const char* disc : {"tet", "grid"}) {
    const std::string base =
        fmt::format("'{}' --log-level warn --set fluid.discretization={}", scene, disc);
    const Result good = run_tetfsi(dir.path, "validate " + base);
    INFO(disc, ": ", good.err);
    CHECK(good.code == 0);
    CHECK(good.err.empty());
    CHECK(contains(good.out,
                   std::string(disc) == "tet" ? "fluid mesh at t = 0: " : "fluid grid at t = 0: "));
    const std::tuple<const char*, const char*> cases[] = {
        {"bodies.1.name=fluid", "body 'fluid' would be written to 'fluid.pvd'"},
        {"bodies.0.name=interface", "body 'interface' would be written to 'interface.pvd'"},
        {"bodies.1.mesh.box.hi=[1.0,0.6,0.55]",  // touching the wall
         "body 'right' (bodies[1]) is not strictly inside the fluid box"},
        {"bodies.1.mesh.box.hi=[1.3,0.6,0.55]",  // through it
         "body 'right' (bodies[1]) is not strictly inside the fluid box"},
        {"bodies.1.mesh.box.lo=[0.3,0.45,0.4]", "bodies 0 and 1 overlap: triangle"},
        {"bodies.1.mesh.box.lo=[0.25,0.45,0.4] --set bodies.1.mesh.box.hi=[0.35,0.55,0.5]",
         "body 1 lies inside body 0"}};
    int i = 0;
    for (const auto& [set, want] : cases) {
      const std::string out = fmt::format("o_{}_{}", disc, i++);
      const Result v = run_tetfsi(dir.path, fmt::format("validate {} --set {}", base, set));
      const Result r =
          run_tetfsi(dir.path, fmt::format("run {} --set {} --out {}", base, set, out));
      INFO(set, "\nvalidate: ", v.err, "\nrun: ", r.err);
      CHECK(v.code == 1);
      CHECK(r.code == 1);
      const auto vl = v.err_lines(), rl = r.err_lines();
      REQUIRE(vl.size() == 1);
      REQUIRE(!rl.empty());
      CHECK(contains(vl[0], want));
      CHECK(vl[0] == rl.back());  // "ok" from validate means run starts
      CHECK(!contains(v.out, "\nok"));
      // run refuses a body's name before it creates anything; a step-0 failure keeps frame 0.
      CHECK(fs::exists(dir.path / out) == (i > 2));
    }
  }
  // validate writes nothing: the folder holds the CLI captures and run's folders only.
  for (const auto& e : fs::directory_iterator(dir.path)) {
    const std::string name = e.path().filename().string();
    CHECK((name.rfind("cli_std", 0) == 0 || name.rfind("o_", 0) == 0));
  }
}

TEST_CASE("a tolerance below round-off is met at the floor - a real failure still warns (item 8)") {
  TempDir dir("floor");
  const std::string scene = (k_scenes / "water_shell_in_water.json").string();
  // coupling.rel_tol 1e-13 lies below this system's round-off floor (~1e-12).
  const Result r = run_tetfsi(dir.path, fmt::format("run '{}' --out o --progress off", scene));
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(!contains(r.err, "did not converge"));
  CHECK(!contains(r.err, "warning"));
  CHECK(contains(r.out, "solved to their round-off floor"));
  const auto c = nlohmann::json::parse(read_text(dir.path / "o" / "summary.json"))["coupling"];
  CHECK(c["unconverged_solves"] == 0);
  CHECK(c["steps_at_round_off_floor"].get<int>() >= 1);
  const double res = c["max_residual"].get<double>(), floor = c["max_round_off_floor"];
  CHECK(res > 1e-13);        // above the tolerance: the case is real
  CHECK(res < 1e-10);        // and a fine solve all the same
  CHECK(floor > 1e-14);      // the measured floor is
  CHECK(res <= 10 * floor);  // what bounds the residual

  // An iteration limit is not round-off: it warns, naming the key to raise.
  const Result lim = run_tetfsi(
      dir.path,
      fmt::format("run '{}' --out p --progress off --set coupling.max_iterations=3", scene));
  INFO(lim.err);
  CHECK(lim.code == 0);
  CHECK(contains(lim.err, "did not converge at t = 0.01 s"));
  CHECK(contains(lim.err, "raise coupling.max_iterations"));
  const auto cl = nlohmann::json::parse(read_text(dir.path / "p" / "summary.json"))["coupling"];
  CHECK(cl["unconverged_solves"] == 3);
  CHECK(cl["steps_at_round_off_floor"] == 0);
}

TEST_CASE("--set with an array index beyond any integer names the index, not a crash") {
  TempDir dir("setidx");
  const std::string scene = (k_scenes / "diverging_cantilever.json").string();
  for (const char* idx : {"99999999999999999999", "1", "18446744073709551616"}) {
    const Result r =
        run_tetfsi(dir.path, fmt::format("validate '{}' --set bodies.{}.name=x", scene, idx));
    INFO(idx, ": ", r.err);
    CHECK(r.code == 1);
    const auto lines = r.err_lines();
    REQUIRE(lines.size() == 1);
    CHECK(
        contains(lines[0], fmt::format("index {} is out of range ('bodies' has 1 element)", idx)));
  }
}

TEST_CASE("deeply nested JSON, in a scene or a --set value, is refused at once") {
  TempDir dir("deep");
  // 30000 levels would overflow the recursive parser's stack; 64 is the stated limit.
  const std::string deep = std::string(30000, '[') + std::string(30000, ']');
  const fs::path scene = dir.path / "deep.json";
  std::ofstream(scene) << "{\n  \"name\": \"deep\",\n  \"bodies\": " << deep << "\n}\n";
  const Result r = run_tetfsi(dir.path, "validate deep.json");
  CHECK(r.code == 1);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(contains(r.err_lines()[0], "deep.json: line 3: JSON nested more than 64 levels deep"));

  const std::string ok_scene = (k_scenes / "diverging_cantilever.json").string();
  const Result s =
      run_tetfsi(dir.path, fmt::format("validate '{}' --set 'bodies.0.extra={}'", ok_scene, deep));
  CHECK(s.code == 1);
  REQUIRE(s.err_lines().size() == 1);
  CHECK(contains(s.err_lines()[0], "--set 'bodies.0.extra': line 1: JSON nested more than 64"));
  // 64 levels are allowed by the nesting check (and then refused as an unknown key).
  const std::string fine = std::string(60, '[') + std::string(60, ']');
  const Result f =
      run_tetfsi(dir.path, fmt::format("validate '{}' --set 'bodies.0.extra={}'", ok_scene, fine));
  CHECK(f.code == 1);
  CHECK_FALSE(contains(f.err, "nested"));
  CHECK(contains(f.err, "extra"));
}

TEST_CASE("nonsense physical values are refused with the range named (item 6)") {
  TempDir dir("ranges");
  const std::string plume = (fs::path(TETFSI_SOURCE_DIR) / "data/scenes/smoke_plume.json").string();
  const std::string toy = (fs::path(TETFSI_SOURCE_DIR) / "data/scenes/toy.json").string();
  const std::tuple<std::string, std::string, std::string> cases[] = {
      {plume, "fluid.domain.hi=[1e308,1,1]", "fluid.domain.hi[0]: must be in [-1e6, 1e6] (m)"},
      {plume, "fluid.domain.hi=[9.2e18,1,1]", "fluid.domain.hi[0]: must be in [-1e6, 1e6] (m)"},
      {plume, "fluid.buoyancy.ambient_temperature=-1",
       "fluid.buoyancy.ambient_temperature: must be in [0, 1e6] (K), got -1"},
      {plume, "fluid.sources.0.temperature=-100", "fluid.sources[0].temperature: must be in [0"},
      {plume, "time.dt=1e308", "time.dt: must be in [1e-9, 1e6] (s)"},
      {plume, "gravity=[0,0,-1e9]", "gravity[2]: must be in [-1e4, 1e4] (m/s^2)"},
      {toy, "bodies.0.material.density=1e-300", "bodies[0].material.density: must be in [1e-10"},
      {toy, "bodies.0.material.youngs_modulus=1e-300",
       "bodies[0].material.youngs_modulus: must be in [0.01, 1e13] (Pa)"},
      {toy, "obstacles.0.friction=1e18", "obstacles[0].friction: must be in [0, 100], got 1e+18"},
  };
  for (const auto& [scene, set, what] : cases) {
    const Result r = run_tetfsi(dir.path, fmt::format("validate '{}' --set '{}'", scene, set));
    INFO(set, ": ", r.err);
    CHECK(r.code == 1);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(contains(r.err_lines()[0], what));
  }
}
