#pragma once
/// @file bench_integrators.hpp
/// `tetfsi bench integrators`: the solid integrators side by side on undamped swings, to
/// choose the defaults by measurement (issue 21). For each scene (a dynamic, solid-only scene
/// with one deformable body), each step h in {dt, 2 dt} and each integrator
///   linearized/paper, linearized/midpoint [Chentanez06, Eqs. (4)-(5)], and the nonlinear
///   trapezoidal rule iterated by newton, modified_newton, bfgs [BatheSonnad80],
/// the scene runs from rest for its end time. The probe is the rest node closest to
/// (hi.x, c.y, c.z) of the body's rest box (a cantilever's tip). The period T is measured on
/// the reference run (newton at dt / 2) as the mean spacing of its tip's successive lowest
/// points; the amplitude of period k is the peak-to-peak of the tip's z-displacement over
/// [k T, (k + 1) T]. Printed per run: the amplitude of the last whole period over that of the
/// first ("A_last/A_1", 1 = no damping), the energy drift E(end) − E(0) and the largest
/// |E(t) − E(0)|, both over the reference's largest kinetic energy (E = kinetic + elastic +
/// gravity potential), the wall milliseconds per step and their ratio to linearized/paper at
/// the same h, and whether the run completed ("diverged at t" when |E − E(0)| exceeds 10 ×
/// the reference's kinetic energy, "failed at t: ..." when a step throws).
/// A two-way scene (`data/bench/swing_air.json`) runs the coupling schemes instead:
/// simultaneous/paper and simultaneous/midpoint (the simultaneous solve with either
/// linearised rule), newton and bfgs (the iterated coupled step, the nonlinear trapezoidal
/// rule); E adds the fluid's kinetic energy, the reference run (T, KE) is the bodies alone,
/// and "x paper" is against simultaneous/paper.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace tetfsi::app {

/// The default scenes (relative to the working folder): a soft cantilever's large swing
/// under gravity (nonlinear) and a stiff one's small oscillation (linear).
inline const char* const k_bench_integrator_scenes[] = {"data/bench/swing_large.json",
                                                        "data/bench/swing_linear.json"};

struct BenchIntegratorsOptions {
  /// If nonempty, also write the rows here (atomically) as `{"scenes": [{"scene", "dt",
  /// "period", "reference_kinetic_energy", "rows": [{"integrator", "dt", "periods",
  /// "amplitude_ratio", "energy_drift", "max_energy_error", "step_ms", "cost_vs_paper",
  /// "completed", "failure"}]}]}`; figures that do not exist are null.
  std::filesystem::path json_path;
  std::vector<std::string> overrides;  ///< `--set key.path=value`, applied to every scene
};

/// Run the benchmark on `scenes` and print one table per scene to `out`.
/// @throws InputError if a scene cannot be read, is static, has a fluid without two-way coupling,
/// has no deformable
///   body, or its reference run shows fewer than two periods.
/// @return 0
int bench_integrators(const std::vector<std::filesystem::path>& scenes,
                      const BenchIntegratorsOptions& opt, std::ostream& out);

}  // namespace tetfsi::app
