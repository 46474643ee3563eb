// Checkpoints and restart (run/checkpoints.hpp, run/run.hpp resume_run, `tetfsi resume`):
// a run stopped in any of the ways a user stops one and resumed equals the continuous run bit
// for bit (every frame file and collection byte for byte, every non-timing stats.csv column);
// a checkpoint that cannot be used is a one-line error naming the file and the fault.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/checkpoint.hpp"
#include "io/output.hpp"
#include "run/checkpoints.hpp"
#include "tests/run_compare.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using tetfsi::test::check_same_runs;
using tetfsi::test::contains;
using tetfsi::test::differences;
using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;

namespace {

using Result = tetfsi::test::CliResult;

Result cli(const fs::path& cwd, const std::string& args) {
  return tetfsi::test::run_tetfsi(cwd, args);
}

/// A soft cantilever (4×1×1 cells, one end pinned) swinging down under gravity: every step
/// changes every free node. Frames every 2 steps, so that a stop off the schedule is tested.
json swing_scene(int steps) {
  return json::parse(fmt::format(R"({{
    "name": "swing",
    "time": {{ "dt": 0.01, "steps": {} }},
    "output": {{ "every": 2 }},
    "bodies": [ {{
      "name": "beam",
      "mesh": {{ "box": {{ "lo": [0, 0, 0], "hi": [1, 0.25, 0.25], "cells": [4, 1, 1] }} }},
      "material": {{ "density": 1000, "youngs_modulus": 2e5, "poisson_ratio": 0.3 }},
      "pins": [ {{ "box": {{ "lo": [-0.01, -1, -1], "hi": [0.01, 1, 1] }} }} ]
    }} ]
  }})",
                                 steps));
}

void write_scene(const fs::path& dir, const json& j, const std::string& name = "swing.json") {
  std::ofstream(dir / name) << j.dump(2);
}

json summary_of(const fs::path& out) {
  return json::parse(read_text(out / "summary.json"));
}

/// summary.json without what differs between a resumed run and a straight one by design:
/// seconds, the folder, the checkpoint and where the run was resumed.
json summary_without_timing(const fs::path& out) {
  json j = summary_of(out);
  for (const char* k : {"build_seconds", "wall_seconds", "ms_per_step", "output_dir", "checkpoint",
                        "resumed_from_step"})
    j.erase(k);
  if (j.contains("fluid"))
    for (const char* k : {"remesh_seconds", "ms_per_remesh", "max_remesh_seconds", "fluid_seconds"})
      j["fluid"].erase(k);
  return j;
}

/// A folder with the continuous run of `steps` steps in `dir/straight`.
void run_straight(const fs::path& dir, int steps) {
  const Result r =
      cli(dir, fmt::format("run swing.json --out straight --steps {} --progress off", steps));
  REQUIRE_MESSAGE(r.code == 0, r.err);
}

/// Start `tetfsi <args>` in the background, wait until stats.csv of `out` has `rows` rows, then
/// run `action` (a shell command, e.g. "kill -TERM $p" or "touch OUT/STOP"); the exit code is
/// returned.
int run_until(const fs::path& dir, const std::string& args, const std::string& out, int rows,
              const std::string& action) {
  const std::string cmd = fmt::format(
      "cd '{}' && ('{}' {} >out.txt 2>err.txt & p=$!; "
      "while [ \"$(cat {}/stats.csv 2>/dev/null | wc -l)\" -le {} ]; do sleep 0.01; "
      "kill -0 $p 2>/dev/null || break; done; {}; wait $p; echo $? >code.txt)",
      dir.string(), TETFSI_EXE, args, out, rows, action);
  REQUIRE(std::system(cmd.c_str()) == 0);
  return std::stoi(read_text(dir / "code.txt"));
}

}  // namespace

