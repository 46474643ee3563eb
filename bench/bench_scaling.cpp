/// @file bench_scaling.cpp
/// `tetfsi bench scaling` (bench_scaling.hpp).
#include "bench/bench_scaling.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <ostream>
#include <utility>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "bench/bench_threads.hpp"
#include "core/error.hpp"
#include "core/parallel.hpp"
#include "io/output.hpp"
#include "scene/scene.hpp"

namespace tetfsi::app {

namespace {

namespace fs = std::filesystem;

/// One run's figures: its phases in column order, the mean seconds per timed step of each,
/// and its physics columns (name → values per step).
struct ScalingRun {
  int ranks = 1, threads = 1;
  std::vector<std::string> phases;
  std::map<std::string, double> seconds;
  double step_lo = 0.0, step_hi = 0.0;  ///< the whole step's fastest and slowest round
  std::map<std::string, std::vector<std::string>> physics;
};

/// A word for the shell, in single quotes.
std::string quoted(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// The shell command of one run: this executable's `run`, under mpirun for ranks > 1 (not
/// bound to cores, so that replicated ranks' threads spread too; a driver rank 0 unbinds
/// itself).
std::string run_command(const fs::path& scene, const BenchScalingOptions& opt, int ranks,
                        int threads, const fs::path& out) {
  std::string cmd;
  if (ranks > 1)
    cmd = fmt::format(
        "mpirun --quiet --bind-to none -np {}{} ", ranks,
        ranks > static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN)) ? " --oversubscribe" : "");
  cmd += fmt::format("{} run {} --out {} --steps {} --threads {} --progress off --log-level error",
                     quoted(fs::read_symlink("/proc/self/exe").string()), quoted(scene.string()),
                     quoted(out.string()), opt.steps, threads);
  for (const std::string& s : opt.overrides) cmd += " --set " + quoted(s);
  return cmd +
         fmt::format(" >{} 2>{}", quoted((out.string() + ".out")), quoted(out.string() + ".err"));
}

/// The last nonempty line of a file ("" if none).
std::string last_line(const fs::path& p) {
  std::string all;
  if (FILE* f = std::fopen(p.c_str(), "r")) {
    char buf[4096];
    for (size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) all.append(buf, n);
    std::fclose(f);
  }
  while (!all.empty() && (all.back() == '\n' || all.back() == '\r')) all.pop_back();
  const auto nl = all.rfind('\n');
  return nl == std::string::npos ? all : all.substr(nl + 1);
}

ScalingRun run_once(const fs::path& scene, const BenchScalingOptions& opt, int ranks, int threads,
                    const std::vector<std::string>& phases, const fs::path& dir) {
  const fs::path out = dir / fmt::format("r{}_t{}", ranks, threads);
  const int status = std::system(run_command(scene, opt, ranks, threads, out).c_str());
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  TETFSI_REQUIRE(SolverError, code == 0,
                 "bench scaling: the run at {} rank(s) x {} thread(s) "
                 "failed (exit code {}): {}",
                 ranks, threads, code, last_line(out.string() + ".err"));
  const StatsCsv csv = read_stats_csv(out / "stats.csv");
  ScalingRun run;
  run.ranks = ranks;
  run.threads = threads;
  for (std::size_t k = 0; k < csv.header.size(); ++k) {
    const std::string& name = csv.header[k];
    const bool phase = std::find(phases.begin(), phases.end(), name) != phases.end();
    if (phase) run.phases.push_back(name);
    double sum = 0.0;
    for (std::size_t i = 0; i < csv.rows.size(); ++i) {
      if (phase && i > 0) sum += std::stod(csv.rows[i].at(k));
      if (!is_seconds_column(name, phases)) run.physics[name].push_back(csv.rows[i].at(k));
    }
    if (phase) run.seconds[name] = sum / static_cast<double>(csv.rows.size() - 1);
  }
  return run;
}

/// The solver's own figures (iteration counts, residuals, the divergence left after the
/// projection) and the mesh-quality figures (q_*: counts of near-degenerate cells that tip over
/// a threshold with the last digits of the vertices): they differ between any two runs that
/// agree to solver tolerance.
bool is_solver_figure(const std::string& name) {
  return name.find("iterations") != std::string::npos ||
         name.find("residual") != std::string::npos || name == "divergence" ||
         name.rfind("q_", 0) == 0;
}

/// The largest difference of b's physics columns from a's (solver figures left out), relative
/// to each column's largest |value| in a, and the column where it is (0 for identical runs).
std::pair<double, std::string> max_rel_difference(const ScalingRun& a, const ScalingRun& b) {
  std::pair<double, std::string> worst{0.0, ""};
  for (const auto& [name, va] : a.physics) {
    if (is_solver_figure(name)) continue;
    const auto it = b.physics.find(name);
    if (it == b.physics.end() || it->second.size() != va.size()) return {INFINITY, name};
    double scale = 0.0, diff = 0.0;
    for (size_t i = 0; i < va.size(); ++i) {
      const double x = std::stod(va[i]), y = std::stod(it->second[i]);
      if (std::isnan(x) && std::isnan(y)) continue;
      scale = std::max(scale, std::abs(x));
      diff = std::max(diff, std::isfinite(y) ? std::abs(x - y) : INFINITY);
    }
    const double rel = diff == 0 ? 0.0 : scale > 0 ? diff / scale : INFINITY;
    if (rel > worst.first) worst = {rel, name};
  }
  return worst;
}

/// The first round's runs with each phase's seconds the median over the rounds (the mean of
/// the middle two for an even count).
std::vector<ScalingRun> median_of_rounds(const std::vector<std::vector<ScalingRun>>& rounds) {
  std::vector<ScalingRun> runs = rounds.front();
  for (size_t i = 0; i < runs.size(); ++i)
    for (auto& [phase, seconds] : runs[i].seconds) {
      std::vector<double> v;
      for (const auto& round : rounds) v.push_back(round[i].seconds.at(phase));
      std::sort(v.begin(), v.end());
      const size_t m = v.size() / 2;
      seconds = v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
      if (phase == "total") {
        runs[i].step_lo = v.front();
        runs[i].step_hi = v.back();
      }
    }
  return runs;
}

void check_options(const Scene& scene, const BenchScalingOptions& opt) {
  TETFSI_REQUIRE(InputError, opt.repeat >= 1, "bench scaling: --repeat must be at least 1, got {}",
                 opt.repeat);
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "bench scaling needs a dynamic scene (mode is 'static')");
  TETFSI_REQUIRE(InputError, opt.steps >= 2,
                 "bench scaling: --steps must be at least 2 (the first is a warm-up), got {}",
                 opt.steps);
  TETFSI_REQUIRE(InputError, !opt.threads.empty() && !opt.ranks.empty(),
                 "bench scaling: --threads and --ranks need at least one count each");
  for (const auto* list : {&opt.threads, &opt.ranks})
    for (const int n : *list)
      TETFSI_REQUIRE(InputError, n >= 1, "bench scaling: every count must be >= 1, got {}", n);
  if (*std::max_element(opt.ranks.begin(), opt.ranks.end()) > 1)
    TETFSI_REQUIRE(InputError, std::system("command -v mpirun >/dev/null 2>&1") == 0,
                   "bench scaling: --ranks above 1 needs mpirun (Debian: apt-get install "
                   "openmpi-bin), which is not on the PATH");
}

}  // namespace

