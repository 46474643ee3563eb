#pragma once
/// @file bench_solvers.hpp
/// `tetfsi bench solvers`: every linear solver backend on one 3D Poisson problem, timed,
/// with the ratio of each total (setup + solve) to the fastest in the same run.
#include <iosfwd>
#include <string>
#include <vector>

namespace tetfsi::app {

/// Benchmark linear solvers on the 7-point 3D Poisson matrix (core/test_problems.hpp) of an
/// m × m × m grid, m = round(∛n), with a fixed pseudo-random right-hand side in [−1, 1]
/// (seed 1), from x = 0, to relative residual 1e-8 (max 2000 iterations).
///
/// Prints a table (backend, setup s, solve s, total s, iterations, true relative residual,
/// converged, total / fastest converged total) to `out`. Without an explicit backend list,
/// `cholmod` and `umfpack` are skipped (with a note) above the sizes where they would take
/// more than about two minutes on this machine; named explicitly, they always run.
///
/// @param n          approximate number of unknowns (≥ 1)
/// @param json_path  if nonempty, write `{"n": N, "grid": m, "backends": [{"name", "setup_s",
///                   "solve_s", "iterations", "converged", "residual"}], "skipped": [{"name",
///                   "reason"}], "failed": [{"name", "error"}]}` there (N = m³)
/// @param backends   backend names as in `solver_names()`; empty = all
/// @param out        where the table goes
/// @return 0 if every backend that ran converged, 1 otherwise (a failure is also reported)
/// @throws InputError on n < 1, an unknown backend name or an unwritable json_path
int bench_solvers(int n, const std::string& json_path, const std::vector<std::string>& backends,
                  std::ostream& out);

}  // namespace tetfsi::app