TEST_CASE("checkpoint files: names, the listing by step and pruning") {
  using namespace tetfsi::app;
  TempDir dir("ckfiles");
  CHECK(checkpoint_path(dir.path, 12) == dir.path / "checkpoints" / "step_000012.tfck");
  CHECK(checkpoint_path(dir.path, 1234567).filename() == "step_1234567.tfck");
  CHECK(list_checkpoints(dir.path).empty());  // no folder
  fs::create_directories(dir.path / "checkpoints");
  for (const char* f : {"step_000004.tfck", "step_000010.tfck", "step_000002.tfck",
                        "step_000012.tfck", "step_000008.tfck.tmp", "notes.txt", "step_x.tfck"})
    std::ofstream(dir.path / "checkpoints" / f) << "x";
  const auto files = list_checkpoints(dir.path);
  REQUIRE(files.size() == 4);
  CHECK(files[0].step == 2);
  CHECK(files[3].step == 12);
  // After writing step 10: step 12 is of an abandoned future, 2 is beyond the newest 2, the
  // leftover temporary file goes; what is not ours stays.
  prune_checkpoints(dir.path, 10, 2);
  const auto kept = list_checkpoints(dir.path);
  REQUIRE(kept.size() == 2);
  CHECK(kept[0].step == 4);
  CHECK(kept[1].step == 10);
  CHECK_FALSE(fs::exists(dir.path / "checkpoints" / "step_000008.tfck.tmp"));
  CHECK(fs::exists(dir.path / "checkpoints" / "notes.txt"));
  CHECK(fs::exists(dir.path / "checkpoints" / "step_x.tfck"));
}

TEST_CASE("the physics of a scene - what a resumed run may not change") {
  using namespace tetfsi::app;
  const json a = json::parse(R"({"name": "s", "description": "x", "time": {"dt": 0.1, "steps": 4},
      "output": {"every": 1}, "bodies": [{"material": {"density": 1000}}]})");
  json b = a;
  b["output"]["every"] = 5;
  b["time"]["steps"] = 8;
  b["description"] = "y";
  CHECK(physics_hash(a) == physics_hash(b));
  CHECK_FALSE(first_difference(physics_part(a), physics_part(b)));
  b["bodies"][0]["material"]["density"] = 500;
  CHECK(physics_hash(a) != physics_hash(b));
  CHECK(first_difference(physics_part(a), physics_part(b)) ==
        std::string("bodies[0].material.density: 1000 vs 500"));
  b = a;
  b["time"]["dt"] = 0.2;
  CHECK(first_difference(a, b) == std::string("time.dt: 0.1 vs 0.2"));
  b = a;
  b["gravity"] = json::array({0, 0, -1});
  CHECK(first_difference(a, b) == std::string("gravity: (none) vs [0,0,-1]"));
}

TEST_CASE("--wall-time and the resume line's quoting") {
  using namespace tetfsi::app;
  CHECK(parse_wall_time("11:30:00") == 41400.0);
  CHECK(parse_wall_time("0:00:05") == 5.0);
  CHECK(parse_wall_time("100:00:00") == 360000.0);
  for (const char* bad : {"", "5", "1:2", "1:60:00", "00:00:00", "-1:00:00", "1:00:00x", "a:b:c"})
    CHECK_MESSAGE(
        contains(tetfsi::test::message_of<tetfsi::InputError>([&] { parse_wall_time(bad); }),
                 "expected HH:MM:SS"),
        bad);
  CHECK(shell_quote("out/toy") == "out/toy");
  CHECK(shell_quote("my runs/toy") == "'my runs/toy'");
  CHECK(shell_quote("it's") == "'it'\\''s'");
}

TEST_CASE("stats.csv of a resumed run keeps the rows up to the checkpoint and appends") {
  using tetfsi::app::StatsWriter;
  using tetfsi::app::StepStats;
  TempDir dir("stats_continue");
  const fs::path p = dir.path / "stats.csv";
  {
    StatsWriter w(p);
    for (int s = 1; s <= 5; ++s) {
      StepStats row;
      row.step = s;
      w.write(row);
    }
  }
  {
    StatsWriter w(p, false, false, 3);
    StepStats row;
    row.step = 4;
    row.kinetic_energy = 7.0;
    w.write(row);
  }
  const auto lines = lines_of(read_text(p));
  REQUIRE(lines.size() == 5);
  CHECK(lines[3].rfind("3,", 0) == 0);
  CHECK(lines[4].rfind("4,", 0) == 0);
  CHECK(contains(lines[4], ",7,"));
  // Rows missing before the checkpoint's step, or another run's columns: a one-line error.
  CHECK(contains(
      tetfsi::test::message_of<tetfsi::InputError>([&] { StatsWriter w(p, false, false, 9); }),
      "has the rows of steps 1..4 only, the checkpoint is at step 9"));
  CHECK(contains(
      tetfsi::test::message_of<tetfsi::InputError>([&] { StatsWriter w(p, true, false, 2); }),
      "its header is not this run's columns"));
  CHECK(contains(tetfsi::test::message_of<tetfsi::InputError>(
                     [&] { StatsWriter w(dir.path / "none.csv", false, false, 2); }),
                 "no such file"));
}

