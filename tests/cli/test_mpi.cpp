// MPI ranks (core/ranks.hpp) through the command line: `mpirun -np 2 tetfsi run SCENE` runs
// the scene on rank 0 with the PETSc and hypre solves distributed over the two ranks (driver
// ranks, the default; TETFSI_RANKS=replicated: every rank runs the scene), rank 0 writing
// the output. Its results agree with the one-rank run to solver tolerance (the distributed
// BoomerAMG is a different preconditioner, so the iterates differ in the last digits), and
// the two ways of sharing the ranks agree bit for bit. On this 2-core machine -np 2 fits;
// -np 3 needs --oversubscribe.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/parallel.hpp"
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

bool have_mpirun() {
  return std::system("command -v mpirun >/dev/null 2>&1") == 0;
}

/// The shell prefix that runs `tetfsi` under `mpirun -np N` (as root too). The Open MPI and
/// PMIx variables of this process are dropped first: a test before this one in the same
/// process may have started PETSc, and the variables of that singleton MPI start make the
/// launched ranks fail. With `timeout_s` > 0, mpirun is killed after that many seconds (exit
/// code 124).
std::string mpirun_prefix(int n, int timeout_s = 0) {
  return fmt::format(
      "unset $(env | sed -n "
      "'s/^\\(OMPI_[A-Za-z0-9_]*\\|PMIX_[A-Za-z0-9_]*\\|PMI_[A-Za-z0-9_]*\\)=.*/\\1/p'); "
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "OMPI_MCA_rmaps_base_oversubscribe=1 "
      "{}mpirun --quiet -np {}",
      timeout_s > 0 ? fmt::format("timeout {} ", timeout_s) : std::string(), n);
}

/// Every stats.csv column of `a` in `columns` (and every body column: the names ending in
/// _lowest, _centroid_height, _rotation_deg) agrees with `b`'s to `rel` of the column's
/// largest |value| (or of 1e-12 for an all-zero column).
void check_close(const fs::path& a, const fs::path& b, const std::vector<std::string>& columns,
                 double rel) {
  const auto ca = tetfsi::test::read_csv_columns(a / "stats.csv");
  const auto cb = tetfsi::test::read_csv_columns(b / "stats.csv");
  REQUIRE(ca.size() == cb.size());
  int compared = 0;
  for (const auto& [name, va] : ca) {
    const bool body = name.find("_centroid_height") != std::string::npos ||
                      name.find("_rotation_deg") != std::string::npos ||
                      name.find("_lowest") != std::string::npos;
    if (!body && std::find(columns.begin(), columns.end(), name) == columns.end()) continue;
    CAPTURE(name);
    const std::vector<double>& vb = cb.at(name);
    REQUIRE(va.size() == vb.size());
    double scale = 1e-12;
    for (const double v : va) scale = std::max(scale, std::abs(v));
    double worst = 0.0;
    for (size_t i = 0; i < va.size(); ++i) worst = std::max(worst, std::abs(va[i] - vb[i]));
    CHECK(worst <= rel * scale);
    ++compared;
  }
  CHECK(compared >= static_cast<int>(columns.size()));
}

/// `tetfsi run SCENE ARGS` at one rank (dir/r1) and under mpirun -np 2 (dir/r2).
void run_at_one_and_two_ranks(const fs::path& dir, const std::string& scene,
                              const std::string& args) {
  const std::string run =
      fmt::format("run '{}' --progress off {}", shipped_scene(scene).string(), args);
  const Result one = tetfsi::test::run_tetfsi(dir, run + " --out r1");
  REQUIRE_MESSAGE(one.code == 0, one.err);
  const Result two = tetfsi::test::run_tetfsi(dir, run + " --out r2", mpirun_prefix(2));
  REQUIRE_MESSAGE(two.code == 0, two.err);
  // One summary (rank 0's), naming the ranks and rank 0's threads: every core with driver
  // ranks (the worker sleeps between the solves).
  // (TETFSI_THREADS when the suite runs at a thread count: the same rule as rank 0's.)
  const int threads = tetfsi::requested_thread_count("");
  CHECK(contains(two.out,
                 fmt::format(" on 2 ranks x {} thread{}, ", threads, threads > 1 ? "s" : "")));
  CHECK(tetfsi::test::lines_of(two.out).size() == tetfsi::test::lines_of(one.out).size());
  CHECK(json::parse(read_text(dir / "r2" / "summary.json"))["ranks"] == 2);
  CHECK(json::parse(read_text(dir / "r1" / "summary.json"))["ranks"] == 1);
  // The same files: rank 0 wrote them all, nobody else wrote anything.
  std::vector<std::string> f1, f2;
  for (const auto& e : fs::recursive_directory_iterator(dir / "r1"))
    f1.push_back(fs::relative(e.path(), dir / "r1").string());
  for (const auto& e : fs::recursive_directory_iterator(dir / "r2"))
    f2.push_back(fs::relative(e.path(), dir / "r2").string());
  std::sort(f1.begin(), f1.end());
  std::sort(f2.begin(), f2.end());
  CHECK(f1 == f2);
}

}  // namespace

