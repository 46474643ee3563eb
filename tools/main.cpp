/// @file main.cpp
/// The `tetfsi` command line:
///   tetfsi run SCENE [--out DIR] [--set key.path=value ...] [--steps N | --end-time T]
///                    [--progress auto|tty|plain|off]
///   tetfsi validate SCENE [--set key.path=value ...]
///   tetfsi bench solvers [--n N] [--json FILE] [--backends a,b]
///   tetfsi bench remesh [--json FILE] [--max-cells N]
///   tetfsi bench step SCENE [--json FILE] [--steps N] [--sizes a,b,c]
///   tetfsi bench coupled SCENE [--json FILE] [--time T] [--steps-down N] [--set k=v ...]
///   tetfsi bench bfgs [SCENE] [--json FILE] [--history FILE.csv] [--ratio R] [--time T]
///                     [--set k=v ...]
///   tetfsi quality FILE.vtu [--json FILE] [--png FILE]
///   (every subcommand also takes --log-level trace|debug|info|warn|error|off)
/// Every error ends the program with one line `error: <message>` on stderr and exit code 1;
/// command-line usage errors are reported by CLI11 with its exit code. Ctrl-C (or SIGTERM)
/// during `run` stops after the current step with a complete output folder, one line
/// `error: interrupted ...` and exit code 130; a second Ctrl-C ends the program at once.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/error.hpp"
#include "core/log.hpp"
#include "tools/bench_bfgs.hpp"
#include "tools/bench_coupled.hpp"
#include "tools/bench_remesh.hpp"
#include "tools/bench_solvers.hpp"
#include "tools/bench_step.hpp"
#include "tools/output.hpp"
#include "tools/process_env.hpp"
#include "tools/quality_cmd.hpp"
#include "tools/run.hpp"
#include "tools/scene.hpp"

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
int report_error(std::string message) {
  for (char& c : message)
    if (c == '\n' || c == '\r') c = ' ';
  std::fflush(stdout);
  std::fprintf(stderr, "error: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tetfsi;
  tools::cap_openmp_threads(argv);  // before any library starts threads

  CLI::App app{
      "tetfsi: incompressible fluids coupled with deformable linear-tet FEM solids "
      "(this version: solids only, with ParaView output)",
      "tetfsi"};
  app.set_version_flag("--version", std::string("tetfsi ") + TETFSI_VERSION);
  app.require_subcommand(1);
  app.fallthrough();  // --log-level is accepted after the subcommand too
  app.footer(
      "Examples:\n"
      "  tetfsi validate data/scenes/sheet_sag.json\n"
      "  tetfsi run data/scenes/sheet_sag.json --steps 50 --set output.every=5\n"
      "  tetfsi bench solvers --n 250000 --backends cholmod,amg --json bench.json\n"
      "  tetfsi quality out/sheet_sag/sheet/sheet_000050.vtu --json q.json --png q.png\n"
      "  tetfsi run data/scenes/remesh_sheet.json -o out/rs   # the fluid mesh follows the sheet\n"
      "  tetfsi bench remesh --json remesh.json\n"
      "  tetfsi bench step data/scenes/remesh_sheet.json --json step.json\n"
      "  tetfsi bench coupled data/scenes/bar.json --json coupled.json   # the two schemes\n"
      "  tetfsi bench bfgs --json bfgs.json   # [BatheSonnad80] Table I on shell_step\n"
      "Output: OUT/<body>.pvd (open in ParaView), OUT/<body>/*.vtu, OUT/stats.csv,\n"
      "OUT/summary.json, OUT/scene.resolved.json; fluid scenes add OUT/fluid.pvd and\n"
      "OUT/interface.pvd. Errors: one line 'error: ...', exit code 1.\n");

  /// An integer option that must be at least 1.
  const CLI::Validator at_least_one(
      [](std::string& v) -> std::string {
        try {
          std::size_t used = 0;
          if (std::stoll(v, &used) >= 1 && used == v.size()) return {};
        } catch (const std::exception&) {
        }
        return "must be an integer >= 1, got '" + v + "'";
      },
      ">= 1");

  std::string log_level = "info";
  app.add_option("--log-level", log_level,
                 "log messages on stderr at least this severe: trace, debug, info, warn, error, "
                 "off (also accepted after the subcommand)")
      ->type_name("LEVEL")
      ->capture_default_str();

  // ---- run ----
  CLI::App* run = app.add_subcommand("run", "simulate a scene and write ParaView output");
  std::string run_scene_file;
  std::string run_out;
  std::vector<std::string> run_sets;
  int run_steps = 0;
  double run_end_time = 0.0;
  std::string run_progress = "auto";
  run->add_option("SCENE", run_scene_file, "scene file (JSON)")->required()->type_name("FILE");
  run->add_option("--out,-o", run_out, "output folder (default: out/<scene name>)")
      ->type_name("DIR");
  run->add_option("--set", run_sets,
                  "override a scene value, e.g. --set time.dt=0.002 --set "
                  "bodies.0.material.density=500 (repeatable)")
      ->allow_extra_args(false)
      ->type_name("KEY=VALUE");
  auto* steps_opt = run->add_option("--steps", run_steps, "number of steps (overrides the scene)")
                        ->type_name("N")
                        ->check(at_least_one);
  auto* end_opt = run->add_option("--end-time", run_end_time,
                                  "end time in s: ceil(T / dt) steps (overrides the scene)")
                      ->type_name("T");
  steps_opt->excludes(end_opt);
  run->add_option("--progress", run_progress,
                  "progress on stderr: auto (live line on a terminal, else plain), tty, plain, off")
      ->type_name("MODE")
      ->check(CLI::IsMember({"auto", "tty", "plain", "off"}))
      ->capture_default_str();

  // ---- validate ----
  CLI::App* validate =
      app.add_subcommand("validate", "check a scene: parse it, build its bodies, print a summary");
  std::string val_scene_file;
  std::vector<std::string> val_sets;
  validate->add_option("SCENE", val_scene_file, "scene file (JSON)")->required()->type_name("FILE");
  validate->add_option("--set", val_sets, "override a scene value (repeatable)")
      ->allow_extra_args(false)
      ->type_name("KEY=VALUE");

  // ---- bench ----
  CLI::App* bench = app.add_subcommand("bench", "benchmarks");
  bench->require_subcommand(1);
  CLI::App* bench_solvers_cmd =
      bench->add_subcommand("solvers", "time the linear-solver backends on a 3D Poisson problem");
  int bench_n = 100000;
  std::string bench_json;
  std::vector<std::string> bench_backends;
  bench_solvers_cmd->add_option("--n", bench_n, "approximate number of unknowns")
      ->type_name("N")
      ->check(at_least_one)
      ->capture_default_str();
  bench_solvers_cmd->add_option("--json", bench_json, "also write the results to this JSON file")
      ->type_name("FILE");
  bench_solvers_cmd
      ->add_option(
          "--backends", bench_backends,
          "comma-separated backends (default: all): " +
              [] {
                std::string s;
                for (const auto& n : solver_names()) s += (s.empty() ? "" : ",") + n;
                return s;
              }())
      ->delimiter(',')
      ->type_name("A,B");

  CLI::App* bench_remesh_cmd = bench->add_subcommand(
      "remesh", "time the fluid remesher against the bare CGAL Delaunay of the same vertices");
  std::string bench_remesh_json;
  long bench_remesh_max = 1000000;
  bench_remesh_cmd
      ->add_option("--json", bench_remesh_json, "also write the results to this JSON file")
      ->type_name("FILE");
  bench_remesh_cmd
      ->add_option("--max-cells", bench_remesh_max,
                   "skip the cases above this size (30k, 250k, 1M)")
      ->type_name("N")
      ->check(at_least_one)
      ->capture_default_str();

  CLI::App* bench_step_cmd = bench->add_subcommand(
      "step",
      "time whole steps of a fluid scene at three mesh sizes against the floor: the bare CGAL "
      "Delaunay of the same vertices + one AMG pressure solve");
  std::string bench_step_scene;
  std::string bench_step_json;
  int bench_step_steps = 3;
  std::vector<double> bench_step_sizes;
  bench_step_cmd->add_option("SCENE", bench_step_scene, "fluid scene file (JSON)")
      ->required()
      ->type_name("FILE");
  bench_step_cmd->add_option("--json", bench_step_json, "also write the results to this JSON file")
      ->type_name("FILE");
  bench_step_cmd
      ->add_option("--steps", bench_step_steps,
                   "steps per size; the first is a warm-up and is not in the figures (>= 2)")
      ->type_name("N")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  bench_step_cmd
      ->add_option("--sizes", bench_step_sizes,
                   "comma-separated factors on the scene's fluid mesh sizes (default: chosen for "
                   "about 30k, 100k and 250k cells)")
      ->delimiter(',')
      ->check(CLI::PositiveNumber)
      ->type_name("A,B,C");

  CLI::App* bench_coupled_cmd = bench->add_subcommand(
      "coupled",
      "the two coupling schemes side by side: each one's largest stable step, seconds per step, "
      "and the coupled solve against a fluid-only projection on the same mesh");
  std::string bench_coupled_scene;
  tools::BenchCoupledOptions bench_coupled_opt;
  std::string bench_coupled_json;
  bench_coupled_cmd->add_option("SCENE", bench_coupled_scene, "two-way fluid scene file (JSON)")
      ->required()
      ->type_name("FILE");
  bench_coupled_cmd
      ->add_option("--json", bench_coupled_json, "also write the results to this JSON file")
      ->type_name("FILE");
  bench_coupled_cmd
      ->add_option("--time", bench_coupled_opt.time,
                   "simulated seconds of each stability run (> 0)")
      ->type_name("T")
      ->capture_default_str();
  bench_coupled_cmd
      ->add_option("--steps-down", bench_coupled_opt.steps_down,
                   "halvings of the largest step 2 dt tried: h = 2 dt / 2^k, k = 0..N (0..12)")
      ->type_name("N")
      ->capture_default_str();
  bench_coupled_cmd
      ->add_option("--timed-steps", bench_coupled_opt.timed_steps,
                   "steps per scheme at dt for the seconds per step, the first a warm-up (>= 4)")
      ->type_name("N")
      ->capture_default_str();
  bench_coupled_cmd
      ->add_option("--set", bench_coupled_opt.overrides, "override a scene value (repeatable)")
      ->allow_extra_args(false)
      ->type_name("KEY=VALUE");

  CLI::App* bench_bfgs_cmd = bench->add_subcommand(
      "bfgs",
      "the seed's Table I [BatheSonnad80]: BFGS, modified Newton and Newton at dt and R dt, "
      "iterations per step, convergence, and the agreement of two probes' displacements");
  std::string bench_bfgs_scene = tools::k_bench_bfgs_scene;
  tools::BenchBfgsOptions bench_bfgs_opt;
  std::string bench_bfgs_json, bench_bfgs_history;
  double bench_bfgs_time = 0.0;
  bench_bfgs_cmd
      ->add_option("SCENE", bench_bfgs_scene,
                   "dynamic scene file (JSON): two-way coupled (coupling.scheme = method) or not "
                   "(solid.integrator = method)")
      ->type_name("FILE")
      ->capture_default_str();
  bench_bfgs_cmd->add_option("--json", bench_bfgs_json, "also write the results to this JSON file")
      ->type_name("FILE");
  bench_bfgs_cmd
      ->add_option("--history", bench_bfgs_history,
                   "also write the probes' histories (method, dt, step, t, dA_x, dB_x, uA_x, "
                   "uB_x) to this CSV file")
      ->type_name("FILE.csv");
  bench_bfgs_cmd
      ->add_option("--ratio", bench_bfgs_opt.ratio,
                   "the larger step is R times the scene's dt (> 1)")
      ->type_name("R")
      ->capture_default_str();
  auto* bench_bfgs_time_opt =
      bench_bfgs_cmd
          ->add_option("--time", bench_bfgs_time,
                       "simulated seconds of each run (> 0; default: the scene's end time)")
          ->type_name("T");
  bench_bfgs_cmd
      ->add_option("--set", bench_bfgs_opt.overrides, "override a scene value (repeatable)")
      ->allow_extra_args(false)
      ->type_name("KEY=VALUE");

  // ---- quality ----
  CLI::App* quality = app.add_subcommand(
      "quality",
      "mesh-quality figures of any tetrahedral .vtu: dihedral angles, shape, dual lengths, "
      "histograms");
  std::string quality_file;
  std::string quality_json;
  std::string quality_png;
  quality->add_option("FILE", quality_file, "VTK XML unstructured grid (VTK_TETRA cells are used)")
      ->required()
      ->type_name("FILE.vtu");
  quality->add_option("--json", quality_json, "also write the figures and histograms as JSON")
      ->type_name("FILE");
  quality
      ->add_option("--png", quality_png,
                   "also draw the four histograms as bar charts into this PNG")
      ->type_name("FILE");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    set_log_level(log_level);

    if (*run) {
      const tools::Scene scene = tools::load_scene(run_scene_file, run_sets);
      tools::RunOptions opt;
      opt.out_dir = run_out.empty()
                        ? std::filesystem::path("out") / tools::file_safe_name(scene.name)
                        : std::filesystem::path(run_out);
      if (*steps_opt) opt.steps = run_steps;
      if (*end_opt) opt.end_time = run_end_time;
      opt.progress = tools::parse_progress_mode(run_progress);
      opt.stop = &g_stop;
      std::signal(SIGINT, on_stop_signal);
      std::signal(SIGTERM, on_stop_signal);
      const tools::RunResult r = tools::run_scene(scene, opt);
      std::signal(SIGINT, SIG_DFL);
      std::signal(SIGTERM, SIG_DFL);
      tools::print_summary(r, std::cout);
      std::cout.flush();
      if (r.interrupted) {
        report_error(r.error);
        return 130;  // the shell convention for "ended by SIGINT"
      }
      if (!r.completed) return report_error(r.error);
      return 0;
    }
    if (*validate) {
      const tools::Scene scene = tools::load_scene(val_scene_file, val_sets);
      const solid::SolidWorld world = tools::build_world(scene);
      tools::print_world_summary(scene, world, std::cout);
      std::cout << "ok\n";
      return 0;
    }
    if (*bench_solvers_cmd) {
      return tools::bench_solvers(bench_n, bench_json, bench_backends, std::cout);
    }
    if (*bench_remesh_cmd) {
      return tools::bench_remesh(bench_remesh_json, bench_remesh_max, std::cout);
    }
    if (*bench_step_cmd) {
      tools::BenchStepOptions o;
      o.json_path = bench_step_json;
      o.steps = bench_step_steps;
      o.scales = bench_step_sizes;
      return tools::bench_step(bench_step_scene, o, std::cout);
    }
    if (*bench_coupled_cmd) {
      bench_coupled_opt.json_path = bench_coupled_json;
      return tools::bench_coupled(bench_coupled_scene, bench_coupled_opt, std::cout);
    }
    if (*bench_bfgs_cmd) {
      bench_bfgs_opt.json_path = bench_bfgs_json;
      bench_bfgs_opt.history_path = bench_bfgs_history;
      if (*bench_bfgs_time_opt) bench_bfgs_opt.time = bench_bfgs_time;
      return tools::bench_bfgs(bench_bfgs_scene, bench_bfgs_opt, std::cout);
    }
    if (*quality) {
      return tools::quality_command(quality_file, quality_json, quality_png, std::cout);
    }
  } catch (const std::exception& e) {
    return report_error(e.what());  // tetfsi::Error and everything else: one line
  } catch (...) {
    return report_error("unknown internal error");
  }
  return 0;
}
