#pragma once
/// @file bench_bfgs.hpp
/// `tetfsi bench bfgs`: the seed's Table I [BatheSonnad80] for a scene. For h in {dt, R dt}
/// (dt the scene's) and each iteration method m in {bfgs, modified_newton, newton}, the scene
/// runs from its initial state for T seconds with
///   - coupling.scheme = m if it is two-way coupled (coupling/coupled_step.hpp: the fluid's
///     forces in the out-of-balance force; bfgs and modified_newton start from the bodies' own
///     matrix, the seed's Eq. (15)), else
///   - solid.integrator = m (solid/nonlinear_trapezoid.hpp; a one-way fluid does not act on
///     the bodies and is not run),
/// with the scene's solid.* tolerances (RTOL, ETOL, STOL, max_iterations, ...). Every step
/// records the equilibrium iterations (the seed's count: directions Δx computed), the
/// residual evaluations, its wall seconds, and the x-displacement and x-velocity of two probe
/// nodes of the first deformable body: A, the rest node closest to (lo.x, c.y, c.z) of the
/// body's rest bounding box lo..hi with centre c, and B, closest to (hi.x, c.y, c.z) (the
/// seed's Fig. 2 plots the x-velocities at A and B). A run stops at the first step that
/// throws (tetfsi::Error); a non-converged iteration is reported as "failed to converge in N
/// iterations at step k" (N = solid.max_iterations), anything else as "failed at step k: ...".
///
/// Printed: one row per (method, h): max and average iterations per step, converged or the
/// failure, evaluations and wall seconds per step; then the agreement of the x-displacement
/// histories of A and B, each the largest difference over the probes and the compared times
/// divided by the largest |d_x| of A and B in the histories compared, in percent against the
/// goal 1 %:
///   - same h: over every pair of converged methods at that h;
///   - across h: each method converged at R dt against the same method and against newton at
///     dt (interpolated linearly at the larger step's times);
/// and the goal of the seed's Table I: BFGS converges at R dt in at most 5 iterations per step.
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace tetfsi::app {

/// The default scene of `tetfsi bench bfgs` (relative to the working folder).
inline const char* const k_bench_bfgs_scene = "data/scenes/shell_step.json";

struct BenchBfgsOptions {
  /// If nonempty, also write the results here (atomically) as `{"scene", "mode" ("coupled" |
  /// "solid"), "dt", "ratio", "time", "tolerances": {"rtol", "etol", "stol",
  /// "max_iterations"}, "probes": {"body", "A": {"node", "rest"}, "B": {...}}, "rows":
  /// [{"method", "dt", "max_iterations", "avg_iterations", "converged", "step_s",
  /// "evaluations_per_step", "steps", "completed", "failure"}], "agreement": {"goal_percent",
  /// "same_dt": [{"dt", "methods", "percent", "max_difference", "scale", "worst", "met"}],
  /// "across_dt": [{"method", "dt", "reference", "reference_dt", "percent",
  /// "max_difference", "scale", "met"}]}, "goals": {"bfgs_at_most_5_iterations",
  /// "agreement_same_dt", "agreement_across_dt"}}`. A figure that does not exist (no step
  /// completed, fewer than two converged methods) is null; "failure" is null for a converged
  /// run; coupled rows also have "fluid_solves_per_step".
  std::filesystem::path json_path;
  /// If nonempty, also write every run's probe histories here (CSV, step 0 included):
  /// method, dt, step, t, dA_x, dB_x, uA_x, uB_x (s, m, m/s).
  std::filesystem::path history_path;
  std::vector<std::string> overrides;  ///< `--set key.path=value`, as load_scene
  double ratio = 10.0;                 ///< R: the larger step is R dt (> 1)
  std::optional<double> time;  ///< simulated seconds per run (> 0); unset: the scene's end time
};

/// Run the benchmark and print its table to `out`.
/// @throws InputError if the scene cannot be read, is static or has no deformable body, or an
///   option is out of range; MeshError if a two-way scene cannot be meshed at t = 0.
/// @return 0 (the goals are reported, not enforced)
int bench_bfgs(const std::filesystem::path& scene, const BenchBfgsOptions& opt, std::ostream& out);

}  // namespace tetfsi::app