TEST_CASE("mpi: bar (tet fluid - two-way) under mpirun -np 2 agrees with one rank") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  // The coupled Schur-CG's BoomerAMG and the pressure solves over two ranks. One rank
  // against two agree to ~1e-12 of each column's scale (measured); asserted to 1e-8.
  TempDir dir("mpi_bar");
  run_at_one_and_two_ranks(dir.path, "bar.json", "--steps 12");
  // At a given rank count a run repeats bit for bit.
  const Result again =
      tetfsi::test::run_tetfsi(dir.path,
                               fmt::format("run '{}' --progress off --steps 12 --out r2b",
                                           shipped_scene("bar.json").string()),
                               mpirun_prefix(2));
  REQUIRE_MESSAGE(again.code == 0, again.err);
  tetfsi::test::check_same_runs(dir.path / "r2", dir.path / "r2b");
  // Progress comes from rank 0 alone: one line per step.
  const Result progress =
      tetfsi::test::run_tetfsi(dir.path,
                               fmt::format("run '{}' --progress plain --steps 2 --out r2c",
                                           shipped_scene("bar.json").string()),
                               mpirun_prefix(2));
  REQUIRE_MESSAGE(progress.code == 0, progress.err);
  int step_lines = 0;
  for (const std::string& line : progress.err_lines()) step_lines += line.rfind("step ", 0) == 0;
  CHECK(step_lines == 2);
  check_close(dir.path / "r1", dir.path / "r2",
              {"kinetic_energy", "elastic_energy", "fluid_kinetic_energy", "max_speed",
               "solid_flux", "interface_power"},
              1e-8);
}

TEST_CASE("mpi: a coarse smoke_sheets (two-way - smoke) under mpirun -np 2 agrees with one rank") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  TempDir dir("mpi_sheets");
  run_at_one_and_two_ranks(dir.path, "smoke_sheets.json",
                           "--steps 4 --set output.every=2 --set fluid.mesh.surface_size=0.06 "
                           "--set fluid.mesh.far_size=0.2 --set fluid.refine.size=0.07");
  check_close(dir.path / "r1", dir.path / "r2",
              {"kinetic_energy", "elastic_energy", "fluid_kinetic_energy", "smoke_mass",
               "max_speed", "interface_power"},
              1e-8);
}

namespace {

/// smoke_plume, coarse (11k cells by step 3), its pressure factorised by `solver` on one rank
/// and distributed over two: both direct (one iteration, residual ~1e-13), the same to
/// round-off (asserted to 1e-10), and with amg (rel_tol 1e-8) to 1e-6.
void check_direct_over_ranks(const std::string& solver) {
  CAPTURE(solver);
  TempDir dir("mpi_" + solver);
  const std::string coarse =
      "--steps 6 --set fluid.mesh.surface_size=0.1 --set fluid.mesh.far_size=0.2";
  run_at_one_and_two_ranks(dir.path, "smoke_plume.json",
                           coarse + " --set fluid.solver.linear=" + solver);
  const std::vector<std::string> physics = {"fluid_kinetic_energy", "smoke_mass", "max_speed",
                                            "divergence_before"};
  check_close(dir.path / "r1", dir.path / "r2", physics, 1e-10);
  for (const char* run : {"r1", "r2"}) {
    const auto c = tetfsi::test::read_csv_columns(dir.path / run / "stats.csv");
    for (const double it : c.at("pressure_iterations")) CHECK(it == 1);
    for (const double r : c.at("pressure_residual")) CHECK(r <= 1e-12);
  }
  const Result amg = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("run '{}' --progress off {} --out amg",
                            shipped_scene("smoke_plume.json").string(), coarse));
  REQUIRE_MESSAGE(amg.code == 0, amg.err);
  check_close(dir.path / "r1", dir.path / "amg", physics, 1e-6);
}

}  // namespace

