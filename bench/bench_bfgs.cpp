/// @file bench_bfgs.cpp
/// `tetfsi bench bfgs` (bench_bfgs.hpp).
#include "bench/bench_bfgs.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "coupling/simulation.hpp"
#include "io/output.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"

namespace tetfsi::app {

namespace {

using json = nlohmann::ordered_json;  // the keys in the documented order

/// The methods of the seed's Table I, in its order, then full Newton.
const std::vector<std::string>& methods() {
  static const std::vector<std::string> m = {"bfgs", "modified_newton", "newton"};
  return m;
}

constexpr double k_goal_percent = 1.0;     ///< agreement goal
constexpr int k_goal_bfgs_iterations = 5;  ///< Table I: BFGS at the larger step
/// Issue 21's goals with the fluid's added mass in the starting matrix: BFGS at the larger
/// step at most 4 iterations and 3 on average; modified Newton converging at the smaller one.
constexpr int k_goal_bfgs_max = 4;
constexpr double k_goal_bfgs_avg = 3.0;

struct Probe {
  Index node = 0;
  Vec3 rest = Vec3::Zero();
};

/// The x-displacement and x-velocity of the two probes after a step.
struct Sample {
  double t = 0.0, dA = 0.0, dB = 0.0, uA = 0.0, uB = 0.0;
};

/// One run of a method at step h from the scene's initial state.
struct Run {
  std::string method;
  double h = 0.0;
  int steps = 0;                                           ///< planned
  std::vector<int> iterations, evaluations, fluid_solves;  ///< per completed step
  std::vector<double> step_s;                              ///< wall seconds per completed step
  std::vector<Sample> history;                             ///< step 0, then every completed step
  std::string failure;                                     ///< empty if every step completed
  int completed() const { return static_cast<int>(iterations.size()); }
  bool converged() const { return failure.empty(); }
  int max_iterations() const {
    return iterations.empty() ? 0 : *std::max_element(iterations.begin(), iterations.end());
  }
  static double mean(const std::vector<int>& v) {
    double s = 0.0;
    for (int x : v) s += x;
    return v.empty() ? 0.0 : s / static_cast<double>(v.size());
  }
  double avg_iterations() const { return mean(iterations); }
  double evaluations_per_step() const { return mean(evaluations); }
  double fluid_solves_per_step() const { return mean(fluid_solves); }
  double mean_step_s() const {
    double s = 0.0;
    for (double x : step_s) s += x;
    return step_s.empty() ? 0.0 : s / static_cast<double>(step_s.size());
  }
};

/// Probe A (closest to (lo.x, c.y, c.z)) or B (closest to (hi.x, c.y, c.z)) of `rest`.
Probe find_probe(const MatX3& rest, bool high) {
  Probe p;
  p.node = end_node(rest, high);
  p.rest = rest.row(p.node).transpose();
  return p;
}

Sample sample(const solid::SolidBody& body, const Probe& a, const Probe& b, double t) {
  return {t, body.displacement(a.node, 0), body.displacement(b.node, 0), body.velocity(a.node, 0),
          body.velocity(b.node, 0)};
}

/// `steps` steps of `method` at h: coupled (coupling.scheme = method) or the bodies alone
/// (solid.integrator = method). Stops at the first step that throws.
Run run_method(const Scene& scene, const solid::SolidWorld& world0, bool coupled, size_t body,
               const Probe& a, const Probe& b, const std::string& method, double h, int steps) {
  Run r;
  r.method = method;
  r.h = h;
  r.steps = steps;
  solid::SolidWorld world0_copy = world0;
  if (!coupled) world0_copy.integrator = solid::parse_integrator(method);
  Scene sc = scene;
  if (coupled) sc.coupling->params.scheme = coupling::parse_scheme(method);
  coupling::FsiSimulation sim = coupled ? make_simulation(sc, std::move(world0_copy))
                                        : coupling::FsiSimulation(std::move(world0_copy));
  solid::SolidWorld& world = sim.world();
  PhaseTimes phases;
  sim.start(phases);  // a scene that cannot be meshed at t = 0 is an error
  r.history.push_back(sample(world.bodies[body], a, b, 0.0));
  for (int k = 1; k <= steps; ++k) {
    const double t0 = now_seconds();
    int iterations = 0, evaluations = 0, fluid_solves = 0;
    try {
      if (coupled) {
        const coupling::CoupledStepReport rep = *sim.step(h, phases).coupled;
        iterations = rep.equilibrium.iterations;
        evaluations = rep.equilibrium.evaluations;
        fluid_solves = rep.fluid_solves;
      } else {
        const solid::SolidStepReport rep = world.step(h, phases);
        iterations = rep.equilibrium_iterations;
        evaluations = rep.equilibrium_evaluations;
      }
    } catch (const InputError&) {
      throw;  // the scene cannot be run this way (e.g. a region sealed by a body)
    } catch (const Error& e) {
      const std::string what = e.what();
      if (what.find("did not converge in") != std::string::npos)
        r.failure = fmt::format("failed to converge in {} iterations at step {}",
                                scene.solid.equilibrium.max_iterations, k);
      else
        r.failure = one_line(fmt::format("failed at step {}: {}", k, what));
      logger().info("bench bfgs: {} at h = {:.6g} s: {}", method, h, one_line(what));
      break;
    }
    r.step_s.push_back(now_seconds() - t0);
    r.iterations.push_back(iterations);
    r.evaluations.push_back(evaluations);
    r.fluid_solves.push_back(fluid_solves);
    r.history.push_back(sample(world.bodies[body], a, b, k * h));
  }
  logger().info("bench bfgs: {} at h = {:.6g} s: {}/{} steps, {:.3g} iterations per step (max {})",
                method, h, r.completed(), steps, r.avg_iterations(), r.max_iterations());
  return r;
}

/// The probes' x-displacement at time t, linearly interpolated in a history; false if t is
/// past its end.
bool displacement_at(const std::vector<Sample>& hist, double h, double t, double& dA, double& dB) {
  const double s = t / h;
  const double last = static_cast<double>(hist.size() - 1);
  if (s > last + 1e-9) return false;
  const size_t i = static_cast<size_t>(std::clamp(std::floor(s + 1e-9), 0.0, last));
  if (static_cast<double>(i) >= last) {
    dA = hist.back().dA;
    dB = hist.back().dB;
    return true;
  }
  const double w = std::clamp(s - static_cast<double>(i), 0.0, 1.0);
  dA = (1 - w) * hist[i].dA + w * hist[i + 1].dA;
  dB = (1 - w) * hist[i].dB + w * hist[i + 1].dB;
  return true;
}

/// The largest |d_x| of A and B in a history.
double largest_displacement(const std::vector<Sample>& hist) {
  double m = 0.0;
  for (const Sample& s : hist) m = std::max({m, std::abs(s.dA), std::abs(s.dB)});
  return m;
}

/// max over the samples of `a` (times ≤ the end of `b`) and the probes of |a − b(t)|, b
/// interpolated at a's times; `probe` is set to "A" or "B", where it is largest.
double max_difference(const Run& a, const Run& b, const char*& probe) {
  double m = 0.0;
  probe = "A";
  for (const Sample& s : a.history) {
    double dA = 0.0, dB = 0.0;
    if (!displacement_at(b.history, b.h, s.t, dA, dB)) break;
    if (std::abs(s.dA - dA) > m) {
      m = std::abs(s.dA - dA);
      probe = "A";
    }
    if (std::abs(s.dB - dB) > m) {
      m = std::abs(s.dB - dB);
      probe = "B";
    }
  }
  return m;
}

/// 100 diff / scale; NaN if there is no scale (nothing moved) but a difference.
double percent(double diff, double scale) {
  if (scale > 0) return 100.0 * diff / scale;
  return diff == 0 ? 0.0 : std::numeric_limits<double>::quiet_NaN();
}

json number_or_null(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}

std::string percent_text(double p) {
  return std::isfinite(p) ? fmt::format("{:.3g} %", p) : std::string("n/a (no motion)");
}

const char* met(bool b) {
  return b ? "met" : "NOT met";
}

}  // namespace

/// The run of `method` at step h, or null; with `converged_only`, only if it converged.
const Run* find_run_of(const std::vector<Run>& runs, const std::string& method, double h,
                       bool converged_only) {
  for (const Run& r : runs)
    if (r.method == method && r.h == h && (!converged_only || r.converged())) return &r;
  return nullptr;
}
const Run* find_converged(const std::vector<Run>& runs, const std::string& method, double h) {
  return find_run_of(runs, method, h, true);
}

/// The iteration goals at the two steps, printed under "goals:".
struct IterationGoals {
  bool bfgs_5 = false;           ///< the seed's Table I: BFGS at most 5 iterations at R dt
  bool bfgs_4_3 = false;         ///< at most 4, and 3 on average, at R dt
  bool modified_newton = false;  ///< modified Newton converges at dt
};

IterationGoals iteration_goals(const std::vector<Run>& runs, double dt, double big,
                               std::ostream& out) {
  IterationGoals g;
  const Run* bfgs_big = find_converged(runs, "bfgs", big);
  g.bfgs_5 = bfgs_big && bfgs_big->max_iterations() <= k_goal_bfgs_iterations;
  fmt::print(out, "\ngoals:\n  BFGS at most {} iterations per step at dt = {:.4g} s: {} -> {}\n",
             k_goal_bfgs_iterations, big,
             bfgs_big ? fmt::format("at most {}", bfgs_big->max_iterations())
                      : std::string("did not converge"),
             met(g.bfgs_5));
  g.bfgs_4_3 = bfgs_big && bfgs_big->max_iterations() <= k_goal_bfgs_max &&
               bfgs_big->avg_iterations() <= k_goal_bfgs_avg;
  fmt::print(
      out,
      "  BFGS at most {} and on average at most {:.3g} iterations at dt = {:.4g} s: {} -> {}\n",
      k_goal_bfgs_max, k_goal_bfgs_avg, big,
      bfgs_big ? fmt::format("at most {}, {:.3g} on average", bfgs_big->max_iterations(),
                             bfgs_big->avg_iterations())
               : std::string("did not converge"),
      met(g.bfgs_4_3));
  const Run* mn_small = find_run_of(runs, "modified_newton", dt, false);
  g.modified_newton = mn_small && mn_small->converged();
  fmt::print(out, "  modified Newton converges at dt = {:.4g} s: {} -> {}\n", dt,
             !mn_small           ? std::string("not run")
             : g.modified_newton ? std::string("converged")
                                 : mn_small->failure,
             met(g.modified_newton));
  return g;
}

namespace {

/// What every run starts from: the scene, its bodies at t = 0, the probed body and its probes,
/// the two steps (dt and R dt) and the simulated seconds per run.
struct Setup {
  const Scene& scene;
  const solid::SolidWorld& world0;
  std::string name;  ///< the scene file
  size_t body = 0;   ///< the probed (first deformable) body
  bool coupled = false;
  double dt = 0.0, big = 0.0, time = 0.0;
  Probe a, b;
};

/// Every run in order (the methods at dt, then at R dt) and their rows' JSON.
struct Runs {
  std::vector<Run> runs;
  json rows = json::array();
};

/// The agreement of some comparisons: one JSON entry each, and whether all met the goal.
struct Agreement {
  json entries = json::array();
  bool met = true;
};

/// The largest difference over pairs of runs, and where it is ("a vs b at A").
struct Worst {
  double diff = 0.0;
  std::string where;
};

/// Rejects out-of-range options.
void check_options(const BenchBfgsOptions& opt) {
  TETFSI_REQUIRE(InputError, std::isfinite(opt.ratio) && opt.ratio > 1,
                 "bench bfgs: --ratio must be a number > 1 (the larger step is R dt), got {}",
                 opt.ratio);
  TETFSI_REQUIRE(InputError, !opt.time || (std::isfinite(*opt.time) && *opt.time > 0),
                 "bench bfgs: --time must be a positive number of seconds, got {}",
                 opt.time.value_or(0.0));
}

/// The set-up of a dynamic scene; throws if it has no deformable body to probe.
Setup make_setup(const Scene& scene, const solid::SolidWorld& world0, const std::string& name,
                 const BenchBfgsOptions& opt) {
  const size_t body = first_deformable_body(world0);
  TETFSI_REQUIRE(InputError, body < world0.bodies.size(),
                 "{}: bench bfgs needs a deformable (non-kinematic) body to probe", name);
  const bool coupled = scene.two_way();
  const double dt = scene.time.dt;
  const double big = opt.ratio * dt;
  const double time =
      opt.time ? *opt.time : scene.time.end_time.value_or(scene.time.num_steps() * dt);
  const solid::SolidBody& probed = world0.bodies[body];
  const Probe a = find_probe(probed.rest_positions(), false);
  const Probe b = find_probe(probed.rest_positions(), true);
  return Setup{scene, world0, name, body, coupled, dt, big, time, a, b};
}

/// The title, the tolerances, the probes and the column heads of the runs' table.
void print_header(const Setup& s, double ratio, std::ostream& out) {
  const Scene& scene = s.scene;
  const EquilibriumOptions& eq = scene.solid.equilibrium;
  const solid::SolidBody& probed = s.world0.bodies[s.body];
  fmt::print(out,
             "tetfsi bench bfgs: {} ('{}'), {}, dt = {:.6g} s and {:.6g} dt = {:.6g} s, "
             "{:.6g} s per run\n",
             s.name, scene.name,
             s.coupled ? "two-way coupled (coupling.scheme = method)"
                       : (scene.fluid ? "the bodies alone (solid.integrator = method; the one-way "
                                        "fluid does not act on them and is not run)"
                                      : "solid only (solid.integrator = method)"),
             s.dt, ratio, s.big, s.time);
  fmt::print(out,
             "RTOL {:.3g}, ETOL {:.3g}, STOL {:.3g}, at most {} iterations per step, line "
             "search {}, starting matrix per {}\n",
             eq.rtol, eq.etol, eq.stol, eq.max_iterations, eq.line_search ? "on" : "off",
             eq.keep_matrix ? "run" : "step");
  fmt::print(out, "probes of body '{}': A node {} at {}, B node {} at {} (rest)\n\n", probed.name(),
             s.a.node, fmt_vec(s.a.rest), s.b.node, fmt_vec(s.b.rest));
  fmt::print(out, "{:<16} {:>10} {:>6} {:>7} {:>10} {:>10}  {}\n", "method", "dt (s)", "max it",
             "avg it", "eval/step", "s/step", "converged");
  out.flush();
}

/// Prints a run's row of the table and returns its JSON row.
json report_run(const Run& r, bool coupled, std::ostream& out) {
  const bool any = r.completed() > 0;  // else no figure: "-"
  auto figure = [any](const char* f, double v) {
    return any ? fmt::format(fmt::runtime(f), v) : std::string("-");
  };
  fmt::print(out, "{:<16} {:>10.4g} {:>6} {:>7} {:>10} {:>10}  {}\n", r.method, r.h,
             figure("{:.0f}", r.max_iterations()), figure("{:.3g}", r.avg_iterations()),
             figure("{:.3g}", r.evaluations_per_step()), figure("{:.4g}", r.mean_step_s()),
             r.converged() ? std::string("yes") : r.failure);
  out.flush();
  json row = {{"method", r.method},
              {"dt", r.h},
              {"max_iterations", any ? json(r.max_iterations()) : json(nullptr)},
              {"avg_iterations", any ? json(r.avg_iterations()) : json(nullptr)},
              {"converged", r.converged()},
              {"step_s", any ? json(r.mean_step_s()) : json(nullptr)},
              {"evaluations_per_step", any ? json(r.evaluations_per_step()) : json(nullptr)},
              {"steps", r.steps},
              {"completed", r.completed()},
              {"failure", r.converged() ? json(nullptr) : json(r.failure)}};
  if (coupled) row["fluid_solves_per_step"] = any ? json(r.fluid_solves_per_step()) : json(nullptr);
  return row;
}

/// Every method at dt, then at R dt, each run's row printed as it ends.
Runs run_all(const Setup& s, std::ostream& out) {
  Runs all;
  for (const double h : {s.dt, s.big}) {
    const int steps = static_cast<int>(std::ceil(s.time / h - 1e-9));
    for (const std::string& m : methods()) {
      Run r = run_method(s.scene, s.world0, s.coupled, s.body, s.a, s.b, m, h, steps);
      all.rows.push_back(report_run(r, s.coupled, out));
      all.runs.push_back(std::move(r));
    }
  }
  return all;
}

/// The largest difference over every pair of the runs `ok` (at least two).
Worst worst_pair(const std::vector<const Run*>& ok) {
  Worst w;
  for (size_t i = 0; i < ok.size(); ++i) {
    for (size_t k = i + 1; k < ok.size(); ++k) {
      const char* probe = "A";
      const double d = max_difference(*ok[i], *ok[k], probe);
      if (d > w.diff || w.where.empty()) {
        w.diff = std::max(w.diff, d);
        w.where = fmt::format("{} vs {} at {}", ok[i]->method, ok[k]->method, probe);
      }
    }
  }
  return w;
}

/// Appends the agreement of the methods converged at step h (and prints it) to `agg`.
void agree_at(const std::vector<Run>& runs, double h, Agreement& agg, std::ostream& out) {
  std::vector<const Run*> ok;
  for (const std::string& m : methods())
    if (const Run* r = find_converged(runs, m, h)) ok.push_back(r);
  json e = {{"dt", h}, {"methods", json::array()}};
  for (const Run* r : ok) e["methods"].push_back(r->method);
  if (ok.size() < 2) {
    fmt::print(out, "  dt = {:.4g} s: fewer than two converged methods -> NOT met\n", h);
    e.update({{"percent", nullptr},
              {"max_difference", nullptr},
              {"scale", nullptr},
              {"worst", nullptr},
              {"met", false}});
    agg.met = false;
    agg.entries.push_back(e);
    return;
  }
  double scale = 0.0;
  for (const Run* r : ok) scale = std::max(scale, largest_displacement(r->history));
  const Worst w = worst_pair(ok);
  const double diff = w.diff;
  const double p = percent(diff, scale);
  const bool m = std::isfinite(p) && p <= k_goal_percent;
  agg.met = agg.met && m;
  std::string list;
  for (const Run* r : ok) list += (list.empty() ? "" : ", ") + r->method;
  fmt::print(out, "  dt = {:.4g} s, {}: {} ({}; {:.3g} m of {:.3g} m) -> {}\n", h, list,
             percent_text(p), w.where, diff, scale, met(m));
  e.update({{"percent", number_or_null(p)},
            {"max_difference", diff},
            {"scale", scale},
            {"worst", w.where},
            {"met", m}});
  agg.entries.push_back(e);
}

/// The agreement of the converged methods with each other at each step, printed.
Agreement agreement_same_dt(const std::vector<Run>& runs, const Setup& s, std::ostream& out) {
  fmt::print(out,
             "\nagreement of the x-displacements of A and B (largest difference / largest "
             "|d_x| of A and B; goal <= {:.3g} %):\n",
             k_goal_percent);
  Agreement agg;
  for (const double h : {s.dt, s.big}) agree_at(runs, h, agg, out);
  return agg;
}

/// Appends the agreement of `m` at R dt with `ref` at dt (and prints it) to `agg`; false if
/// either did not converge.
bool agree_across(const std::vector<Run>& runs, const std::string& m, const std::string& ref,
                  const Setup& s, Agreement& agg, std::ostream& out) {
  const Run* r = find_converged(runs, m, s.big);
  const Run* sr = find_converged(runs, ref, s.dt);
  json e = {{"method", m}, {"dt", s.big}, {"reference", ref}, {"reference_dt", s.dt}};
  if (!r || !sr) {
    fmt::print(
        out, "    {} vs {}: n/a ({} did not converge)\n", m, ref,
        !r ? fmt::format("{} at {:.4g} s", m, s.big) : fmt::format("{} at {:.4g} s", ref, s.dt));
    e.update(
        {{"percent", nullptr}, {"max_difference", nullptr}, {"scale", nullptr}, {"met", false}});
    agg.met = false;
    agg.entries.push_back(e);
    return false;
  }
  const char* probe = "A";
  const double diff = max_difference(*r, *sr, probe);
  const double scale =
      std::max(largest_displacement(r->history), largest_displacement(sr->history));
  const double p = percent(diff, scale);
  const bool ok = std::isfinite(p) && p <= k_goal_percent;
  agg.met = agg.met && ok;
  fmt::print(out, "    {} vs {}: {} (at {}; {:.3g} m of {:.3g} m) -> {}\n", m, ref, percent_text(p),
             probe, diff, scale, met(ok));
  e.update(
      {{"percent", number_or_null(p)}, {"max_difference", diff}, {"scale", scale}, {"met", ok}});
  agg.entries.push_back(e);
  return true;
}

/// The agreement of each method at R dt with itself and with newton at dt, printed; not met
/// if no comparison could be made.
Agreement agreement_across_dt(const std::vector<Run>& runs, const Setup& s, std::ostream& out) {
  fmt::print(out, "  {:.4g} s against {:.4g} s at the larger step's times:\n", s.big, s.dt);
  Agreement agg;
  bool any_across = false;
  for (const std::string& m : methods()) {
    std::vector<std::string> refs = {m};  // the same method, and newton (once for newton)
    if (m != "newton") refs.push_back("newton");
    for (const std::string& ref : refs)
      any_across = agree_across(runs, m, ref, s, agg, out) || any_across;
  }
  agg.met = agg.met && any_across;
  return agg;
}

/// Writes every run's probe histories to `path` (CSV, atomically).
void write_history(const std::filesystem::path& path, const std::vector<Run>& runs) {
  std::string csv = "method,dt,step,t,dA_x,dB_x,uA_x,uB_x\n";
  for (const Run& r : runs) {
    for (size_t k = 0; k < r.history.size(); ++k) {
      const Sample& s = r.history[k];
      csv += fmt::format("{},{:.17g},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", r.method, r.h,
                         k, s.t, s.dA, s.dB, s.uA, s.uB);
    }
  }
  write_text_file_atomic(path, csv);
}

/// A probe's node and rest position as JSON.
json probe_json(const Probe& p) {
  return json{{"node", p.node}, {"rest", {p.rest.x(), p.rest.y(), p.rest.z()}}};
}

/// Writes the results as JSON to `path` (atomically).
void write_json(const std::filesystem::path& path, const Setup& s, double ratio, const json& rows,
                const Agreement& same, const Agreement& across, const IterationGoals& goals) {
  const EquilibriumOptions& eq = s.scene.solid.equilibrium;
  const json j{
      {"scene", s.scene.name},
      {"mode", s.coupled ? "coupled" : "solid"},
      {"dt", s.dt},
      {"ratio", ratio},
      {"time", s.time},
      {"tolerances",
       {{"rtol", eq.rtol},
        {"etol", eq.etol},
        {"stol", eq.stol},
        {"max_iterations", eq.max_iterations}}},
      {"probes",
       {{"body", s.world0.bodies[s.body].name()}, {"A", probe_json(s.a)}, {"B", probe_json(s.b)}}},
      {"rows", rows},
      {"agreement",
       {{"goal_percent", k_goal_percent},
        {"same_dt", same.entries},
        {"across_dt", across.entries}}},
      {"goals",
       {{"bfgs_at_most_5_iterations", goals.bfgs_5},
        {"bfgs_at_most_4_average_3", goals.bfgs_4_3},
        {"modified_newton_converges_at_dt", goals.modified_newton},
        {"agreement_same_dt", same.met},
        {"agreement_across_dt", across.met}}}};
  write_text_file_atomic(path, j.dump(2) + "\n");
}

}  // namespace

int bench_bfgs(const std::filesystem::path& scene_file, const BenchBfgsOptions& opt,
               std::ostream& out) {
  check_options(opt);
  const Scene scene = load_scene(scene_file, opt.overrides);
  const std::string name = scene_file.string();
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "{}: bench bfgs needs a dynamic scene (mode is 'static')", name);
  const solid::SolidWorld world0 = build_world(scene);
  const Setup s = make_setup(scene, world0, name, opt);
  print_header(s, opt.ratio, out);

  const Runs all = run_all(s, out);
  const Agreement same = agreement_same_dt(all.runs, s, out);
  const Agreement across = agreement_across_dt(all.runs, s, out);
  const IterationGoals goals = iteration_goals(all.runs, s.dt, s.big, out);
  fmt::print(out, "  agreement within {:.3g} % at each dt -> {}\n", k_goal_percent, met(same.met));
  fmt::print(out, "  agreement within {:.3g} % across the two dts -> {}\n", k_goal_percent,
             met(across.met));

  if (!opt.history_path.empty()) write_history(opt.history_path, all.runs);
  if (!opt.json_path.empty())
    write_json(opt.json_path, s, opt.ratio, all.rows, same, across, goals);
  return 0;
}

}  // namespace tetfsi::app
