/// @file bench_bfgs.cpp
/// `tetfsi bench bfgs` (bench_bfgs.hpp).
#include "tools/bench_bfgs.hpp"

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
#include "tools/output.hpp"
#include "tools/run.hpp"
#include "tools/scene.hpp"

namespace tetfsi::tools {

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

int bench_bfgs(const std::filesystem::path& scene_file, const BenchBfgsOptions& opt,
               std::ostream& out) {
  TETFSI_REQUIRE(InputError, std::isfinite(opt.ratio) && opt.ratio > 1,
                 "bench bfgs: --ratio must be a number > 1 (the larger step is R dt), got {}",
                 opt.ratio);
  TETFSI_REQUIRE(InputError, !opt.time || (std::isfinite(*opt.time) && *opt.time > 0),
                 "bench bfgs: --time must be a positive number of seconds, got {}",
                 opt.time.value_or(0.0));
  const Scene scene = load_scene(scene_file, opt.overrides);
  const std::string name = scene_file.string();
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "{}: bench bfgs needs a dynamic scene (mode is 'static')", name);
  const solid::SolidWorld world0 = build_world(scene);
  const size_t body = first_deformable_body(world0);
  TETFSI_REQUIRE(InputError, body < world0.bodies.size(),
                 "{}: bench bfgs needs a deformable (non-kinematic) body to probe", name);
  const bool coupled = scene.two_way();
  const double dt = scene.time.dt;
  const double big = opt.ratio * dt;
  const double time =
      opt.time ? *opt.time : scene.time.end_time.value_or(scene.time.num_steps() * dt);
  const EquilibriumOptions& eq = scene.solid.equilibrium;
  const solid::SolidBody& probed = world0.bodies[body];
  const Probe a = find_probe(probed.rest_positions(), false);
  const Probe b = find_probe(probed.rest_positions(), true);

  fmt::print(out,
             "tetfsi bench bfgs: {} ('{}'), {}, dt = {:.6g} s and {:.6g} dt = {:.6g} s, "
             "{:.6g} s per run\n",
             name, scene.name,
             coupled ? "two-way coupled (coupling.scheme = method)"
                     : (scene.fluid ? "the bodies alone (solid.integrator = method; the one-way "
                                      "fluid does not act on them and is not run)"
                                    : "solid only (solid.integrator = method)"),
             dt, opt.ratio, big, time);
  fmt::print(out,
             "RTOL {:.3g}, ETOL {:.3g}, STOL {:.3g}, at most {} iterations per step, line "
             "search {}, starting matrix per {}\n",
             eq.rtol, eq.etol, eq.stol, eq.max_iterations, eq.line_search ? "on" : "off",
             eq.keep_matrix ? "run" : "step");
  fmt::print(out, "probes of body '{}': A node {} at {}, B node {} at {} (rest)\n\n", probed.name(),
             a.node, fmt_vec(a.rest), b.node, fmt_vec(b.rest));
  fmt::print(out, "{:<16} {:>10} {:>6} {:>7} {:>10} {:>10}  {}\n", "method", "dt (s)", "max it",
             "avg it", "eval/step", "s/step", "converged");
  out.flush();

  std::vector<Run> runs;
  json rows = json::array();
  for (const double h : {dt, big}) {
    const int steps = static_cast<int>(std::ceil(time / h - 1e-9));
    for (const std::string& m : methods()) {
      Run r = run_method(scene, world0, coupled, body, a, b, m, h, steps);
      const bool any = r.completed() > 0;  // else no figure: "-"
      auto figure = [any](const char* f, double v) {
        return any ? fmt::format(fmt::runtime(f), v) : std::string("-");
      };
      fmt::print(out, "{:<16} {:>10.4g} {:>6} {:>7} {:>10} {:>10}  {}\n", m, h,
                 figure("{:.0f}", r.max_iterations()), figure("{:.3g}", r.avg_iterations()),
                 figure("{:.3g}", r.evaluations_per_step()), figure("{:.4g}", r.mean_step_s()),
                 r.converged() ? std::string("yes") : r.failure);
      out.flush();
      json row = {{"method", m},
                  {"dt", h},
                  {"max_iterations", any ? json(r.max_iterations()) : json(nullptr)},
                  {"avg_iterations", any ? json(r.avg_iterations()) : json(nullptr)},
                  {"converged", r.converged()},
                  {"step_s", any ? json(r.mean_step_s()) : json(nullptr)},
                  {"evaluations_per_step", any ? json(r.evaluations_per_step()) : json(nullptr)},
                  {"steps", steps},
                  {"completed", r.completed()},
                  {"failure", r.converged() ? json(nullptr) : json(r.failure)}};
      if (coupled)
        row["fluid_solves_per_step"] = any ? json(r.fluid_solves_per_step()) : json(nullptr);
      rows.push_back(row);
      runs.push_back(std::move(r));
    }
  }
  auto find_run = [&](const std::string& m, double h) { return find_converged(runs, m, h); };

