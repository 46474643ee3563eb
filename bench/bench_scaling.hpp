#pragma once
/// @file bench_scaling.hpp
/// `tetfsi bench scaling SCENE [--threads 1,2] [--ranks 1,2] [--steps N] [--repeat K]
/// [--json FILE] [--set K=V]`: the same steps of a scene run as separate processes at every (ranks,
/// threads) pair — `tetfsi run` itself, under `mpirun -np R` for R > 1 (core/ranks.hpp) — and, per
/// stats.csv phase and for the whole step, the mean seconds per step (the first step is a
/// warm-up and left out), the speed-up against the first pair and the parallel efficiency
/// (speed-up / (ranks x threads)). It also reports how far each run's physics (every stats.csv
/// column but the seconds, relative to the column's largest |value|) is from the first run's.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace tetfsi::app {

struct BenchScalingOptions {
  /// If nonempty, also write the results here (atomically) as `{"scene", "steps", "repeat",
  /// "cores", "runs": [{"ranks", "threads", "step_s_fastest", "step_s_slowest"}], "phases":
  /// [{"phase", "seconds": [per run], "speedup": [per run], "efficiency": [per run]}],
  /// "max_rel_difference": [per run], "identical": [per run]}`; the phase "step" is the whole step
  /// (stats.csv's total), its fastest and slowest round per run in "runs".
  std::filesystem::path json_path;
  std::vector<std::string> overrides;  ///< `--set key.path=value`, passed on to each run
  int steps = 4;                       ///< steps per run (≥ 2); the first is a warm-up
  std::vector<int> threads = {1, 2};   ///< thread counts (each ≥ 1)
  std::vector<int> ranks = {1};        ///< rank counts (each ≥ 1); > 1 needs mpirun
  int repeat = 1;  ///< rounds of every pair, one after another; seconds are medians over them
};

/// Run the benchmark (ranks outer, threads inner; the first pair is the reference) and print
/// its table to `out`.
/// @throws InputError if the scene is static, an option is out of range or mpirun is missing
///   for a rank count > 1; an Error naming the run and its error line if a run fails.
/// @return 0
int bench_scaling(const std::filesystem::path& scene, const BenchScalingOptions& opt,
                  std::ostream& out);

}  // namespace tetfsi::app
