/// @file main.cpp
/// The `tetfsi` command line:
///   tetfsi run SCENE [--out DIR] [--set key.path=value ...] [--steps N | --end-time T]
///                    [--progress auto|tty|plain|off] [--preview] [--checkpoint-every N]
///                    [--keep-checkpoints K] [--wall-time HH:MM:SS]
///   tetfsi resume OUT [--steps N | --end-time T] [--set key.path=value ...] [--fallback]
///                     [--progress MODE] [--checkpoint-every N] [--keep-checkpoints K]
///                     [--wall-time HH:MM:SS]
///   tetfsi checkpoint FILE
///   tetfsi validate SCENE [--set key.path=value ...]
///   tetfsi bench solvers [--n N] [--json FILE] [--backends a,b]
///   tetfsi bench remesh [--json FILE] [--max-cells N] [--repeat N]
///   tetfsi bench step SCENE [--json FILE] [--steps N] [--sizes a,b,c]
///   tetfsi bench threads SCENE [--steps N] [--threads-list 1,2] [--json FILE] [--set k=v ...]
///   tetfsi bench scaling SCENE [--threads 1,2] [--ranks 1,2] [--steps N] [--repeat K]
///                        [--json FILE] [--set k=v ...]
///   tetfsi bench coupled SCENE [--json FILE] [--time T] [--steps-down N] [--set k=v ...]
///   tetfsi bench bfgs [SCENE] [--json FILE] [--history FILE.csv] [--ratio R] [--time T]
///                     [--set k=v ...]
///   tetfsi quality FILE.vtu [--json FILE] [--png FILE]
///   tetfsi render OUT [--step N | --all] [--slice [AXIS=VALUE]] [--color ARRAY] [-o FILE.png]
///                     [--body-color ARRAY] [--range MIN,MAX] [--body-opacity A] [--zoom F]
///                     [--size WxH] [--movie FILE.mp4]
///   tetfsi export OUT [--vdb] [--ply] [--voxel-size S] [--subsamples N] [--threshold T]
///                     [--frames A:B] [--to DIR]
///   tetfsi plot OUT [-o FILE.png]
///   tetfsi scene --keys [--markdown]
///   tetfsi columns
///   (every subcommand also takes --log-level trace|debug|info|warn|error|off and --threads N:
///   the threads of the parallel loops, default TETFSI_THREADS or every core)
/// Every error ends the program with one line `error: <message>` on stderr and exit code 1;
/// command-line usage errors are reported by CLI11 with its exit code. Ctrl-C (or SIGTERM)
/// during `run` / `resume` stops after the current step with a complete output folder, a
/// checkpoint, one line `error: interrupted ...` and exit code 130; a second Ctrl-C ends the
/// program at once. A file OUT/STOP (checked before every step) or a --wall-time about to run
/// out stops the same way with exit code 0. Each stop with a checkpoint prints the line
/// `resume with: tetfsi resume OUT`.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <iostream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench/bench_bfgs.hpp"
#include "bench/bench_coupled.hpp"
#include "bench/bench_integrators.hpp"
#include "bench/bench_remesh.hpp"
#include "bench/bench_scaling.hpp"
#include "bench/bench_solvers.hpp"
#include "bench/bench_step.hpp"
#include "bench/bench_threads.hpp"
#include "cli/process_env.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "core/ranks.hpp"
#include "io/output.hpp"
#include "io/stats_columns.hpp"
#include "render/export_cmd.hpp"
#include "render/plot.hpp"
#include "render/quality_cmd.hpp"
#include "render/render.hpp"
#include "run/checkpoints.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"
#include "scene/scene_keys.hpp"

#ifndef TETFSI_VERSION
#define TETFSI_VERSION "unknown"
#endif

namespace {

/// Set by the first Ctrl-C / SIGTERM: the run loop stops after the current step and writes its
/// summary. A second signal ends the program at once (default action).
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "g_stop must be async-signal-safe");

extern "C" void on_stop_signal(int sig) {
  if (g_stop.exchange(true)) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
}

/// Print `error: <message>` as exactly one line on stderr.
int report_error(const std::string& what) {
  if (!tetfsi::is_root_rank()) return 1;  // every rank fails alike under mpirun: rank 0 says it
  const std::string message = tetfsi::app::one_line(what);
  std::fflush(stdout);
  std::fprintf(stderr, "error: %s\n", message.c_str());
  return 1;
}

/// A subcommand and what it does once the command line is parsed (its options live in the
/// action's captures).
struct Command {
  CLI::App* app;
  std::function<int()> action;
};

/// An integer option that must be at least 1.
const CLI::Validator& at_least_one() {
  static const CLI::Validator v(
      [](std::string& s) -> std::string {
        try {
          std::size_t used = 0;
          if (std::stoll(s, &used) >= 1 && used == s.size()) return {};
        } catch (const std::exception&) {
        }
        return "must be an integer >= 1, got '" + s + "'";
      },
      ">= 1");
  return v;
}

