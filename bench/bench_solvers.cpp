#include "bench/bench_solvers.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numeric>
#include <ostream>
#include <random>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/test_problems.hpp"
#include "core/timer.hpp"

namespace tetfsi::app {

namespace {

/// Largest unknown counts at which the direct solvers stay under ~2 minutes here
/// (3D Poisson, OpenBLAS, OPENBLAS_NUM_THREADS=1, with other jobs running: CHOLMOD 10 s
/// at 250k and 35 s CPU / 57 s wall at 512k, growing like n^1.8; UMFPACK 60–90 s at 250k).
constexpr long long k_cholmod_auto_max = 800'000;
constexpr long long k_umfpack_auto_max = 300'000;

struct Row {
  std::string name;
  SolveReport rep;
};

/// The 3D Poisson problem of an m × m × m grid with its pseudo-random right-hand side.
struct Problem {
  int m = 0;
  SparseMatrix A;
  VecX b;
  long long rows() const { return A.rows(); }
};

/// What the backends gave: the rows of those that solved, those skipped and those that threw.
struct Results {
  std::vector<Row> rows;
  nlohmann::json skipped = nlohmann::json::array(), failed = nlohmann::json::array();
};

/// The table as JSON rows, and whether every backend that ran converged.
struct Table {
  nlohmann::json rows = nlohmann::json::array();
  bool all_converged = true;
};

/// Builds the problem of about n unknowns (m = round(∛n)) and prints its line.
Problem make_problem(int n, std::ostream& out) {
  Problem p;
  p.m = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(n)))));
  const int m = p.m;
  const double t_build = now_seconds();
  p.A = poisson3d(m, m, m);
  const long long N = p.A.rows();
  p.b.resize(N);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (auto& v : p.b) v = uniform(rng);
  out << fmt::format(
      "3D Poisson, {0} x {0} x {0} grid: {1} unknowns, {2} nonzeros (built in "
      "{3:.2f} s); rhs uniform in [-1, 1], x0 = 0, rel_tol 1e-8\n",
      m, N, p.A.nonZeros(), now_seconds() - t_build);
  return p;
}

/// The largest unknown count at which a backend runs when it is not named explicitly.
long long auto_limit(SolverKind kind) {
  return kind == SolverKind::Cholmod || kind == SolverKind::Mumps || kind == SolverKind::SuperluDist
             ? k_cholmod_auto_max
         : kind == SolverKind::Umfpack ? k_umfpack_auto_max
                                       : std::numeric_limits<long long>::max();
}

/// Solves the problem with backend `name` into a row of `res`, or records its failure.
void run_backend(const std::string& name, SolverKind kind, const Problem& p,
                 const SolverOptions& opts, Results& res, std::ostream& out) {
  const long long N = p.rows();
  const int m = p.m;
  try {
    const double t_make = now_seconds();
    auto solver = make_linear_solver(kind, opts);
    const double init_s = now_seconds() - t_make;
    if (init_s > 0.01)  // amg/amg_gamg: PETSc and MPI start once per process
      out << fmt::format("{}: one-time start-up {:.2f} s (not in the table)\n", name, init_s);
    // poisson3d numbers its m³ grid x fastest, as the structured backend (pfmg) reads it
    GridLayout layout{{m, m, m}, std::vector<Index>(static_cast<std::size_t>(p.A.rows()))};
    std::iota(layout.cells.begin(), layout.cells.end(), Index{0});
    solver->set_grid(layout);
    solver->setup(p.A);
    VecX x = VecX::Zero(N);
    res.rows.push_back({name, solver->solve(p.b, x)});
  } catch (const Error& e) {
    std::string msg = e.what();
    if (!msg.starts_with(name + ":")) msg = fmt::format("{}: {}", name, msg);
    out << fmt::format("failed: {}\n", msg);
    res.failed.push_back({{"name", name}, {"error", msg}});
  }
}

