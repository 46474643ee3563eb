#pragma once
/// @file bench_threads.hpp
/// `tetfsi bench threads SCENE [--steps N] [--threads-list 1,2] [--json FILE] [--set K=V]`:
/// the same steps of a scene run (app::run_scene, its frames into a temporary folder) once
/// per thread count, in one process: mean seconds per step of every phase of stats.csv
/// (the first step is a warm-up and left out) and the speed-up of each phase and of the whole
/// step against the first thread count of the list. It also says whether the runs' physics
/// (every stats.csv column but the seconds) came out the same, bit for bit.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace tetfsi::app {

struct BenchThreadsOptions {
  /// If nonempty, also write the results here (atomically) as `{"scene", "steps",
  /// "threads": [1, 2], "phases": [{"phase", "seconds": [per thread count], "speedup": [per
  /// thread count, against the first]}], "identical": [per thread count: its physics columns
  /// equal the first's bit for bit]}`; the phase "step" is the whole step (stats.csv's total).
  std::filesystem::path json_path;
  std::vector<std::string> overrides;  ///< `--set key.path=value`, as load_scene
  int steps = 4;                       ///< steps per run (≥ 2); the first is a warm-up
  std::vector<int> threads = {1, 2};   ///< thread counts (each ≥ 1), the first the reference
};

/// stats.csv as its header and rows of fields (the text as written).
struct StatsCsv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};
/// @throws InputError naming the file if it cannot be read.
StatsCsv read_stats_csv(const std::filesystem::path& path);
/// Every phase column stats.csv can have (StatsWriter::phase_columns of each kind of run).
std::vector<std::string> all_phase_columns();
/// Whether column `name` holds seconds: one of `phases`, or a figure ending in "_s".
bool is_seconds_column(const std::string& name, const std::vector<std::string>& phases);

/// Run the benchmark and print its table to `out`; the process's thread count is restored
/// afterwards.
/// @throws InputError if the scene is static or an option is out of range; what run_scene's
///   result reports as a failed step, as an Error.
/// @return 0
int bench_threads(const std::filesystem::path& scene, const BenchThreadsOptions& opt,
                  std::ostream& out);

}  // namespace tetfsi::app