/// `--set KEY=VALUE` (repeatable) into `sets`.
void add_set_option(CLI::App* cmd, std::vector<std::string>& sets, const std::string& help) {
  cmd->add_option("--set", sets, help)->allow_extra_args(false)->type_name("KEY=VALUE");
}

/// The options `run` and `resume` share: checkpoints and the wall time.
struct CheckpointCli {
  int every = 0, keep = 2;
  std::string wall_time;
  CLI::Option *every_opt = nullptr, *keep_opt = nullptr, *wall_opt = nullptr;

  void add(CLI::App* cmd) {
    every_opt = cmd->add_option("--checkpoint-every", every,
                                "a checkpoint every N steps in OUT/checkpoints/ and at the last "
                                "step (overrides output.checkpoint_every; 0: only when stopped)")
                    ->type_name("N")
                    ->check(CLI::NonNegativeNumber);
    keep_opt = cmd->add_option("--keep-checkpoints", keep,
                               "keep the K newest checkpoints (overrides output.keep_checkpoints, "
                               "default 2)")
                   ->type_name("K")
                   ->check(at_least_one());
    wall_opt = cmd->add_option("--wall-time", wall_time,
                               "stop with a checkpoint (exit code 0) before this much wall time "
                               "has passed")
                   ->type_name("HH:MM:SS");
  }
  void apply(tetfsi::app::RunOptions& opt) const {
    if (*every_opt) opt.checkpoint_every = every;
    if (*keep_opt) opt.keep_checkpoints = keep;
    if (*wall_opt) opt.wall_time = tetfsi::app::parse_wall_time(wall_time);
  }
};

/// What a run or a resumed run prints and returns: the summary, the resume line of a stopped
/// run, and the exit code (130 for a signal, 0 for OUT/STOP and the wall time).
int finish_command(const tetfsi::app::RunResult& r, const std::string& preview_error,
                   const std::filesystem::path& preview) {
  tetfsi::app::print_summary(r, std::cout);
  if (!preview.empty()) std::cout << "preview: " << preview.string() << "\n";
  // A signal's stop ends with its error line (which says how to resume); the others here.
  if (r.interrupted && r.stop_reason != "signal" && !r.checkpoint.empty())
    std::cout << "resume with: " << tetfsi::app::resume_command(r) << "\n";
  std::cout.flush();
  if (!preview_error.empty() && r.completed) return report_error(preview_error);
  if (r.interrupted && r.stop_reason == "signal") {
    report_error(r.error);
    return 130;  // the shell convention for "ended by SIGINT"
  }
  if (r.interrupted) return r.checkpoint.empty() ? report_error(r.error) : 0;
  if (!r.completed) return report_error(r.error);
  return 0;
}

