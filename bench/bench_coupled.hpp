#pragma once
/// @file bench_coupled.hpp
/// `tetfsi bench coupled`: the two coupling schemes of a fluid scene side by side
/// (coupling/coupled_step.hpp), in one run:
///  (a) the largest stable step of each: the scene from its initial state for `time` seconds
///      at h = 2 dt, dt, dt/2, … (dt the scene's), from the largest down, stopping for a
///      scheme at its first stable step. A run is unstable when a step throws (tetfsi::Error:
///      a diverged solve, a non-finite state, a body leaving the box) or when the solid energy
///      E = kinetic + elastic exceeds the bound
///          E_max(h) = 10 · max(E₀, E_sim(h)),
///      E₀ the energy at t = 0 and E_sim(h) the largest E of the simultaneous run at the same
///      h if that run was stable (else 0; the simultaneous runs use 10 E₀ alone). The
///      simultaneous scheme is run at every h splitting is tried at, to give that reference.
///  (b) the mean wall seconds per step of each scheme at dt (the first step is a warm-up; a
///      run that fails times the steps it completed, at least 3);
///  (c) the coupled solve (coupling::solve_coupled, schur_amg, the bodies free) against the
///      fluid-only projection (fluid::project of the same v* with the bodies' velocities
///      held, a fresh solver of the scene's fluid kind at the coupled solve's tolerance) on
///      the mesh of the step after a few simultaneous steps at dt: best of 3 wall seconds each.
///      On the grid (fluid.discretization "grid") the same on the step's classified grid:
///      the grid's coupled solve (GridPredicted::solve, the scene's J form) against
///      fluid::grid_project — one AMG Poisson solve of the same grid.
/// It prints the figures against the goals: simultaneous stable at dt where splitting is not;
/// coupled solve ≤ 1.5 × the fluid-only one; simultaneous step ≤ 1.2 × a splitting step.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace tetfsi::app {

struct BenchCoupledOptions {
  /// If nonempty, also write the results here (atomically) as `{"scene", "dt", "time",
  /// "criterion", "initial_energy", "stable_dt": {"simultaneous", "splitting"} (s or null),
  /// "step_s": {"simultaneous", "splitting"} (s or null), "coupled_solve_s",
  /// "fluid_only_solve_s", "solve_ratio", "step_ratio", "runs": {"simultaneous": [{"h",
  /// "steps", "completed", "stable", "outcome", "max_energy", "bound"}], "splitting": [...]},
  /// "timing": {<scheme>: {"completed", "timed", "failed"}}, "solve": {"cells",
  /// "pressure_unknowns", "solid_unknowns", "coupled_iterations", "fluid_only_iterations",
  /// "fluid_only_groups"}, "goals": {...}}`.
  std::filesystem::path json_path;
  std::vector<std::string> overrides;  ///< `--set key.path=value`, as load_scene
  double time = 1.0;                   ///< simulated seconds of each stability run (> 0)
  int steps_down = 5;                  ///< halvings of 2 dt: h = 2 dt / 2^k, k = 0 … N (0 … 12)
  int timed_steps = 6;                 ///< (b): steps per scheme at dt, the first a warm-up (≥ 4)
  int warm_steps = 3;                  ///< (c): simultaneous steps before the solves (≥ 1)
};

/// Run the benchmark on a two-way fluid scene and print its table to `out`.
/// @throws InputError if the scene has no fluid or no deformable body, is static, starts with
///   zero solid energy (the bound is relative to it) or an option is out of range;
///   MeshError / SolverError if the scene cannot be meshed or (c)'s solves fail.
/// @return 0
int bench_coupled(const std::filesystem::path& scene, const BenchCoupledOptions& opt,
                  std::ostream& out);

}  // namespace tetfsi::app
