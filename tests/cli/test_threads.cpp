// Threads (core/parallel.hpp) through the command line: `--threads N` and TETFSI_THREADS, the
// thread count in the summary, `tetfsi bench threads`, and the guarantee that a run's results
// do not depend on the thread count: the same scene at 1, 2 and 3 threads (3 on this 2-core
// machine: more threads than cores, uneven splits) gives the same stats.csv (every column but
// the seconds) and the same frame files, byte for byte.
#include <doctest/doctest.h>

#include <filesystem>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "tests/run_compare.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using tetfsi::test::contains;
using tetfsi::test::read_text;
using tetfsi::test::shipped_scene;
using tetfsi::test::TempDir;

namespace {

using Result = tetfsi::test::CliResult;

/// `tetfsi run SCENE ARGS` into dir/t<N> at N = 1, 2 and 3 threads; each run equals the first.
void check_same_at_thread_counts(const fs::path& dir, const std::string& scene,
                                 const std::string& args) {
  for (const int n : {1, 2, 3}) {
    CAPTURE(n);
    const Result r = tetfsi::test::run_tetfsi(
        dir, fmt::format("run '{}' --out t{} --progress off --threads {} {}",
                         shipped_scene(scene).string(), n, n, args));
    REQUIRE_MESSAGE(r.code == 0, r.err);
    CHECK(json::parse(read_text(dir / fmt::format("t{}", n) / "summary.json"))["threads"] == n);
    CHECK(contains(r.out, fmt::format(" on {} thread{}, ", n, n == 1 ? "" : "s")));
    if (n > 1) tetfsi::test::check_same_runs(dir / "t1", dir / fmt::format("t{}", n));
  }
}

}  // namespace

TEST_CASE("threads: a coarse smoke_sheets (tet fluid - two-way) is the same at 1 2 and 3 threads") {
  // BFECC smoke, the velocity's pressure along the path, the coupled solve, remeshing: the
  // transfer's hinted chains and every parallel loop of the step. ~20k cells.
  TempDir dir("threads_tet");
  check_same_at_thread_counts(
      dir.path, "smoke_sheets.json",
      "--steps 3 --set output.every=1 --set fluid.mesh.surface_size=0.06 --set "
      "fluid.mesh.far_size=0.2 --set fluid.refine.size=0.07");
}

TEST_CASE(
    "threads: a coarse smoke_sheets_grid (MAC grid - two-way) is the same at 1 2 and 3 "
    "threads") {
  TempDir dir("threads_grid");
  check_same_at_thread_counts(dir.path, "smoke_sheets_grid.json",
                              "--steps 3 --set output.every=1 --set fluid.grid.cell_size=0.05");
}

TEST_CASE("threads: sheet_sag (the solid alone) is the same at 1 2 and 3 threads") {
  // 2,400 tets: the element forces and Jacobians in ten parallel chunks, scattered in order.
  TempDir dir("threads_solid");
  check_same_at_thread_counts(dir.path, "sheet_sag.json", "--steps 6 --set output.every=2");
}

TEST_CASE("threads: --threads and TETFSI_THREADS - a bad value is a one-line error") {
  TempDir dir("threads_cli");
  const std::string scene = shipped_scene("sheet_sag.json").string();
  for (const char* bad : {"0", "-1", "abc", "2.5"}) {
    CAPTURE(bad);
    Result r = tetfsi::test::run_tetfsi(
        dir.path, fmt::format("run '{}' --steps 1 --out o --threads '{}'", scene, bad));
    CHECK(r.code == 1);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(r.err_lines()[0] ==
          fmt::format("error: --threads: expected an integer >= 1 (threads), got '{}'", bad));
    r = tetfsi::test::run_tetfsi(dir.path, fmt::format("validate '{}'", scene),
                                 fmt::format("TETFSI_THREADS='{}'", bad));
    CHECK(r.code == 1);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(r.err_lines()[0] ==
          fmt::format("error: TETFSI_THREADS: expected an integer >= 1 (threads), got '{}'", bad));
  }
  // The variable sets the count; --threads (also after the subcommand) wins over it.
  Result r = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("run '{}' --steps 1 --out env --progress off", scene),
      "TETFSI_THREADS=3");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  CHECK(json::parse(read_text(dir.path / "env" / "summary.json"))["threads"] == 3);
  r = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("--threads 2 run '{}' --steps 1 --out opt --progress off", scene),
      "TETFSI_THREADS=3");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  CHECK(json::parse(read_text(dir.path / "opt" / "summary.json"))["threads"] == 2);
  CHECK(contains(r.out, " on 2 threads, "));
}

TEST_CASE("tetfsi bench threads: the phases at each thread count - the speed-up - the check") {
  TempDir dir("threads_bench");
  const Result r = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("bench threads '{}' --steps 2 --threads-list 1,2 --json b.json",
                            shipped_scene("sheet_sag.json").string()));
  REQUIRE_MESSAGE(r.code == 0, r.err);
  for (const char* s :
       {"phase (s/step)", "1 thr", "2 thr", "x2", "assemble", "step", "2 threads: identical"})
    CHECK_MESSAGE(contains(r.out, s), s);
  const json j = json::parse(read_text(dir.path / "b.json"));
  CHECK(j["threads"] == json::array({1, 2}));
  CHECK(j["identical"] == json::array({true, true}));
  REQUIRE(j["phases"].size() == 5);  // assemble, solve, update, output, step
  CHECK(j["phases"][4]["phase"] == "step");
  CHECK(j["phases"][4]["seconds"].size() == 2);
  CHECK(j["phases"][4]["speedup"][0] == 1.0);
  const Result bad = tetfsi::test::run_tetfsi(
      dir.path,
      fmt::format("bench threads '{}' --threads-list 0", shipped_scene("sheet_sag.json").string()));
  CHECK(bad.code != 0);
}