  fmt::print(out,
             "\nagreement of the x-displacements of A and B (largest difference / largest "
             "|d_x| of A and B; goal <= {:.3g} %):\n",
             k_goal_percent);
  json same = json::array();
  bool same_met = true;
  for (const double h : {dt, big}) {
    std::vector<const Run*> ok;
    for (const std::string& m : methods())
      if (const Run* r = find_run(m, h)) ok.push_back(r);
    json e = {{"dt", h}, {"methods", json::array()}};
    for (const Run* r : ok) e["methods"].push_back(r->method);
    if (ok.size() < 2) {
      fmt::print(out, "  dt = {:.4g} s: fewer than two converged methods -> NOT met\n", h);
      e.update({{"percent", nullptr},
                {"max_difference", nullptr},
                {"scale", nullptr},
                {"worst", nullptr},
                {"met", false}});
      same_met = false;
      same.push_back(e);
      continue;
    }
    double scale = 0.0, diff = 0.0;
    std::string worst;
    for (const Run* r : ok) scale = std::max(scale, largest_displacement(r->history));
    for (size_t i = 0; i < ok.size(); ++i) {
      for (size_t k = i + 1; k < ok.size(); ++k) {
        const char* probe = "A";
        const double d = max_difference(*ok[i], *ok[k], probe);
        if (d > diff || worst.empty()) {
          diff = std::max(diff, d);
          worst = fmt::format("{} vs {} at {}", ok[i]->method, ok[k]->method, probe);
        }
      }
    }
    const double p = percent(diff, scale);
    const bool m = std::isfinite(p) && p <= k_goal_percent;
    same_met = same_met && m;
    std::string list;
    for (const Run* r : ok) list += (list.empty() ? "" : ", ") + r->method;
    fmt::print(out, "  dt = {:.4g} s, {}: {} ({}; {:.3g} m of {:.3g} m) -> {}\n", h, list,
               percent_text(p), worst, diff, scale, met(m));
    e.update({{"percent", number_or_null(p)},
              {"max_difference", diff},
              {"scale", scale},
              {"worst", worst},
              {"met", m}});
    same.push_back(e);
  }

  fmt::print(out, "  {:.4g} s against {:.4g} s at the larger step's times:\n", big, dt);
  json across = json::array();
  bool across_met = true;
  bool any_across = false;
  for (const std::string& m : methods()) {
    const Run* r = find_run(m, big);
    std::vector<std::string> refs = {m};  // the same method, and newton (once for newton)
    if (m != "newton") refs.push_back("newton");
    for (const std::string& ref : refs) {
      const Run* s = find_run(ref, dt);
      json e = {{"method", m}, {"dt", big}, {"reference", ref}, {"reference_dt", dt}};
      if (!r || !s) {
        fmt::print(
            out, "    {} vs {}: n/a ({} did not converge)\n", m, ref,
            !r ? fmt::format("{} at {:.4g} s", m, big) : fmt::format("{} at {:.4g} s", ref, dt));
        e.update({{"percent", nullptr},
                  {"max_difference", nullptr},
                  {"scale", nullptr},
                  {"met", false}});
        across_met = false;
        across.push_back(e);
        continue;
      }
      any_across = true;
      const char* probe = "A";
      const double diff = max_difference(*r, *s, probe);
      const double scale =
          std::max(largest_displacement(r->history), largest_displacement(s->history));
      const double p = percent(diff, scale);
      const bool ok = std::isfinite(p) && p <= k_goal_percent;
      across_met = across_met && ok;
      fmt::print(out, "    {} vs {}: {} (at {}; {:.3g} m of {:.3g} m) -> {}\n", m, ref,
                 percent_text(p), probe, diff, scale, met(ok));
      e.update({{"percent", number_or_null(p)},
                {"max_difference", diff},
                {"scale", scale},
                {"met", ok}});
      across.push_back(e);
    }
  }
  across_met = across_met && any_across;

  const IterationGoals goals = iteration_goals(runs, dt, big, out);
  fmt::print(out, "  agreement within {:.3g} % at each dt -> {}\n", k_goal_percent, met(same_met));
  fmt::print(out, "  agreement within {:.3g} % across the two dts -> {}\n", k_goal_percent,
             met(across_met));

  if (!opt.history_path.empty()) {
    std::string csv = "method,dt,step,t,dA_x,dB_x,uA_x,uB_x\n";
    for (const Run& r : runs) {
      for (size_t k = 0; k < r.history.size(); ++k) {
        const Sample& s = r.history[k];
        csv += fmt::format("{},{:.17g},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", r.method, r.h,
                           k, s.t, s.dA, s.dB, s.uA, s.uB);
      }
    }
    write_text_file_atomic(opt.history_path, csv);
  }
  if (!opt.json_path.empty()) {
    auto probe_json = [](const Probe& p) {
      return json{{"node", p.node}, {"rest", {p.rest.x(), p.rest.y(), p.rest.z()}}};
    };
    const json j{
        {"scene", scene.name},
        {"mode", coupled ? "coupled" : "solid"},
        {"dt", dt},
        {"ratio", opt.ratio},
        {"time", time},
        {"tolerances",
         {{"rtol", eq.rtol},
          {"etol", eq.etol},
          {"stol", eq.stol},
          {"max_iterations", eq.max_iterations}}},
        {"probes", {{"body", probed.name()}, {"A", probe_json(a)}, {"B", probe_json(b)}}},
        {"rows", rows},
        {"agreement", {{"goal_percent", k_goal_percent}, {"same_dt", same}, {"across_dt", across}}},
        {"goals",
         {{"bfgs_at_most_5_iterations", goals.bfgs_5},
          {"bfgs_at_most_4_average_3", goals.bfgs_4_3},
          {"modified_newton_converges_at_dt", goals.modified_newton},
          {"agreement_same_dt", same_met},
          {"agreement_across_dt", across_met}}}};
    write_text_file_atomic(opt.json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace tetfsi::tools