namespace {

std::string run_label(const ScalingRun& r) {
  return fmt::format("{}r x {}t", r.ranks, r.threads);
}

/// The table: seconds per step of each phase per run, then the speed-up and the efficiency
/// against the first run; also the JSON "phases".
nlohmann::json print_phases(const std::vector<ScalingRun>& runs, std::ostream& out) {
  std::string head = fmt::format("{:<18}", "phase (s/step)");
  for (const ScalingRun& r : runs) head += fmt::format(" {:>9}", run_label(r));
  fmt::print(out, "{}\n", head);
  nlohmann::json jphases = nlohmann::json::array();
  std::vector<std::string> speed_lines, eff_lines;
  for (const std::string& p : runs[0].phases) {
    const std::string label = p == "total" ? "step" : p;
    std::vector<double> sec, speedup, efficiency;
    for (const ScalingRun& r : runs) sec.push_back(r.seconds.count(p) ? r.seconds.at(p) : 0.0);
    if (*std::max_element(sec.begin(), sec.end()) == 0.0) continue;  // a phase it does not have
    std::string line = fmt::format("{:<18}", label), sp = line, ef = line;
    for (size_t i = 0; i < runs.size(); ++i) {
      const double x = sec[i] > 0 ? sec[0] / sec[i] : 0.0;
      speedup.push_back(x);
      efficiency.push_back(x / (runs[i].ranks * runs[i].threads));
      line += fmt::format(" {:>9.4f}", sec[i]);
      sp += sec[i] > 0 ? fmt::format(" {:>9.2f}", x) : fmt::format(" {:>9}", "-");
      ef += sec[i] > 0 ? fmt::format(" {:>9.2f}", efficiency.back()) : fmt::format(" {:>9}", "-");
    }
    fmt::print(out, "{}\n", line);
    speed_lines.push_back(sp);
    eff_lines.push_back(ef);
    jphases.push_back(
        {{"phase", label}, {"seconds", sec}, {"speedup", speedup}, {"efficiency", efficiency}});
  }
  std::string spread = fmt::format("{:<18}", "step: rounds");
  for (const ScalingRun& r : runs)
    spread += fmt::format(" {:>9}", fmt::format("{:.2f}-{:.2f}", r.step_lo, r.step_hi));
  fmt::print(out, "{}\n", spread);
  fmt::print(out, "\nspeed-up (seconds of {} / seconds)\n", run_label(runs[0]));
  for (const std::string& l : speed_lines) fmt::print(out, "{}\n", l);
  fmt::print(out, "\nparallel efficiency (speed-up / (ranks x threads))\n");
  for (const std::string& l : eff_lines) fmt::print(out, "{}\n", l);
  return jphases;
}

}  // namespace