Command add_run(CLI::App& app) {
  using namespace tetfsi;
  struct Opt {
    std::string scene_file, out, progress = "auto";
    std::vector<std::string> sets;
    int steps = 0;
    double end_time = 0.0;
    bool preview = false;
    CLI::Option *steps_opt = nullptr, *end_opt = nullptr;
    CheckpointCli checkpoints;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* run = app.add_subcommand(
      "run",
      "simulate a scene (bodies alone, or with a fluid one- or two-way) and write its frames "
      "for ParaView, stats.csv and summary.json into OUT");
  run->add_option("SCENE", o->scene_file, "scene file (JSON)")->required()->type_name("FILE");
  run->add_option("--out,-o", o->out, "output folder (default: out/<scene name>)")
      ->type_name("DIR");
  add_set_option(run, o->sets,
                 "override a scene value, e.g. --set time.dt=0.002 --set "
                 "bodies.0.material.density=500 (repeatable)");
  o->steps_opt = run->add_option("--steps", o->steps, "number of steps (overrides the scene)")
                     ->type_name("N")
                     ->check(at_least_one());
  o->end_opt = run->add_option("--end-time", o->end_time,
                               "end time in s: ceil(T / dt) steps (overrides the scene)")
                   ->type_name("T");
  o->steps_opt->excludes(o->end_opt);
  run->add_option("--progress", o->progress,
                  "progress on stderr: auto (live line on a terminal, else plain), tty, plain, off")
      ->type_name("MODE")
      ->check(CLI::IsMember(app::k_progress_mode_names.names()))
      ->capture_default_str();
  run->add_flag("--preview", o->preview,
                "at the end, render the last frame to OUT/preview.png (as `tetfsi render`)");
  o->checkpoints.add(run);
  return {run, [o] {
            const app::Scene scene = app::load_scene(o->scene_file, o->sets);
            app::RunOptions opt;
            opt.out_dir = o->out.empty()
                              ? std::filesystem::path("out") / app::file_safe_name(scene.name)
                              : std::filesystem::path(o->out);
            if (*o->steps_opt) opt.steps = o->steps;
            if (*o->end_opt) opt.end_time = o->end_time;
            opt.progress = app::parse_progress_mode(o->progress);
            o->checkpoints.apply(opt);
            opt.stop = &g_stop;
            std::signal(SIGINT, on_stop_signal);
            std::signal(SIGTERM, on_stop_signal);
            const app::RunResult r = app::run_scene(scene, opt);
            std::signal(SIGINT, SIG_DFL);
            std::signal(SIGTERM, SIG_DFL);
            std::string preview_error;
            std::filesystem::path preview;
            // A preview of the last frame written (a failed run's too: its last good step; not
            // after Ctrl-C). Only a completed run reports a failed preview: else the run's
            // error is the one line.
            if (o->preview && r.frames_written > 0 && !r.interrupted && is_root_rank()) {
              try {
                app::RenderOptions ro;
                ro.output = opt.out_dir / "preview.png";
                preview = app::render_output(opt.out_dir, ro).frames.back().png;
              } catch (const std::exception& e) {
                preview_error = std::string("--preview: ") + e.what();
              }
            }
            return finish_command(r, preview_error, preview);
          }};
}

Command add_resume(CLI::App& app) {
  using namespace tetfsi;
  struct Opt {
    std::string out, progress = "auto";
    std::vector<std::string> sets;
    int steps = 0;
    double end_time = 0.0;
    bool fallback = false;
    CLI::Option *steps_opt = nullptr, *end_opt = nullptr;
    CheckpointCli checkpoints;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = app.add_subcommand(
      "resume",
      "go on with a run from its newest checkpoint (OUT/checkpoints/), into the same folder: the "
      "collections and stats.csv carry on, bit for bit as if it had never stopped");
  cmd->add_option("OUT", o->out, "the output folder of the run")->required()->type_name("DIR");
  o->steps_opt = cmd->add_option("--steps", o->steps,
                                 "the whole run's number of steps (default: the run's own)")
                     ->type_name("N")
                     ->check(at_least_one());
  o->end_opt = cmd->add_option("--end-time", o->end_time,
                               "the whole run's end time in s: ceil(T / dt) steps")
                   ->type_name("T");
  o->steps_opt->excludes(o->end_opt);
  add_set_option(cmd, o->sets,
                 "override a value of the run's scene: output.* only (e.g. --set "
                 "output.every=5); a change of the physics is an error (repeatable)");
  cmd->add_flag("--fallback", o->fallback,
                "if the newest checkpoint is unusable (truncated, corrupt, another version or "
                "scene), warn and use the previous valid one");
  cmd->add_option("--progress", o->progress, "as for run")
      ->type_name("MODE")
      ->check(CLI::IsMember(app::k_progress_mode_names.names()))
      ->capture_default_str();
  o->checkpoints.add(cmd);
  return {cmd, [o] {
            app::ResumeOptions ro;
            ro.run.out_dir = o->out;
            if (*o->steps_opt) ro.run.steps = o->steps;
            if (*o->end_opt) ro.run.end_time = o->end_time;
            ro.run.progress = app::parse_progress_mode(o->progress);
            o->checkpoints.apply(ro.run);
            ro.overrides = o->sets;
            ro.fallback = o->fallback;
            ro.run.stop = &g_stop;
            std::signal(SIGINT, on_stop_signal);
            std::signal(SIGTERM, on_stop_signal);
            const app::RunResult r = app::resume_run(ro);
            std::signal(SIGINT, SIG_DFL);
            std::signal(SIGTERM, SIG_DFL);
            return finish_command(r, "", {});
          }};
}

Command add_checkpoint(CLI::App& app) {
  struct Opt {
    std::string file;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = app.add_subcommand(
      "checkpoint",
      "verify a checkpoint file and list its run (scene, step, time) and records (key, type, "
      "shape, bytes)");
  cmd->add_option("FILE", o->file, "a checkpoint, e.g. OUT/checkpoints/step_000120.tfck")
      ->required()
      ->type_name("FILE.tfck");
  return {cmd, [o] { return tetfsi::app::checkpoint_command(o->file, std::cout); }};
}

Command add_validate(CLI::App& app) {
  using namespace tetfsi;
  struct Opt {
    std::string scene_file;
    std::vector<std::string> sets;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* validate = app.add_subcommand("validate",
                                          "check a scene as run would before its first step "
                                          "(bodies, t = 0 fluid mesh); print a summary");
  validate->add_option("SCENE", o->scene_file, "scene file (JSON)")->required()->type_name("FILE");
  add_set_option(validate, o->sets, "override a scene value (repeatable)");
  return {validate, [o] {
            const app::Scene scene = app::load_scene(o->scene_file, o->sets);
            app::validate_scene(scene, std::cout);
            std::cout << "ok\n";
            return 0;
          }};
}

Command add_scene(CLI::App& app) {
  struct Opt {
    bool keys = false, markdown = false;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* scene =
      app.add_subcommand("scene", "about scene files: every key, its default and range");
  scene->add_flag("--keys", o->keys, "print every scene key: type, default, range, unit, meaning")
      ->required();
  scene->add_flag("--markdown", o->markdown,
                  "as the markdown tables of docs/user/scene_keys.md (with their markers)");
  return {scene, [o] {
            std::cout << (o->markdown ? tetfsi::app::scene_keys_markdown()
                                      : tetfsi::app::scene_keys_text());
            return 0;
          }};
}

Command add_columns(CLI::App& app) {
  CLI::App* cmd =
      app.add_subcommand("columns",
                         "about stats.csv: every column, its unit and meaning (Markdown, as in "
                         "docs/user/output.md)");
  return {cmd, [] {
            std::cout << tetfsi::app::stats_columns_markdown();
            return 0;
          }};
}

Command add_bench_solvers(CLI::App& bench) {
  struct Opt {
    int n = 100000;
    std::string json;
    std::vector<std::string> backends;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd =
      bench.add_subcommand("solvers", "time the linear-solver backends on a 3D Poisson problem");
  cmd->add_option("--n", o->n, "approximate number of unknowns")
      ->type_name("N")
      ->check(at_least_one())
      ->capture_default_str();
  cmd->add_option("--json", o->json, "also write the results to this JSON file")->type_name("FILE");
  std::string names;
  for (const auto& n : tetfsi::solver_names()) names += (names.empty() ? "" : ",") + n;
  cmd->add_option("--backends", o->backends, "comma-separated backends (default: all): " + names)
      ->delimiter(',')
      ->type_name("A,B");
  return {cmd, [o] { return tetfsi::app::bench_solvers(o->n, o->json, o->backends, std::cout); }};
}

Command add_bench_remesh(CLI::App& bench) {
  struct Opt {
    std::string json;
    long max_cells = 1000000;
    int repeat = 1;
    std::string scene = "data/scenes/remesh_sheet.json";
    int steps = 20;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "remesh", "time the fluid remesher against the bare CGAL Delaunay of the same vertices");
  cmd->add_option("--json", o->json, "also write the results to this JSON file")->type_name("FILE");
  cmd->add_option("--max-cells", o->max_cells, "skip the cases above this size (30k, 250k, 1M)")
      ->type_name("N")
      ->check(at_least_one())
      ->capture_default_str();
  cmd->add_option("--repeat", o->repeat,
                  "time each remesh and each floor this many times and keep the fastest of each")
      ->type_name("N")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_option("--moving-scene", o->scene,
                  "the moving case: a one-way scene whose bodies are remeshed at every step")
      ->type_name("FILE")
      ->capture_default_str();
  cmd->add_option("--moving-steps", o->steps,
                  "steps of the moving case, remeshed on the full and the incremental path (0 "
                  "or 1: skip it)")
      ->type_name("N")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  return {cmd, [o] {
            return tetfsi::app::bench_remesh(o->json, o->max_cells, std::cout, o->repeat, o->scene,
                                             o->steps);
          }};
}

/// A scene benchmark's SCENE (described by `scene_help`), `--json FILE` and `--steps N` (≥ 2,
/// per `what`, the first a warm-up).
void add_scene_bench_options(CLI::App* cmd, std::string& scene, const std::string& scene_help,
                             std::string& json, int& steps, const std::string& what) {
  cmd->add_option("SCENE", scene, scene_help)->required()->type_name("FILE");
  cmd->add_option("--json", json, "also write the results to this JSON file")->type_name("FILE");
  cmd->add_option("--steps", steps,
                  "steps per " + what + "; the first is a warm-up and is not in the figures (>= 2)")
      ->type_name("N")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
}

/// A comma-separated list of counts, each at least 1 (thread, rank counts).
void add_count_list_option(CLI::App* cmd, const std::string& name, std::vector<int>& counts,
                           const std::string& help) {
  cmd->add_option(name, counts, help)->delimiter(',')->check(CLI::PositiveNumber)->type_name("A,B");
}

Command add_bench_step(CLI::App& bench) {
  struct Opt {
    std::string scene, json;
    tetfsi::app::BenchStepOptions bench;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "step",
      "time whole steps of a fluid scene at three mesh sizes against the floor: the bare CGAL "
      "Delaunay of the same vertices + one AMG pressure solve");
  add_scene_bench_options(cmd, o->scene, "fluid scene file (JSON)", o->json, o->bench.steps,
                          "size");
  cmd->add_option("--sizes", o->bench.scales,
                  "comma-separated factors on the scene's fluid mesh sizes (default: chosen for "
                  "about 30k, 100k and 250k cells)")
      ->delimiter(',')
      ->check(CLI::PositiveNumber)
      ->type_name("A,B,C");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            return tetfsi::app::bench_step(o->scene, o->bench, std::cout);
          }};
}

Command add_bench_threads(CLI::App& bench) {
  struct Opt {
    std::string scene, json;
    tetfsi::app::BenchThreadsOptions bench;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "threads",
      "the same steps of a scene at each thread count, in one run: seconds per step of every "
      "phase, the speed-up, and whether the physics came out the same bit for bit");
  add_scene_bench_options(cmd, o->scene, "dynamic scene file (JSON)", o->json, o->bench.steps,
                          "run");
  add_count_list_option(cmd, "--threads-list", o->bench.threads,
                        "comma-separated thread counts, the first the reference (default 1,2)");
  add_set_option(cmd, o->bench.overrides, "override a scene value (repeatable)");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            return tetfsi::app::bench_threads(o->scene, o->bench, std::cout);
          }};
}

Command add_bench_scaling(CLI::App& bench) {
  struct Opt {
    std::string scene, json;
    tetfsi::app::BenchScalingOptions bench;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "scaling",
      "the same steps of a scene at every (MPI ranks, threads) pair, each a `tetfsi run` "
      "process (under mpirun for ranks > 1): seconds per step of every phase, speed-up, "
      "parallel efficiency, and how far the physics is from the first run's");
  add_scene_bench_options(cmd, o->scene, "dynamic scene file (JSON)", o->json, o->bench.steps,
                          "run");
  add_count_list_option(cmd, "--threads", o->bench.threads,
                        "comma-separated thread counts per rank (default 1,2)");
  cmd->add_option("--repeat", o->bench.repeat,
                  "rounds of every pair, one after another; seconds are the medians (default 1)")
      ->check(at_least_one())
      ->type_name("K");
  add_count_list_option(cmd, "--ranks", o->bench.ranks,
                        "comma-separated MPI rank counts (default 1; above 1 runs under mpirun)");
  add_set_option(cmd, o->bench.overrides, "override a scene value (repeatable)");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            return tetfsi::app::bench_scaling(o->scene, o->bench, std::cout);
          }};
}