TEST_CASE(
    "mpi: the mumps and superlu_dist pressure solves distributed over two ranks agree with one "
    "rank") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  check_direct_over_ranks("mumps");
  check_direct_over_ranks("superlu_dist");
  // MUMPS with no workspace slack (ICNTL(14) = 0) runs out of it on two ranks in most runs
  // (each of 10 on an idle machine here, but not in a CI run under load: MUMPS's scheduling
  // varies): the set-up raises the slack and factorises again (logged), and the run ends as
  // the others do
  TempDir dir("mpi_mumps_workspace");
  const Result r = tetfsi::test::run_tetfsi(
      dir.path,
      fmt::format("--log-level debug run '{}' --progress off --steps 8 --set "
                  "fluid.solver.linear=mumps --out r",
                  shipped_scene("smoke_plume.json").string()),
      "export PETSC_OPTIONS='-tetfsi_mumps_mat_mumps_icntl_14 0'; " + mpirun_prefix(2));
  REQUIRE_MESSAGE(r.code == 0, r.err);
  MESSAGE("the factorisation ran out of workspace and was redone: " << contains(
              r.err, "mumps: out of workspace; ICNTL(14) 0 -> 20"));
  const auto c = tetfsi::test::read_csv_columns(dir.path / "r" / "stats.csv");
  for (const double res : c.at("pressure_residual")) CHECK(res <= 1e-12);
  // The debug log says how much of each matrix couples the two ranks' row blocks.
  CHECK(contains(r.err, "2 ranks, contiguous row blocks of "));
  CHECK(contains(r.err, "% of the off-diagonal non-zeros couple two ranks"));
}

TEST_CASE("mpi: driver ranks give the results of replicated ranks bit for bit") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  // The same solver code on the same data: rank 0 sends each matrix and vector to the worker
  // instead of the worker computing them. bar: the coupled Schur-CG's BoomerAMG and the
  // pressure's amg; a small dam_break: the grid liquid's pfmg.
  TempDir dir("mpi_driver");
  const std::vector<std::pair<std::string, std::string>> runs = {
      {"bar.json", "--steps 6"}, {"dam_break.json", "--steps 4 --set fluid.grid.cells=[30,10,13]"}};
  for (const auto& [scene, args] : runs) {
    CAPTURE(scene);
    const std::string run =
        fmt::format("run '{}' --progress off {} --out ", shipped_scene(scene).string(), args);
    const Result driver =
        tetfsi::test::run_tetfsi(dir.path, run + scene + ".driver", mpirun_prefix(2));
    REQUIRE_MESSAGE(driver.code == 0, driver.err);
    const Result replicated =
        tetfsi::test::run_tetfsi(dir.path, run + scene + ".replicated",
                                 "export TETFSI_RANKS=replicated; " + mpirun_prefix(2));
    REQUIRE_MESSAGE(replicated.code == 0, replicated.err);
    CHECK(json::parse(read_text(dir.path / (scene + ".driver") / "summary.json"))["ranks"] == 2);
    tetfsi::test::check_same_runs(dir.path / (scene + ".driver"),
                                  dir.path / (scene + ".replicated"));
  }
}

TEST_CASE("mpi: driver ranks - a bad TETFSI_RANKS, and rank 0 failing, end in one line") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  TempDir dir("mpi_driver_errors");
  const std::string bar = shipped_scene("bar.json").string();
  const Result bad =
      tetfsi::test::run_tetfsi(dir.path, fmt::format("run '{}' --steps 1 --out bad", bar),
                               "export TETFSI_RANKS=both; " + mpirun_prefix(2));
  CHECK(bad.code != 0);
  REQUIRE(bad.err_lines().size() == 1);
  CHECK(contains(bad.err, "error: TETFSI_RANKS is 'both': it must be driver"));
  // Rank 0 stops with an error before any solve (a missing scene) and after the workers have
  // served solves (time splitting diverges on bar, the run's divergence check ends it): the
  // worker stops with it, nothing waits (timeout: exit code 124).
  const Result missing =
      tetfsi::test::run_tetfsi(dir.path, "run no_such_scene.json --out m", mpirun_prefix(2, 120));
  CHECK(missing.code != 0);
  CHECK(missing.code != 124);
  CHECK(contains(missing.err, "no_such_scene.json"));
  const Result diverged = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("run '{}' --progress off --set coupling.scheme=splitting --out d", bar),
      mpirun_prefix(2, 300));
  CHECK(diverged.code != 0);
  CHECK(diverged.code != 124);
  CHECK(contains(diverged.err, "error: "));
}