int bench_scaling(const fs::path& scene_file, const BenchScalingOptions& opt, std::ostream& out) {
  const Scene scene = load_scene(scene_file, opt.overrides);
  check_options(scene, opt);
  if (geteuid() == 0) {  // Open MPI refuses root unless told (the runs are ours)
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 0);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 0);
  }
  const std::vector<std::string> phases = all_phase_columns();
  const fs::path dir = fs::temp_directory_path() / fmt::format("tetfsi_bench_scaling_{}", getpid());
  std::vector<ScalingRun> runs;
  fs::create_directories(dir);
  try {
    // --repeat: every pair once per round, rounds one after another, so that a slow spell of
    // the machine hits every pair alike; each phase's median over the rounds.
    std::vector<std::vector<ScalingRun>> rounds(static_cast<size_t>(opt.repeat));
    for (auto& round : rounds)
      for (const int r : opt.ranks)
        for (const int t : opt.threads)
          round.push_back(run_once(scene_file, opt, r, t, phases, dir));
    runs = median_of_rounds(rounds);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(dir, ec);
    throw;
  }
  std::error_code ec;
  fs::remove_all(dir, ec);

  fmt::print(out,
             "tetfsi bench scaling: {} ('{}'), {} steps per run (the first a warm-up; seconds are "
             "means of the others{}), {} core(s); NrxMt = N MPI ranks x M threads each\n\n",
             scene_file.string(), scene.name, opt.steps,
             opt.repeat > 1 ? fmt::format(", medians of {} rounds", opt.repeat) : std::string(),
             sysconf(_SC_NPROCESSORS_ONLN));
  const nlohmann::json jphases = print_phases(runs, out);
  std::vector<double> diff;
  std::vector<bool> identical;
  nlohmann::json jruns = nlohmann::json::array();
  std::string agree;
  for (const ScalingRun& r : runs) {
    const auto [d, column] = max_rel_difference(runs[0], r);
    diff.push_back(d);
    identical.push_back(r.physics == runs[0].physics);
    jruns.push_back({{"ranks", r.ranks},
                     {"threads", r.threads},
                     {"step_s_fastest", r.step_lo},
                     {"step_s_slowest", r.step_hi}});
    if (&r != &runs[0])
      agree += fmt::format("\n  {}: {}", run_label(r),
                           identical.back() ? std::string("identical, bit for bit")
                                            : fmt::format("{:.2g} ({})", d, column));
  }
  fmt::print(out,
             "\nphysics against {} (stats.csv's columns but the seconds, the solver's "
             "iterations, residuals and divergence, and the mesh quality; the largest difference "
             "relative to the "
             "column's largest |value|, and its column):{}\n",
             run_label(runs[0]), agree.empty() ? " (one run)" : agree);
  if (!opt.json_path.empty()) {
    const nlohmann::json j{{"scene", scene.name},
                           {"steps", opt.steps},
                           {"repeat", opt.repeat},
                           {"cores", sysconf(_SC_NPROCESSORS_ONLN)},
                           {"runs", jruns},
                           {"phases", jphases},
                           {"max_rel_difference", diff},
                           {"identical", identical}};
    write_text_file_atomic(opt.json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace tetfsi::app