Command add_bench_coupled(CLI::App& bench) {
  struct Opt {
    std::string scene, json;
    tetfsi::app::BenchCoupledOptions bench;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "coupled",
      "the two coupling schemes side by side: each one's largest stable step, seconds per step, "
      "and the coupled solve against a fluid-only projection on the same mesh");
  cmd->add_option("SCENE", o->scene, "two-way fluid scene file (JSON)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--json", o->json, "also write the results to this JSON file")->type_name("FILE");
  cmd->add_option("--time", o->bench.time, "simulated seconds of each stability run (> 0)")
      ->type_name("T")
      ->capture_default_str();
  cmd->add_option("--steps-down", o->bench.steps_down,
                  "halvings of the largest step 2 dt tried: h = 2 dt / 2^k, k = 0..N (0..12)")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option("--timed-steps", o->bench.timed_steps,
                  "steps per scheme at dt for the seconds per step, the first a warm-up (>= 4)")
      ->type_name("N")
      ->capture_default_str();
  add_set_option(cmd, o->bench.overrides, "override a scene value (repeatable)");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            return tetfsi::app::bench_coupled(o->scene, o->bench, std::cout);
          }};
}

Command add_bench_bfgs(CLI::App& bench) {
  struct Opt {
    std::string scene = tetfsi::app::k_bench_bfgs_scene;
    tetfsi::app::BenchBfgsOptions bench;
    std::string json, history;
    double time = 0.0;
    CLI::Option* time_opt = nullptr;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "bfgs",
      "Table I of [BatheSonnad80]: BFGS, modified Newton and Newton at dt and R dt, "
      "iterations per step, convergence, and the agreement of two probes' displacements");
  cmd->add_option("SCENE", o->scene,
                  "dynamic scene file (JSON): two-way coupled (coupling.scheme = method) or not "
                  "(solid.integrator = method)")
      ->type_name("FILE")
      ->capture_default_str();
  cmd->add_option("--json", o->json, "also write the results to this JSON file")->type_name("FILE");
  cmd->add_option("--history", o->history,
                  "also write the probes' histories (method, dt, step, t, dA_x, dB_x, uA_x, "
                  "uB_x) to this CSV file")
      ->type_name("FILE.csv");
  cmd->add_option("--ratio", o->bench.ratio, "the larger step is R times the scene's dt (> 1)")
      ->type_name("R")
      ->capture_default_str();
  o->time_opt = cmd->add_option("--time", o->time,
                                "simulated seconds of each run (> 0; default: the scene's end "
                                "time)")
                    ->type_name("T");
  add_set_option(cmd, o->bench.overrides, "override a scene value (repeatable)");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            o->bench.history_path = o->history;
            if (*o->time_opt) o->bench.time = o->time;
            return tetfsi::app::bench_bfgs(o->scene, o->bench, std::cout);
          }};
}