TEST_CASE("mpi: a subcommand other than run or resume under mpirun -np 2 is a one-line error") {
  if (!have_mpirun()) {
    MESSAGE("mpirun not found: skipped");
    return;
  }
  TempDir dir("mpi_cli");
  const Result r = tetfsi::test::run_tetfsi(
      dir.path, fmt::format("validate '{}'", shipped_scene("bar.json").string()), mpirun_prefix(2));
  CHECK(r.code != 0);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(contains(r.err, "error: only `tetfsi run` and `tetfsi resume` use MPI ranks (2 here)"));
}

TEST_CASE("mpi: tetfsi bench scaling times bar at 1 and 2 threads and ranks") {
  TempDir dir("mpi_scaling");
  const bool mpi = have_mpirun();
  const Result r = tetfsi::test::run_tetfsi(
      dir.path,
      fmt::format("bench scaling '{}' --steps 3 --threads 1,2 --ranks {} --repeat 2 --json s.json",
                  shipped_scene("bar.json").string(), mpi ? "1,2" : "1"));
  REQUIRE_MESSAGE(r.code == 0, r.err);
  const json j = json::parse(read_text(dir.path / "s.json"));
  const size_t runs = mpi ? 4 : 2;
  CHECK(j["repeat"] == 2);
  REQUIRE(j["runs"].size() == runs);
  CHECK(j["runs"][1]["threads"] == 2);
  CHECK(j["runs"][1]["ranks"] == 1);
  // Threads change nothing, bit for bit; two ranks agree to solver tolerance.
  CHECK(j["identical"][1] == true);
  CHECK(j["max_rel_difference"][1].get<double>() == 0.0);
  if (mpi) {
    CHECK(j["runs"][2]["ranks"] == 2);
    CHECK(j["max_rel_difference"][2].get<double>() < 1e-8);
  }
  bool step = false;
  for (const json& p : j["phases"]) {
    CAPTURE(p["phase"].get<std::string>());
    REQUIRE(p["seconds"].size() == runs);
    CHECK(p["speedup"][0].get<double>() == doctest::Approx(p["seconds"][0] > 0 ? 1.0 : 0.0));
    for (size_t i = 0; i < runs; ++i) {
      const double n = j["runs"][i]["ranks"].get<double>() * j["runs"][i]["threads"].get<double>();
      CHECK(p["efficiency"][i].get<double>() == doctest::Approx(p["speedup"][i].get<double>() / n));
    }
    if (p["phase"] == "step") {
      step = true;
      for (size_t i = 0; i < runs; ++i) CHECK(p["seconds"][i].get<double>() > 0);
    }
  }
  CHECK(step);
  CHECK(contains(r.out, "parallel efficiency"));
  CHECK(contains(r.out, "1r x 2t: identical, bit for bit"));
}

TEST_CASE("mpi: bench scaling - bad options are one-line errors") {
  TempDir dir("mpi_scaling_bad");
  const std::string bar = shipped_scene("bar.json").string();
  std::vector<std::pair<std::string, std::string>> cases = {
      {fmt::format("bench scaling '{}' --set time.dt=-1", bar), "time.dt"},
      {fmt::format("bench scaling '{}' --steps 2 --set bodies.0.material.youngs_modulus=1e-300",
                   bar),
       "youngs_modulus"}};
  cases.push_back({fmt::format("bench scaling '{}'", shipped_scene("csm1.json").string()),
                   "bench scaling needs a dynamic scene (mode is 'static')"});
  for (const auto& [args, expect] : cases) {
    CAPTURE(args);
    const Result r = tetfsi::test::run_tetfsi(dir.path, args);
    CHECK(r.code != 0);
    REQUIRE(r.err_lines().size() == 1);
    CHECK(contains(r.err, expect));
  }
}
