/// @file bench_integrators.cpp
/// `tetfsi bench integrators` (bench_integrators.hpp).
#include "bench/bench_integrators.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "io/output.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"

namespace tetfsi::app {

namespace {

using json = nlohmann::ordered_json;

/// The integrators compared: the linearized rule's two variants, then the iterated ones.
const std::vector<std::string> k_integrators = {"paper", "midpoint", "newton", "modified_newton",
                                                "bfgs"};

/// Two-way scenes: the coupling schemes, the simultaneous one with either linearised rule.
const std::vector<std::string> k_schemes = {"simultaneous/paper", "simultaneous/midpoint", "newton",
                                            "bfgs"};

std::string label(const std::string& integrator) {
  if (integrator == "paper" || integrator == "midpoint") return "linearized/" + integrator;
  return integrator;
}

/// The first row of a table, the cost reference ("x paper").
bool is_paper(const std::string& m) {
  return m == "paper" || m == "simultaneous/paper";
}

struct Run {
  std::string integrator;
  double h = 0;
  std::vector<double> t, z, energy, kinetic;
  double wall_s = 0;
  std::string failure;
  int steps() const { return static_cast<int>(t.size()) - 1; }
};

double world_energy(const solid::SolidWorld& w, double& kinetic) {
  kinetic = 0;
  double e = 0;
  for (const solid::SolidBody& b : w.bodies) {
    kinetic += b.kinetic_energy();
    e += b.kinetic_energy() + b.elastic_energy() + b.gravity_potential(w.gravity);
  }
  return e;
}

/// One sample; `fluid_ke` (J) is added to the energy (two-way runs: the fluid's kinetic energy).
void record(const solid::SolidWorld& w, size_t body, Index tip, double t, Run& r,
            double fluid_ke = 0.0) {
  double ke = 0;
  r.t.push_back(t);
  r.z.push_back(w.bodies[body].displacement(tip, 2));
  r.energy.push_back(world_energy(w, ke) + fluid_ke);
  r.kinetic.push_back(ke);
}

/// One run of `integrator` at h to `end`; stops when a step throws or |E − E(0)| exceeds
/// `bound` (if > 0).
Run run_integrator(const solid::SolidWorld& world0, size_t body, Index tip,
                   const std::string& integrator, double h, double end, double bound) {
  Run r;
  r.integrator = integrator;
  r.h = h;
  solid::SolidWorld w = world0;
  if (integrator == "paper" || integrator == "midpoint") {
    w.integrator = solid::Integrator::Linearized;
    w.trapezoid = solid::parse_trapezoid(integrator);
  } else {
    w.integrator = solid::parse_integrator(integrator);
  }
  PhaseTimes phases;
  record(w, body, tip, 0.0, r);
  const int steps = static_cast<int>(std::ceil(end / h - 1e-9));
  const double t0 = now_seconds();
  for (int k = 1; k <= steps; ++k) {
    try {
      w.step(h, phases);
    } catch (const Error& e) {
      r.failure = one_line(fmt::format("failed at t = {:.4g} s: {}", k * h, e.what()));
      break;
    }
    record(w, body, tip, k * h, r);
    if (bound > 0 && std::abs(r.energy.back() - r.energy.front()) > bound) {
      r.failure = fmt::format("diverged at t = {:.4g} s", k * h);
      break;
    }
  }
  r.wall_s = now_seconds() - t0;
  logger().info("bench integrators: {} at h = {:.4g} s: {} steps in {:.3g} s{}", label(integrator),
                h, r.steps(), r.wall_s, r.failure.empty() ? "" : ": " + r.failure);
  return r;
}

/// One two-way run of `scheme` (k_schemes) at h to `end`, as run_integrator; the energy adds
/// the fluid's kinetic energy.
Run run_coupled(const Scene& scene, const solid::SolidWorld& world0, size_t body, Index tip,
                const std::string& scheme, double h, double end, double bound) {
  Run r;
  r.integrator = scheme;
  r.h = h;
  Scene sc = scene;
  solid::SolidWorld w = world0;
  const std::string prefix = "simultaneous/";
  if (scheme.rfind(prefix, 0) == 0) {
    sc.coupling->params.scheme = coupling::Scheme::Simultaneous;
    w.trapezoid = solid::parse_trapezoid(scheme.substr(prefix.size()));
  } else {
    sc.coupling->params.scheme = coupling::parse_scheme(scheme);
  }
  coupling::FsiSimulation sim = make_simulation(sc, std::move(w));
  PhaseTimes phases;
  sim.start(phases);
  record(sim.world(), body, tip, 0.0, r);
  const int steps = static_cast<int>(std::ceil(end / h - 1e-9));
  const double t0 = now_seconds();
  for (int k = 1; k <= steps; ++k) {
    double fluid_ke = 0;
    try {
      fluid_ke = sim.step(h, phases).coupled->fluid.kinetic_energy;
    } catch (const Error& e) {
      r.failure = one_line(fmt::format("failed at t = {:.4g} s: {}", k * h, e.what()));
      break;
    }
    record(sim.world(), body, tip, k * h, r, fluid_ke);
    if (bound > 0 && std::abs(r.energy.back() - r.energy.front()) > bound) {
      r.failure = fmt::format("diverged at t = {:.4g} s", k * h);
      break;
    }
  }
  r.wall_s = now_seconds() - t0;
  logger().info("bench integrators: {} at h = {:.4g} s: {} steps in {:.3g} s{}", scheme, h,
                r.steps(), r.wall_s, r.failure.empty() ? "" : ": " + r.failure);
  return r;
}

/// The mean spacing of the tip's downward crossings of its mean (with a hysteresis of a
/// quarter of its half range, so that higher modes do not count), or nothing if fewer than
/// two.
std::optional<double> measured_period(const Run& r) {
  const auto [lo, hi] = std::minmax_element(r.z.begin(), r.z.end());
  const double mean = 0.5 * (*lo + *hi), band = 0.25 * 0.5 * (*hi - *lo);
  std::vector<double> crossings;
  bool armed = false;
  for (size_t i = 1; i < r.z.size(); ++i) {
    if (r.z[i] > mean + band) armed = true;
    if (armed && r.z[i - 1] > mean && r.z[i] <= mean) {
      const double s = (r.z[i - 1] - mean) / (r.z[i - 1] - r.z[i]);
      crossings.push_back(r.t[i - 1] + s * (r.t[i] - r.t[i - 1]));
      armed = false;
    }
  }
  if (crossings.size() < 3) return std::nullopt;
  return (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
}

/// Peak-to-peak of the tip's z over [a, b).
double peak_to_peak(const Run& r, double a, double b) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t i = 0; i < r.t.size(); ++i) {
    if (r.t[i] < a || r.t[i] >= b) continue;
    lo = std::min(lo, r.z[i]);
    hi = std::max(hi, r.z[i]);
  }
  return hi - lo;
}

json figure(bool ok, double v) {
  return ok ? json(v) : json(nullptr);
}

std::string text(bool ok, const char* f, double v) {
  return ok ? fmt::format(fmt::runtime(f), v) : std::string("-");
}

/// The table of one scene; returns its JSON.
json bench_scene(const std::filesystem::path& file, const BenchIntegratorsOptions& opt,
                 std::ostream& out) {
  const Scene scene = load_scene(file, opt.overrides);
  const std::string name = file.string();
  const bool two_way = scene.two_way();
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic && (!scene.fluid || two_way),
                 "{}: bench integrators needs a dynamic scene without a fluid or two-way "
                 "coupled",
                 name);
  const solid::SolidWorld world0 = build_world(scene);
  const size_t body = first_deformable_body(world0);
  TETFSI_REQUIRE(InputError, body < world0.bodies.size(),
                 "{}: bench integrators needs a deformable body", name);
  const MatX3& rest = world0.bodies[body].rest_positions();
  const Index tip = end_node(rest, true);
  const double dt = scene.time.dt;
  const double end = scene.time.end_time.value_or(scene.time.num_steps() * dt);

