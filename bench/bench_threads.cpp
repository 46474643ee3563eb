/// @file bench_threads.cpp
/// `tetfsi bench threads` (bench_threads.hpp).
#include "bench/bench_threads.hpp"

#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "io/output.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"

namespace tetfsi::app {

namespace fs = std::filesystem;

StatsCsv read_stats_csv(const fs::path& path) {
  std::ifstream in(path);
  TETFSI_REQUIRE(InputError, in.good(), "cannot read '{}'", path.string());
  auto split = [](const std::string& line) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    return f;
  };
  StatsCsv csv;
  std::string line;
  if (std::getline(in, line)) csv.header = split(line);
  while (std::getline(in, line)) csv.rows.push_back(split(line));
  return csv;
}

bool is_seconds_column(const std::string& name, const std::vector<std::string>& phases) {
  return std::find(phases.begin(), phases.end(), name) != phases.end() ||
         (name.size() > 2 && name.compare(name.size() - 2, 2, "_s") == 0);
}

std::vector<std::string> all_phase_columns() {
  std::vector<std::string> all;
  for (const bool fluid : {false, true})
    for (const bool coupled : {false, true})
      for (const std::string& p : StatsWriter::phase_columns(fluid, coupled))
        if (std::find(all.begin(), all.end(), p) == all.end()) all.push_back(p);
  return all;
}

namespace {

/// One run's figures: its phases in column order, the mean seconds per timed step of each,
/// and its physics columns.
struct ThreadsRun {
  std::vector<std::string> phases;
  std::map<std::string, double> seconds;
  std::vector<std::vector<std::string>> physics;
};

ThreadsRun run_once(const Scene& scene, const BenchThreadsOptions& opt, int threads,
                    const std::vector<std::string>& phases, const fs::path& dir) {
  set_thread_count(threads);
  RunOptions ro;
  ro.out_dir = dir / fmt::format("threads_{}", threads);
  ro.steps = opt.steps;
  ro.progress = ProgressMode::Off;
  const RunResult r = run_scene(scene, ro);
  TETFSI_REQUIRE(SolverError, r.completed, "bench threads: the run on {} thread(s) failed: {}",
                 threads, r.error);
  const StatsCsv csv = read_stats_csv(ro.out_dir / "stats.csv");
  ThreadsRun run;
  for (std::size_t k = 0; k < csv.header.size(); ++k) {
    const std::string& name = csv.header[k];
    if (std::find(phases.begin(), phases.end(), name) == phases.end()) continue;
    run.phases.push_back(name);
    double sum = 0.0;
    for (std::size_t i = 1; i < csv.rows.size(); ++i) sum += std::stod(csv.rows[i].at(k));
    run.seconds[name] = sum / static_cast<double>(csv.rows.size() - 1);
  }
  for (const auto& row : csv.rows) {
    std::vector<std::string> p;
    for (std::size_t k = 0; k < row.size() && k < csv.header.size(); ++k)
      if (!is_seconds_column(csv.header[k], phases)) p.push_back(row[k]);
    run.physics.push_back(std::move(p));
  }
  std::error_code ec;
  fs::remove_all(ro.out_dir, ec);
  return run;
}

void check_options(const Scene& scene, const BenchThreadsOptions& opt) {
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "bench threads needs a dynamic scene (mode is 'static')");
  TETFSI_REQUIRE(InputError, opt.steps >= 2,
                 "bench threads: --steps must be at least 2 (the first is a warm-up), got {}",
                 opt.steps);
  TETFSI_REQUIRE(InputError, !opt.threads.empty(), "bench threads: --threads-list is empty");
  for (const int n : opt.threads)
    TETFSI_REQUIRE(InputError, n >= 1,
                   "bench threads: --threads-list: every thread count must be >= 1, got {}", n);
}

}  // namespace

int bench_threads(const fs::path& scene_file, const BenchThreadsOptions& opt, std::ostream& out) {
  const Scene scene = load_scene(scene_file, opt.overrides);
  check_options(scene, opt);
  const std::vector<std::string> phases = all_phase_columns();
  const fs::path dir = fs::temp_directory_path() / fmt::format("tetfsi_bench_threads_{}", getpid());
  const int restore = thread_count();
  std::vector<ThreadsRun> runs;
  try {
    for (const int n : opt.threads) runs.push_back(run_once(scene, opt, n, phases, dir));
  } catch (...) {
    set_thread_count(restore);
    std::error_code ec;
    fs::remove_all(dir, ec);
    throw;
  }
  set_thread_count(restore);
  std::error_code ec;
  fs::remove_all(dir, ec);

  fmt::print(out,
             "tetfsi bench threads: {} ('{}'), {} steps per run (the first a warm-up; seconds "
             "are means of the others), {} core(s)\n\n",
             scene_file.string(), scene.name, opt.steps, default_thread_count());
  std::string head = fmt::format("{:<18}", "phase (s/step)");
  for (const int n : opt.threads) head += fmt::format(" {:>9}", fmt::format("{} thr", n));
  for (std::size_t i = 1; i < opt.threads.size(); ++i)
    head += fmt::format(" {:>9}", fmt::format("x{}", opt.threads[i]));
  fmt::print(out, "{}\n", head);
  nlohmann::json jphases = nlohmann::json::array();
  for (const std::string& p : runs[0].phases) {
    const std::string label = p == "total" ? "step" : p;
    std::string line = fmt::format("{:<18}", label);
    std::vector<double> sec, speedup;
    for (const ThreadsRun& r : runs) sec.push_back(r.seconds.at(p));
    for (const double s : sec) line += fmt::format(" {:>9.4f}", s);
    for (const double s : sec) speedup.push_back(s > 0 ? sec[0] / s : 0.0);
    for (std::size_t i = 1; i < sec.size(); ++i)  // "-": a phase this scene does not have
      line += sec[i] > 0 ? fmt::format(" {:>9.2f}", speedup[i]) : fmt::format(" {:>9}", "-");
    fmt::print(out, "{}\n", line);
    jphases.push_back({{"phase", label}, {"seconds", sec}, {"speedup", speedup}});
  }
  std::vector<bool> identical;
  for (const ThreadsRun& r : runs) identical.push_back(r.physics == runs[0].physics);
  std::string same;
  for (std::size_t i = 1; i < runs.size(); ++i)
    same += fmt::format("{}{} threads: {}", i > 1 ? "; " : "", opt.threads[i],
                        identical[i] ? "identical" : "DIFFERENT");
  fmt::print(out,
             "\nxN = seconds at {} thread(s) / seconds at N threads. Physics (every stats.csv "
             "column but the seconds) against {} thread(s), bit for bit: {}\n",
             opt.threads[0], opt.threads[0], same.empty() ? "(one run)" : same);
  if (!opt.json_path.empty()) {
    const nlohmann::json j{{"scene", scene.name},    {"steps", opt.steps},
                           {"threads", opt.threads}, {"phases", jphases},
                           {"identical", identical}, {"cores", default_thread_count()}};
    write_text_file_atomic(opt.json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace tetfsi::app