TEST_CASE("tetfsi resume: stopped by --steps and resumed equals the continuous run") {
  TempDir dir("resume_steps");
  write_scene(dir.path, swing_scene(8));
  run_straight(dir.path, 8);
  // 3 steps (an odd stop: the last frame, step 3, is off the every-2 schedule).
  Result r = cli(dir.path, "run swing.json --out o --steps 3 --checkpoint-every 2 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  CHECK(fs::exists(dir.path / "o" / "checkpoints" / "step_000002.tfck"));
  CHECK(fs::exists(dir.path / "o" / "checkpoints" / "step_000003.tfck"));  // the last step's
  CHECK(fs::exists(dir.path / "o" / "beam" / "beam_000003.vtu"));
  r = cli(dir.path, "resume o --steps 8 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
  CHECK_FALSE(fs::exists(dir.path / "o" / "beam" / "beam_000003.vtu"));  // not a frame of 8 steps
  const json s = summary_of(dir.path / "o");
  CHECK(s["completed"] == true);
  CHECK(s["steps"] == 8);
  CHECK(s["resumed_from_step"] == 3);
  CHECK(s["frames_written"] == summary_of(dir.path / "straight")["frames_written"]);
  CHECK(s["solver_iterations"] == summary_of(dir.path / "straight")["solver_iterations"]);
  CHECK(summary_without_timing(dir.path / "o") == summary_without_timing(dir.path / "straight"));
  CHECK(json::parse(read_text(dir.path / "o" / "scene.resolved.json"))["time"]["steps"] == 8);
  // checkpoint_every 2 went on in the resumed part; the newest 2 are kept
  const auto files = tetfsi::app::list_checkpoints(dir.path / "o");
  REQUIRE(files.size() == 2);
  CHECK(files[0].step == 6);
  CHECK(files[1].step == 8);
  // Nothing left to do: a one-line error saying how to go on.
  r = cli(dir.path, "resume o --progress off");
  CHECK(r.code == 1);
  CHECK(contains(r.err, "is at step 8, the run's last step is 8: give --steps N"));
}

TEST_CASE(
    "tetfsi resume: SIGTERM at a step checkpoints - exit code 130 - and the resumed run equals the "
    "continuous one") {
  TempDir dir("resume_sigterm");
  json scene = swing_scene(400);
  scene["time"]["dt"] = 0.001;
  write_scene(dir.path, scene);
  run_straight(dir.path, 400);
  const int code =
      run_until(dir.path, "run swing.json --out o --progress off", "o", 5, "kill -TERM $p");
  CHECK(code == 130);
  // The last line says how to go on.
  const auto err = lines_of(read_text(dir.path / "err.txt"));
  REQUIRE(!err.empty());
  CHECK(err.back().rfind("error: interrupted after step ", 0) == 0);
  CHECK(contains(err.back(), "; resume with: tetfsi resume o"));
  const json s = summary_of(dir.path / "o");
  CHECK(s["stop_reason"] == "signal");
  const int stopped = s["steps"].get<int>();
  INFO("stopped after step " << stopped);
  CHECK(stopped < 400);
  CHECK(fs::exists(tetfsi::app::checkpoint_path(dir.path / "o", stopped)));
  const Result r = cli(dir.path, "resume o --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
}

TEST_CASE(
    "tetfsi resume with output.export: the PLY files and export.json equal the straight run's") {
  TempDir dir("resume_export");
  json scene = swing_scene(8);
  scene["output"]["export"] = json::array({"ply"});
  write_scene(dir.path, scene);
  run_straight(dir.path, 8);
  Result r = cli(dir.path, "run swing.json --out o --steps 5 --checkpoint-every 2 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  // Frames of steps 0, 2, 4 and 5 (the stop): 4 PLY files, the last one not a frame of 8 steps.
  CHECK(fs::exists(dir.path / "o" / "ply" / "beam_000003.ply"));
  // A checkpoint of step 4: the resumed run removes frame 3 (step 5) and writes its own.
  fs::remove(tetfsi::app::checkpoint_path(dir.path / "o", 5));
  r = cli(dir.path, "resume o --steps 8 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
  const json m = json::parse(read_text(dir.path / "o" / "export.json"));
  REQUIRE(m["frames"].size() == 5);  // steps 0, 2, 4, 6, 8
  for (int f = 0; f < 5; ++f) {
    CHECK(m["frames"][f]["frame"] == f);
    CHECK(m["frames"][f]["step"] == 2 * f);
    const std::string ply = fmt::format("ply/beam_{:06d}.ply", f);
    CHECK(read_text(dir.path / "o" / ply) == read_text(dir.path / "straight" / ply));
  }
  CHECK_FALSE(fs::exists(dir.path / "o" / "ply" / "beam_000005.ply"));
}

TEST_CASE("tetfsi resume --end-time - and output.checkpoint_every from the scene") {
  TempDir dir("resume_endtime");
  write_scene(dir.path, swing_scene(8));
  run_straight(dir.path, 8);
  json scene = swing_scene(8);
  scene["output"]["checkpoint_every"] = 3;
  write_scene(dir.path, scene, "ck.json");
  Result r = cli(dir.path, "run ck.json --out o --end-time 0.05 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  const auto files = tetfsi::app::list_checkpoints(dir.path / "o");
  REQUIRE(files.size() == 2);  // steps 3 and 5 (the last)
  CHECK(files[0].step == 3);
  CHECK(files[1].step == 5);
  r = cli(dir.path, "resume o --end-time 0.08 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
  CHECK(json::parse(read_text(dir.path / "o" / "scene.resolved.json"))["time"]["end_time"] == 0.08);
}

TEST_CASE("tetfsi resume: a STOP file ends the run with exit code 0 and a resume line") {
  TempDir dir("resume_stopfile");
  json scene = swing_scene(400);
  scene["time"]["dt"] = 0.001;
  write_scene(dir.path, scene);
  run_straight(dir.path, 400);
  const int code =
      run_until(dir.path, "run swing.json --out o --progress off", "o", 5, "touch o/STOP");
  CHECK(code == 0);
  CHECK(contains(read_text(dir.path / "out.txt"), "resume with: tetfsi resume o"));
  CHECK_FALSE(fs::exists(dir.path / "o" / "STOP"));  // consumed
  const json s = summary_of(dir.path / "o");
  CHECK(s["stop_reason"] == "stop_file");
  CHECK(s["interrupted"] == true);
  const Result r = cli(dir.path, "resume o --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
}

TEST_CASE(
    "tetfsi resume: a run that went past its last checkpoint drops the later rows and frames") {
  TempDir dir("resume_past");
  write_scene(dir.path, swing_scene(10));
  run_straight(dir.path, 10);
  Result r = cli(dir.path, "run swing.json --out o --checkpoint-every 4 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  // As if killed after step 10 but before its checkpoint: the newest is step 8's.
  fs::remove(tetfsi::app::checkpoint_path(dir.path / "o", 10));
  r = cli(dir.path, "resume o --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
}

TEST_CASE("tetfsi resume: SIGKILL during a checkpoint write leaves the previous one valid") {
  TempDir dir("resume_sigkill");
  write_scene(dir.path, swing_scene(10));
  run_straight(dir.path, 10);
  Result r = cli(dir.path, "run swing.json --out o --steps 6 --checkpoint-every 2 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  // What a kill during the write of step 6's checkpoint can leave: its temporary file (the
  // rename never happened). Here also a truncated step 6 file, as a disk that lost its tail.
  const fs::path newest = tetfsi::app::checkpoint_path(dir.path / "o", 6);
  fs::copy_file(newest, newest.string() + ".tmp");
  fs::resize_file(newest.string() + ".tmp", fs::file_size(newest) / 2);
  fs::resize_file(newest, fs::file_size(newest) - 100);
  r = cli(dir.path, "resume o --steps 10 --progress off");
  CHECK(r.code == 1);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(contains(r.err, "step_000006.tfck"));
  CHECK(contains(r.err, "--fallback"));
  r = cli(dir.path, "resume o --steps 10 --fallback --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  CHECK(contains(r.err, "falling back to"));
  CHECK(summary_of(dir.path / "o")["resumed_from_step"] == 4);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
  CHECK_FALSE(fs::exists(newest.string() + ".tmp"));  // pruned with the next checkpoint
}

TEST_CASE(
    "tetfsi resume: malformed checkpoints are one-line errors naming the file and the fault") {
  TempDir dir("resume_malformed");
  write_scene(dir.path, swing_scene(6));
  Result r = cli(dir.path, "run swing.json --out o --steps 4 --checkpoint-every 4 --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  const fs::path ck = tetfsi::app::checkpoint_path(dir.path / "o", 4);
  const std::string good = read_text(ck);
  auto put = [&](const std::string& bytes) {
    std::ofstream f(ck, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  };
  auto one_line_error = [&](const std::string& args, const std::string& fault) {
    const Result e = cli(dir.path, args);
    CHECK(e.code == 1);
    CHECK(e.err_lines().size() == 1);
    CHECK_MESSAGE(contains(e.err, "step_000004.tfck"), e.err);
    CHECK_MESSAGE(contains(e.err, fault), e.err);
  };

  SUBCASE("truncated") {
    put(good.substr(0, good.size() * 2 / 3));
    one_line_error("resume o --progress off", "checkpoint");
  }
  SUBCASE("a corrupt byte") {
    std::string bad = good;
    bad[bad.size() / 2] = static_cast<char>(bad[bad.size() / 2] ^ 0x10);
    put(bad);
    one_line_error("resume o --progress off", "CRC");
  }
  SUBCASE("another format version") {
    std::string bad = good;
    bad[8] = static_cast<char>(tetfsi::k_checkpoint_version + 1);  // the u32 after "TETFSICK"
    put(bad);
    one_line_error("resume o --progress off", "version");
  }
  SUBCASE("a changed key that alters the physics") {
    one_line_error("resume o --set bodies.0.material.density=500 --progress off",
                   "bodies[0].material.density: 1000.0 vs 500.0");
  }
  SUBCASE("from another scene's folder") {
    // The folder's scene is not the checkpoint's (a checkpoint copied between runs).
    json other = json::parse(read_text(dir.path / "o" / "scene.resolved.json"));
    other["gravity"] = json::array({0, 0, -1});
    std::ofstream(dir.path / "o" / "scene.resolved.json") << other.dump(2);
    one_line_error("resume o --progress off",
                   "its scene is not this folder's ('o/scene.resolved.json'): gravity[2]: -1 vs "
                   "-9.81");
  }
  SUBCASE("--set output.* is allowed") {
    r = cli(dir.path,
            "resume o --steps 6 --set output.every=1 --set output.compression=zlib --progress off");
    REQUIRE_MESSAGE(r.code == 0, r.err);
    CHECK(fs::exists(dir.path / "o" / "beam" / "beam_000005.vtu"));
    CHECK(json::parse(read_text(dir.path / "o" / "scene.resolved.json"))["output"]["every"] == 1);
  }
}

TEST_CASE("tetfsi resume: without a checkpoint - a one-line error") {
  TempDir dir("resume_none");
  write_scene(dir.path, swing_scene(2));
  Result r = cli(dir.path, "run swing.json --out o --progress off");
  REQUIRE(r.code == 0);
  CHECK_FALSE(fs::exists(dir.path / "o" / "checkpoints"));  // none asked for, none written
  r = cli(dir.path, "resume o");
  CHECK(r.code == 1);
  CHECK(r.err_lines().size() == 1);
  CHECK(contains(r.err, "no checkpoint to resume from"));
}

TEST_CASE("a fresh run replaces an earlier run's checkpoints - a static run ignores the options") {
  TempDir dir("resume_fresh");
  write_scene(dir.path, swing_scene(4));
  Result r = cli(dir.path, "run swing.json --out o --checkpoint-every 1 --progress off");
  REQUIRE(r.code == 0);
  CHECK(tetfsi::app::list_checkpoints(dir.path / "o").size() == 2);
  r = cli(dir.path, "run swing.json --out o --steps 1 --progress off");
  REQUIRE(r.code == 0);
  CHECK(contains(r.err, "removed the 2 checkpoint(s) of an earlier run"));
  CHECK(tetfsi::app::list_checkpoints(dir.path / "o").empty());
  json still = swing_scene(4);
  still["mode"] = "static";
  write_scene(dir.path, still, "still.json");
  r = cli(dir.path,
          "run still.json --out s --checkpoint-every 1 --wall-time 1:00:00 --progress off");
  CHECK_MESSAGE(r.code == 0, r.err);
  CHECK(contains(r.err,
                 "is static: --checkpoint-every, --keep-checkpoints and --wall-time are ignored"));
  CHECK_FALSE(fs::exists(dir.path / "s" / "checkpoints"));
}

TEST_CASE("tetfsi run --wall-time stops with a checkpoint before the time runs out - exit code 0") {
  TempDir dir("resume_walltime");
  json scene = swing_scene(100000000);
  scene["time"]["dt"] = 1e-5;
  scene["output"]["every"] = 1000000;
  write_scene(dir.path, scene);
  Result r = cli(dir.path, "run swing.json --out o --wall-time 00:00:02 --progress off");
  CHECK_MESSAGE(r.code == 0, r.err);
  CHECK(contains(r.out, "resume with: tetfsi resume o"));
  const json s = summary_of(dir.path / "o");
  CHECK(s["stop_reason"] == "wall_time");
  CHECK(fs::exists(tetfsi::app::checkpoint_path(dir.path / "o", s["steps"].get<int>())));
  // and it goes on from there
  r = cli(dir.path, fmt::format("resume o --steps {} --progress off", s["steps"].get<int>() + 3));
  CHECK_MESSAGE(r.code == 0, r.err);
  CHECK(summary_of(dir.path / "o")["completed"] == true);
}

TEST_CASE("tetfsi checkpoint FILE lists the run and the records") {
  TempDir dir("checkpoint_cmd");
  write_scene(dir.path, swing_scene(2));
  Result r = cli(dir.path, "run swing.json --out o --checkpoint-every 2 --progress off");
  REQUIRE(r.code == 0);
  r = cli(dir.path, "checkpoint o/checkpoints/step_000002.tfck");
  CHECK_MESSAGE(r.code == 0, r.err);
  CHECK(contains(r.out, "every CRC valid"));
  CHECK(contains(r.out, "scene 'swing', step 2 of 2"));
  CHECK(contains(r.out, "run/scene "));
  CHECK(contains(r.out, "sim/"));
  std::ofstream(dir.path / "junk.tfck") << "not a checkpoint";
  r = cli(dir.path, "checkpoint junk.tfck");
  CHECK(r.code == 1);
  CHECK(r.err_lines().size() == 1);
  CHECK(contains(r.err, "junk.tfck"));
}

TEST_CASE("tetfsi resume: a two-way fluid run - collections and summaries carry on") {
  // The coupled CLI path: fluid.pvd and interface.pvd, the recorder's fluid and coupling
  // summaries, the divergence budget with the fluid's work (soft_box_in_water: ~0.2 s a step).
  TempDir dir("resume_fluid");
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / "tests/scenes/soft_box_in_water.json";
  Result r = cli(dir.path,
                 fmt::format("run '{}' --out straight --steps 4 --progress off", scene.string()));
  REQUIRE_MESSAGE(r.code == 0, r.err);
  r = cli(dir.path,
          fmt::format("run '{}' --out o --steps 4 --checkpoint-every 1 --keep-checkpoints 3 "
                      "--progress off",
                      scene.string()));
  REQUIRE_MESSAGE(r.code == 0, r.err);
  CHECK(tetfsi::app::list_checkpoints(dir.path / "o").size() == 3);
  // As if the run had died after step 4 with its last two checkpoints lost.
  fs::remove(tetfsi::app::checkpoint_path(dir.path / "o", 4));
  fs::remove(tetfsi::app::checkpoint_path(dir.path / "o", 3));
  r = cli(dir.path, "resume o --progress off");
  REQUIRE_MESSAGE(r.code == 0, r.err);
  check_same_runs(dir.path / "straight", dir.path / "o", false);
  CHECK(fs::exists(dir.path / "o" / "fluid.pvd"));
  CHECK(summary_without_timing(dir.path / "o") == summary_without_timing(dir.path / "straight"));
  CHECK(summary_of(dir.path / "o")["resumed_from_step"] == 2);
}

TEST_CASE("the runs' comparison of these tests sees a one-bit change of the physics") {
  // check_same_runs is what the restart tests rest on: it must see a difference that small.
  TempDir dir("resume_compare");
  json a = swing_scene(2), b = swing_scene(2);
  b["bodies"][0]["material"]["density"] = std::nextafter(1000.0, 2000.0);
  write_scene(dir.path, a, "a.json");
  write_scene(dir.path, b, "b.json");
  REQUIRE(cli(dir.path, "run a.json --out a --progress off").code == 0);
  REQUIRE(cli(dir.path, "run b.json --out b --progress off").code == 0);
  const std::vector<std::string> d = differences(dir.path / "a", dir.path / "b");
  CHECK_FALSE(d.empty());
  CHECK(differences(dir.path / "a", dir.path / "a").empty());
}