Command add_bench_integrators(CLI::App& bench) {
  struct Opt {
    std::vector<std::string> scenes{std::begin(tetfsi::app::k_bench_integrator_scenes),
                                    std::end(tetfsi::app::k_bench_integrator_scenes)};
    tetfsi::app::BenchIntegratorsOptions bench;
    std::string json;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = bench.add_subcommand(
      "integrators",
      "the solid integrators (two-way scenes: the coupling schemes) on undamped swings at dt "
      "and 2 dt: amplitude after the last period, energy drift, cost per step");
  cmd->add_option("SCENES", o->scenes, "dynamic scene files (JSON), solid-only or two-way coupled")
      ->type_name("FILE ...")
      ->capture_default_str();
  cmd->add_option("--json", o->json, "also write the results to this JSON file")->type_name("FILE");
  add_set_option(cmd, o->bench.overrides, "override a scene value in every scene (repeatable)");
  return {cmd, [o] {
            o->bench.json_path = o->json;
            std::vector<std::filesystem::path> files(o->scenes.begin(), o->scenes.end());
            return tetfsi::app::bench_integrators(files, o->bench, std::cout);
          }};
}

Command add_quality(CLI::App& app) {
  struct Opt {
    std::string file, json, png;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* quality = app.add_subcommand(
      "quality",
      "mesh-quality figures of any tetrahedral .vtu: dihedral angles, shape, dual lengths, "
      "histograms");
  quality->add_option("FILE", o->file, "VTK XML unstructured grid (VTK_TETRA cells are used)")
      ->required()
      ->type_name("FILE.vtu");
  quality->add_option("--json", o->json, "also write the figures and histograms as JSON")
      ->type_name("FILE");
  quality->add_option("--png", o->png, "also draw the four histograms as bar charts into this PNG")
      ->type_name("FILE");
  return {quality,
          [o] { return tetfsi::app::quality_command(o->file, o->json, o->png, std::cout); }};
}

/// "1280x720" → (1280, 720).
CLI::Validator size_validator() {
  return CLI::Validator(
      [](std::string& s) -> std::string {
        const size_t x = s.find('x');
        try {
          size_t a = 0, b = 0;
          if (x != std::string::npos && std::stoi(s.substr(0, x), &a) > 0 &&
              std::stoi(s.substr(x + 1), &b) > 0 && a == x && b == s.size() - x - 1)
            return {};
        } catch (const std::exception&) {
        }
        return "expected WIDTHxHEIGHT in pixels (e.g. 1280x720), got '" + s + "'";
      },
      "");
}

/// `tetfsi render`'s command line, turned into RenderOptions by render_options_of.
struct RenderCli {
  std::string out, png, slice, size = "1280x720", movie;
  std::vector<double> range;
  int step = 0;
  tetfsi::app::RenderOptions render;
  CLI::Option* step_opt = nullptr;
  CLI::Option* slice_opt = nullptr;
};

/// The options as parsed, completed: --step, --slice with or without a plane, --range, --size.
tetfsi::app::RenderOptions render_options_of(const RenderCli& o) {
  tetfsi::app::RenderOptions r = o.render;
  if (*o.step_opt) r.step = o.step;
  r.slice_view = o.slice_opt->count() > 0;
  if (!o.slice.empty()) r.slice = tetfsi::app::parse_slice(o.slice);
  if (o.range.size() == 2) r.range = std::array<double, 2>{o.range[0], o.range[1]};
  const size_t x = o.size.find('x');
  r.width = std::stoi(o.size.substr(0, x));
  r.height = std::stoi(o.size.substr(x + 1));
  r.output = o.png;
  r.movie = o.movie;
  return r;
}

Command add_render(CLI::App& app) {
  using Opt = RenderCli;
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "a picture of a run's frame, headless (VTK's renderer, off screen): the bodies coloured by "
      "a body array; the smoke as a volume, a liquid's surface, or a slice of the fluid (--slice); "
      "colour bars, the scene's name and the time");
  cmd->add_option("OUT", o->out, "the output folder of a run (`tetfsi run SCENE --out OUT`)")
      ->required()
      ->type_name("DIR");
  o->step_opt = cmd->add_option("--step", o->step, "the frame of this step (default: the last)")
                    ->type_name("N");
  auto* all =
      cmd->add_flag("--all", o->render.all, "every frame, one PNG each (then -o names a folder)");
  o->step_opt->excludes(all);
  o->slice_opt = cmd->add_option("--slice", o->slice,
                                 "a slice of the fluid instead of the smoke's volume (or the "
                                 "liquid's surface alone): normal to AXIS through VALUE m "
                                 "(without a value: z through the inflow patches' centre, else "
                                 "the box centre; y with a liquid)")
                     ->expected(0, 1)
                     ->type_name("[AXIS=VALUE]");
  cmd->add_option("--color", o->render.color,
                  "the fluid array (default: smoke_density if the scene emits smoke, drawn as "
                  "a volume, else pressure; another fluid array than smoke_density is drawn "
                  "on the slice; vectors by magnitude); a body array colours the bodies")
      ->type_name("ARRAY");
  cmd->add_option("--body-color", o->render.body_color,
                  "the bodies' array (default: von_mises_stress)")
      ->type_name("ARRAY");
  cmd->add_option("--range", o->range,
                  "the slice's colour range or the smoke volume's opacity range (default: "
                  "fixed per run, docs/user/pictures.md)")
      ->delimiter(',')
      ->expected(2)
      ->type_name("MIN,MAX");
  cmd->add_option("--body-opacity", o->render.body_opacity,
                  "in (0, 1]: below 1 shows the slice through the bodies")
      ->type_name("A")
      ->capture_default_str();
  cmd->add_option("--zoom", o->render.zoom,
                  "magnify the picture's centre (1: the whole box fits; in [0.1, 20])")
      ->type_name("F")
      ->capture_default_str();
  cmd->add_option("--size", o->size, "picture size in pixels")
      ->type_name("WxH")
      ->check(size_validator())
      ->capture_default_str();
  cmd->add_option("-o,--output", o->png,
                  "the PNG (default OUT/pictures/<scene>_<step>.png); with --all a folder "
                  "(default OUT/pictures)")
      ->type_name("FILE.png");
  cmd->add_option("--movie", o->movie,
                  "with --all: assemble the PNGs into this movie with ffmpeg (if installed)")
      ->type_name("FILE.mp4");
  return {cmd,
          [o] { return tetfsi::app::render_command(o->out, render_options_of(*o), std::cout); }};
}

Command add_export(CLI::App& app) {
  struct Opt {
    std::string out, to;
    double voxel_size = 0.0;
    tetfsi::app::ExportOptions exp;
    CLI::Option* voxel_opt = nullptr;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = app.add_subcommand(
      "export",
      "a run's frames as files for renderers (Blender, Houdini): the fluid as OpenVDB volumes "
      "(OUT/vdb/fluid_<frame>.vdb), the bodies' and the liquid's surfaces as PLY meshes "
      "(OUT/ply/<body>_<frame>.ply) and the manifest OUT/export.json; the run's files are not "
      "changed");
  cmd->add_option("OUT", o->out, "the output folder of a run (`tetfsi run SCENE --out OUT`)")
      ->required()
      ->type_name("DIR");
  cmd->add_flag("--vdb", o->exp.vdb, "the fluid's volumes (with neither --vdb nor --ply: both)");
  cmd->add_flag("--ply", o->exp.ply, "the surfaces: each body's boundary, the liquid's surface");
  o->voxel_opt = cmd->add_option("--voxel-size", o->voxel_size,
                                 "the tet fluid's voxel edge in m (default: the scene's "
                                 "fluid.mesh.surface_size); a grid fluid exports its cells and "
                                 "ignores --voxel-size and --subsamples")
                     ->type_name("S");
  cmd->add_option("--subsamples", o->exp.subsamples,
                  "each voxel of the tet fluid averages N^3 samples (1..8)")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option("--threshold", o->exp.smoke_threshold,
                  "voxels with smoke density above T (kg/m^3) are active in the .vdb")
      ->type_name("T")
      ->capture_default_str();
  cmd->add_option("--frames", o->exp.frames,
                  "the run's frames by index from 0 (the order of OUT/<body>.pvd), half-open: "
                  "A:B is A to B-1; also A:, :B, A (default: all)")
      ->type_name("A:B");
  cmd->add_option("--to", o->to, "write vdb/, ply/ and export.json here instead of into OUT")
      ->type_name("DIR");
  return {cmd, [o] {
            if (*o->voxel_opt) o->exp.voxel_size = o->voxel_size;
            o->exp.to = o->to;
            return tetfsi::app::export_command(o->out, o->exp, std::cout);
          }};
}

Command add_plot(CLI::App& app) {
  struct Opt {
    std::string out, png;
  };
  auto o = std::make_shared<Opt>();
  CLI::App* cmd = app.add_subcommand(
      "plot",
      "a run's stats.csv as a page of plots over time: energy budget, solver iterations and "
      "residuals, divergence, enclosed volume drift, mesh quality, seconds per phase");
  cmd->add_option("OUT", o->out, "the output folder of a run (`tetfsi run SCENE --out OUT`)")
      ->required()
      ->type_name("DIR");
  cmd->add_option("-o,--output", o->png, "the PNG (default OUT/stats.png)")->type_name("FILE.png");
  return {cmd, [o] { return tetfsi::app::plot_command(o->out, o->png, std::cout); }};
}

/// Run the one subcommand the command line chose; every error is one line and exit code 1.
int dispatch(const std::vector<Command>& commands, const std::string& log_level,
             const std::string& threads) {
  using namespace tetfsi;
  try {
    set_log_level(rank_index() == 0 ? log_level : std::string("off"));
    set_thread_count(requested_thread_count(threads));
    for (const Command& c : commands) {
      if (!*c.app) continue;
      TETFSI_REQUIRE(
          InputError,
          rank_count() == 1 || c.app->get_name() == "run" || c.app->get_name() == "resume",
          "only `tetfsi run` and `tetfsi resume` use MPI ranks ({} here): start "
          "`tetfsi {}` without mpirun",
          rank_count(), c.app->get_name());
      return c.action();
    }
  } catch (const std::exception& e) {
    return report_error(e.what());  // tetfsi::Error and everything else: one line
  } catch (...) {
    return report_error("unknown internal error");
  }
  return 0;
}

/// `tetfsi --help`'s last part: examples and what a run writes.
const char* const k_footer =
    "Examples:\n"
    "  tetfsi validate data/scenes/sheet_sag.json\n"
    "  tetfsi run data/scenes/sheet_sag.json --steps 50 --set output.every=5\n"
    "  tetfsi bench solvers --n 250000 --backends cholmod,amg --json bench.json\n"
    "  tetfsi quality out/sheet_sag/sheet/sheet_000050.vtu --json q.json --png q.png\n"
    "  tetfsi run data/scenes/remesh_sheet.json -o out/rs   # the fluid mesh follows the sheet\n"
    "  tetfsi bench remesh --json remesh.json\n"
    "  tetfsi bench step data/scenes/remesh_sheet.json --json step.json\n"
    "  tetfsi bench threads data/scenes/smoke_sheets.json --threads-list 1,2\n"
    "  tetfsi bench scaling data/scenes/smoke_sheets.json --threads 1,2 --ranks 1,2\n"
    "  tetfsi bench coupled data/scenes/bar.json --json coupled.json   # the two schemes\n"
    "  tetfsi bench bfgs --json bfgs.json   # [BatheSonnad80] Table I on shell_step\n"
    "  tetfsi run data/scenes/smoke_sheets.json       # the default scene: smoke and two sheets\n"
    "  tetfsi run data/scenes/dam_break.json          # a liquid on the grid\n"
    "  tetfsi scene --keys   # every scene key with its default and range\n"
    "  tetfsi columns        # every stats.csv column with its unit\n"
    "  tetfsi render out/smoke_sheets                # the last frame: a PNG\n"
    "  tetfsi render out/smoke_sheets --all --movie smoke.mp4\n"
    "  tetfsi export out/smoke_sheets --frames 40:   # OpenVDB + PLY for Blender: OUT/vdb, "
    "OUT/ply\n"
    "  tetfsi plot out/smoke_sheets                  # stats.csv as plots: OUT/stats.png\n"
    "  tetfsi run data/scenes/toy.json --checkpoint-every 50 --wall-time 11:30:00\n"
    "  tetfsi resume out/toy --steps 400             # go on from the newest checkpoint\n"
    "Output: OUT/<body>.pvd (open in ParaView), OUT/<body>/*.vtu, OUT/stats.csv,\n"
    "OUT/summary.json, OUT/scene.resolved.json; fluid scenes add OUT/fluid.pvd and\n"
    "OUT/interface.pvd; checkpoints (run --checkpoint-every N, or a stopped run) in\n"
    "OUT/checkpoints/. Errors: one line 'error: ...', exit code 1.\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace tetfsi;
  app::cap_openmp_threads(argv);  // before any library starts threads
  // Under mpirun: MPI first (core/ranks.hpp); the ranks but 0 print nothing on stdout.
  try {
    start_ranks();
  } catch (const std::exception& e) {
    return report_error(e.what());
  }
  if (!is_root_rank() && std::freopen("/dev/null", "w", stdout) == nullptr) return 1;
  if (is_solve_worker()) {  // driver ranks: the workers join rank 0's solves, nothing else
    set_log_level("off");
    set_thread_count(1);
    return serve_solves();
  }

  CLI::App app{
      "tetfsi: incompressible fluids coupled two-way with deformable linear-tet FEM solids. The "
      "fluid (smoke, or a liquid with a free surface on the grid) lives on a tet mesh rebuilt "
      "every step around the bodies or on a MAC grid; fluid pressure and solid velocities are "
      "solved together [Chentanez06], with time splitting and the BFGS iteration "
      "[BatheSonnad80] to compare. Scenes are JSON files; output is ParaView (VTU/VTI/VTP/PVD) "
      "with stats.csv and summary.json. The manual: docs/README.md.",
      "tetfsi"};
  app.set_version_flag("--version", std::string("tetfsi ") + TETFSI_VERSION);
  app.require_subcommand(1);
  app.fallthrough();  // --log-level is accepted after the subcommand too
  app.footer(k_footer);

  std::string log_level = "info";
  app.add_option("--log-level", log_level,
                 "log messages on stderr at least this severe: trace, debug, info, warn, error, "
                 "off (also accepted after the subcommand)")
      ->type_name("LEVEL")
      ->capture_default_str();
  // Checked after parsing (parse_thread_count) so that a bad value is one line `error: ...`.
  std::string threads;
  app.add_option("--threads", threads,
                 "threads of the parallel loops (an integer >= 1; default: $TETFSI_THREADS, else "
                 "every core); results do not depend on it (docs/user/running.md)")
      ->type_name("N");

  std::vector<Command> commands = {add_run(app), add_resume(app), add_checkpoint(app),
                                   add_validate(app)};
  CLI::App* bench = app.add_subcommand(
      "bench", "benchmarks: measured figures against in-run floors (never part of the tests)");
  bench->require_subcommand(1);
  for (auto add : {add_bench_solvers, add_bench_remesh, add_bench_step, add_bench_threads,
                   add_bench_scaling, add_bench_coupled, add_bench_bfgs, add_bench_integrators})
    commands.push_back(add(*bench));
  for (auto add : {add_quality, add_render, add_export, add_plot, add_scene, add_columns})
    commands.push_back(add(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  return dispatch(commands, log_level, threads);
}