  // the reference: the bodies alone (two-way: without the fluid, which barely changes T)
  const Run ref = run_integrator(world0, body, tip, "newton", 0.5 * dt, end, 0.0);
  TETFSI_REQUIRE(InputError, ref.failure.empty(), "{}: the reference run (newton at dt/2) {}", name,
                 ref.failure);
  const std::optional<double> period = measured_period(ref);
  TETFSI_REQUIRE(InputError, period.has_value(),
                 "{}: the reference run shows fewer than two periods in {} s: raise time.end_time",
                 name, end);
  const double ke_ref = *std::max_element(ref.kinetic.begin(), ref.kinetic.end());
  fmt::print(out,
             "{} ('{}'{}): tip node {} at {}, period T = {:.4g} s (newton at dt/2{}), {:.4g} s "
             "= {:.3g} T per run, reference kinetic energy {:.4g} J\n",
             name, scene.name, two_way ? ", two-way: coupling.scheme per row" : "", tip,
             fmt_vec(rest.row(tip).transpose()), *period, two_way ? ", the bodies alone" : "", end,
             end / *period, ke_ref);
  fmt::print(out, "{:<24} {:>8} {:>9} {:>11} {:>11} {:>9} {:>8}  {}\n",
             two_way ? "coupling.scheme" : "integrator", "dt (s)", "A_last/A_1", "drift/KE",
             "max|dE|/KE", "ms/step", "x paper", "status");
  json rows = json::array();
  for (const double h : {dt, 2 * dt}) {
    double paper_ms = 0;
    for (const std::string& m : two_way ? k_schemes : k_integrators) {
      const Run r = two_way ? run_coupled(scene, world0, body, tip, m, h, end, 10 * ke_ref)
                            : run_integrator(world0, body, tip, m, h, end, 10 * ke_ref);
      const bool done = r.failure.empty();
      const int periods = static_cast<int>(std::floor(r.t.back() / *period + 1e-9));
      const bool amp = done && periods >= 2;
      const double ratio = amp ? peak_to_peak(r, (periods - 1) * *period, periods * *period) /
                                     peak_to_peak(r, 0, *period)
                               : 0.0;
      double max_err = 0;
      for (double e : r.energy) max_err = std::max(max_err, std::abs(e - r.energy.front()));
      const double drift = (r.energy.back() - r.energy.front()) / ke_ref;
      const double ms = r.steps() > 0 ? 1e3 * r.wall_s / r.steps() : 0.0;
      if (is_paper(m)) paper_ms = ms;
      fmt::print(out, "{:<24} {:>8.4g} {:>9} {:>11} {:>11} {:>9.3g} {:>8}  {}\n", label(m), h,
                 text(amp, "{:.4f}", ratio), text(done, "{:+.2e}", drift),
                 text(done, "{:.2e}", max_err / ke_ref), ms,
                 text(paper_ms > 0, "{:.2f}", ms / paper_ms), done ? "completed" : r.failure);
      out.flush();
      rows.push_back({{"integrator", label(m)},
                      {"dt", h},
                      {"periods", periods},
                      {"amplitude_ratio", figure(amp, ratio)},
                      {"energy_drift", figure(done, drift)},
                      {"max_energy_error", figure(done, max_err / ke_ref)},
                      {"step_ms", ms},
                      {"cost_vs_paper", figure(paper_ms > 0, ms / paper_ms)},
                      {"completed", done},
                      {"failure", done ? json(nullptr) : json(r.failure)}});
    }
  }
  fmt::print(out, "\n");
  return {{"scene", name},
          {"dt", dt},
          {"period", *period},
          {"reference_kinetic_energy", ke_ref},
          {"rows", std::move(rows)}};
}

}  // namespace

int bench_integrators(const std::vector<std::filesystem::path>& scenes,
                      const BenchIntegratorsOptions& opt, std::ostream& out) {
  TETFSI_REQUIRE(InputError, !scenes.empty(), "bench integrators: no scene given");
  fmt::print(out,
             "tetfsi bench integrators: A_last/A_1 = the tip's peak-to-peak over the last whole "
             "period over the first's; drift = E(end) - E(0) and max|dE| = max |E(t) - E(0)|, "
             "over the reference's largest kinetic energy KE\n\n");
  json all = json::array();
  for (const std::filesystem::path& s : scenes) all.push_back(bench_scene(s, opt, out));
  if (!opt.json_path.empty())
    write_text_file_atomic(opt.json_path, json{{"scenes", all}}.dump(2) + "\n");
  return 0;
}

}  // namespace tetfsi::app