/// Runs every backend of `names` in order, skipping the slow direct ones on large problems
/// unless the list is explicit.
Results run_backends(const std::vector<std::string>& names, bool explicit_list, const Problem& p,
                     const SolverOptions& opts, std::ostream& out) {
  const long long N = p.rows();
  Results res;
  for (const auto& name : names) {
    const SolverKind kind = parse_solver_kind(name);
    const long long limit = auto_limit(kind);
    if (!explicit_list && N > limit) {
      const std::string why = fmt::format(
          "skipped above {} unknowns (would take over ~2 min); name it to run it", limit);
      out << fmt::format("{}: {}\n", name, why);
      res.skipped.push_back({{"name", name}, {"reason", why}});
      continue;
    }
    logger().info("bench solvers: {} on {} unknowns", name, N);
    run_backend(name, kind, p, opts, res, out);
  }
  return res;
}

/// Prints the table of the rows (total against the fastest converged one) and returns it as
/// JSON; a failed backend counts as not converged.
Table print_table(const Results& res, std::ostream& out) {
  double fastest = std::numeric_limits<double>::infinity();
  for (const auto& r : res.rows)
    if (r.rep.converged) fastest = std::min(fastest, r.rep.setup_s + r.rep.solve_s);
  out << fmt::format("{:<14} {:>9} {:>9} {:>9} {:>6} {:>10} {:>9} {:>9}\n", "backend", "setup s",
                     "solve s", "total s", "iters", "residual", "converged", "x fastest");
  Table t;
  t.all_converged = res.failed.empty();
  for (const auto& r : res.rows) {
    const double total = r.rep.setup_s + r.rep.solve_s;
    t.all_converged = t.all_converged && r.rep.converged;
    out << fmt::format("{:<14} {:>9.3f} {:>9.3f} {:>9.3f} {:>6} {:>10.2e} {:>9} {:>9}\n", r.name,
                       r.rep.setup_s, r.rep.solve_s, total, r.rep.iterations, r.rep.residual,
                       r.rep.converged ? "yes" : "NO",
                       std::isfinite(fastest) ? fmt::format("{:.1f}", total / fastest) : "-");
    t.rows.push_back({{"name", r.name},
                      {"setup_s", r.rep.setup_s},
                      {"solve_s", r.rep.solve_s},
                      {"iterations", r.rep.iterations},
                      {"converged", r.rep.converged},
                      {"residual", std::isfinite(r.rep.residual) ? nlohmann::json(r.rep.residual)
                                                                 : nlohmann::json()}});
  }
  return t;
}

}  // namespace

int bench_solvers(int n, const std::string& json_path, const std::vector<std::string>& backends,
                  std::ostream& out) {
  TETFSI_REQUIRE(InputError, n >= 1, "bench solvers: need n ≥ 1 unknowns, got {}", n);
  const bool explicit_list = !backends.empty();
  const std::vector<std::string> names = explicit_list ? backends : solver_names();
  for (const auto& name : names) parse_solver_kind(name);  // reject unknown names up front
  std::ofstream json_file;
  if (!json_path.empty()) {
    json_file.open(json_path);
    TETFSI_REQUIRE(InputError, json_file.good(), "bench solvers: cannot write '{}'", json_path);
  }

  const Problem p = make_problem(n, out);
  SolverOptions opts;
  opts.rel_tol = 1e-8;
  opts.max_iterations = 2000;
  opts.symmetric = true;

  const Results res = run_backends(names, explicit_list, p, opts, out);
  const Table t = print_table(res, out);
  if (json_file.is_open()) {
    const nlohmann::json j = {{"n", p.rows()},           {"grid", p.m},
                              {"rel_tol", opts.rel_tol}, {"backends", t.rows},
                              {"skipped", res.skipped},  {"failed", res.failed}};
    json_file << j.dump(2) << '\n';
    TETFSI_REQUIRE(InputError, json_file.good(), "bench solvers: writing '{}' failed", json_path);
  }
  return t.all_converged ? 0 : 1;
}

}  // namespace tetfsi::app
