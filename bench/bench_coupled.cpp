/// @file bench_coupled.cpp
/// `tetfsi bench coupled` (bench_coupled.hpp).
#include "bench/bench_coupled.hpp"

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
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"
#include "coupling/grid_fluid.hpp"
#include "coupling/simulation.hpp"
#include "coupling/tet_fluid.hpp"
#include "fluid/grid/projection.hpp"
#include "fluid/tet/operators.hpp"
#include "io/output.hpp"
#include "mesh/remesh.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"
#include "solid/integrator.hpp"

namespace tetfsi::app {

namespace {

using coupling::Scheme;
constexpr double k_inf = std::numeric_limits<double>::infinity();

/// One run of a scheme from the scene's initial state.
struct Run {
  double h = 0.0, bound = k_inf, max_energy = 0.0;
  int steps = 0, completed = 0, exceeded_at = 0;  ///< exceeded_at: first step with E > bound
  std::string failure;                            ///< what() of the step that threw
  std::vector<double> step_s;                     ///< wall seconds of each completed step
  bool stable() const { return failure.empty() && exceeded_at == 0; }
  std::string outcome() const {
    if (!failure.empty()) return fmt::format("failed at step {}", completed + 1);
    if (exceeded_at > 0) return fmt::format("E > bound at step {}", exceeded_at);
    return "stable";
  }
};

/// `steps` coupled steps of `scheme` at h; stops at a failed step, and at the first step with
/// E > bound if `stop_at_bound`.
Run run_scheme(const Scene& scene, const solid::SolidWorld& world0, Scheme scheme, double h,
               int steps, double bound, bool stop_at_bound) {
  Run r;
  r.h = h;
  r.steps = steps;
  r.bound = bound;
  Scene sc = scene;
  sc.coupling->params.scheme = scheme;
  coupling::FsiSimulation sim = make_simulation(sc, world0);
  PhaseTimes phases;
  sim.start(phases);  // a scene that cannot be meshed at t = 0 is an error
  try {
    for (int k = 0; k < steps; ++k) {
      const double t0 = now_seconds();
      const coupling::CoupledStepReport rep = *sim.step(h, phases).coupled;
      r.step_s.push_back(now_seconds() - t0);
      ++r.completed;
      const double e = rep.solid_kinetic_energy + rep.elastic_energy;
      r.max_energy = std::max(r.max_energy, e);
      if (!(e <= bound) && r.exceeded_at == 0) r.exceeded_at = k + 1;
      if (r.exceeded_at > 0 && stop_at_bound) break;
    }
  } catch (const Error& e) {
    r.failure = e.what();
  }
  logger().info("bench coupled: {} at h = {:.6g} s: {} ({}/{} steps, max E {:.4g} J)",
                coupling::to_string(scheme), h, r.outcome(), r.completed, steps, r.max_energy);
  return r;
}

/// (b): mean seconds of the completed steps after the first; unset if fewer than 3.
std::optional<double> mean_step(const Run& r) {
  if (r.completed < 4) return std::nullopt;
  double s = 0.0;
  for (int k = 1; k < r.completed; ++k) s += r.step_s[k];
  return s / (r.completed - 1);
}

struct SolveFigures {
  double coupled_s = k_inf, fluid_s = k_inf;
  Index cells = 0, pressure_unknowns = 0, solid_unknowns = 0, groups = 0;
  int coupled_iterations = 0, fluid_iterations = 0;
  bool converged = true;
};

/// The bodies of the next step as CoupledStepper::step sets them up (without floor
/// contacts: the figures are the solves' seconds): surfaces at x* = x + h u with their
/// velocities, each free body's trapezoidal system, the interfaces.
struct NextStep {
  std::vector<MatX3> positions;  ///< x* per body (all nodes)
  std::vector<mesh::SolidSurface> solids;
  std::vector<fluid::SolidSurfaceMotion> motion;
  std::vector<coupling::CoupledBody> cb;
  std::vector<coupling::BodyInterface> ifaces;
  std::vector<VecX> velocity;  ///< per body, flat
};

NextStep next_step(solid::SolidWorld& world, double h) {
  const size_t nb = world.bodies.size();
  NextStep n;
  n.positions.resize(nb);
  n.solids.resize(nb);
  n.motion.resize(nb);
  n.cb.resize(nb);
  n.ifaces.resize(nb);
  n.velocity.resize(nb);
  for (size_t b = 0; b < nb; ++b) {
    solid::SolidBody& body = world.bodies[b];
    if (body.is_kinematic()) body.set_kinematic_state(world.time + h);
    const coupling::BodySurface s = coupling::body_surface(body);
    const MatX3 x =
        body.is_kinematic() ? body.positions() : MatX3(body.positions() + h * body.velocity);
    n.positions[b] = x;
    n.velocity[b] = flat(body.velocity);
    n.solids[b].body = static_cast<int>(b);
    n.solids[b].triangles = s.triangles;
    n.solids[b].vertices.resize(s.nodes.size(), 3);
    n.motion[b].triangles = s.triangles;
    n.motion[b].velocity.resize(s.nodes.size(), 3);
    for (Index k = 0; k < s.nodes.size(); ++k) {
      n.solids[b].vertices.row(k) = x.row(s.nodes[k]);
      n.motion[b].velocity.row(k) = body.velocity.row(s.nodes[k]);
    }
    n.ifaces[b] = {s.triangles, s.nodes, body.num_nodes()};
    if (body.is_kinematic()) continue;
    solid::TrapezoidalSystem sys =
        solid::assemble_trapezoidal(body, h, body.external_forces(world.gravity), world.trapezoid);
    coupling::CoupledBody& c = n.cb[b];
    c.free = true;
    c.A = std::move(sys.A);
    c.b = std::move(sys.b);
    c.fixed = body.fixed_dofs();
    c.prescribed = VecX::Zero(body.num_dofs());
    c.x = body.positions();
    c.u = n.velocity[b];
  }
  return n;
}

/// The fluid-only solver of (c): the scene's fluid kind at the coupled solve's tolerance.
std::unique_ptr<LinearSolver> fluid_only_solver(const fluid::FluidParams& fp,
                                                const coupling::CoupledOptions& solve) {
  SolverOptions o;
  o.rel_tol = solve.rel_tol;
  o.max_iterations = solve.max_iterations;
  o.symmetric = true;
  return make_linear_solver(fp.solver, o);
}

/// (c) on the tet mesh: the next step's mesh, v* on it, solve_coupled against fluid::project.
SolveFigures time_tet_solves(const Scene& scene, coupling::FsiSimulation& fsi,
                             const coupling::CoupledOptions& solve, double h) {
  const fluid::FluidSimulation& sim = *coupling::tet_fluid(fsi.fluid());
  solid::SolidWorld world = fsi.world();
  const NextStep n = next_step(world, h);
  PhaseTimes phases;
  mesh::Sizing sizing = scene.fluid->sizing;
  sizing.refine = sim.refinement_field();
  const fluid::FluidPrediction pred =
      sim.predict(mesh::remesh(scene.fluid->domain, n.solids, sizing), h, n.motion, phases);
  const fluid::FluidParams& fp = sim.params();

  // no volume targets: no enclosed-volume correction
  const coupling::InterfaceOperators ops(pred.mesh, n.ifaces);
  const coupling::CoupledInput in = coupling::make_input(pred, fp, ops, n.cb);
  const VecX q_open = pred.p_open * (h / fp.density);
  SolveFigures f;
  f.cells = pred.mesh.num_tets();
  for (int rep = 0; rep < 3; ++rep) {
    const double t0 = now_seconds();
    const coupling::CoupledSolution sol = coupling::solve_coupled(in, solve);
    f.coupled_s = std::min(f.coupled_s, now_seconds() - t0);
    f.coupled_iterations = sol.report.iterations;
    f.pressure_unknowns = sol.report.pressure_unknowns;
    f.solid_unknowns = sol.report.solid_unknowns;
    f.converged = f.converged && sol.report.converged;

    VecX u = pred.u_star, q;  // the Solid faces hold the bodies' velocities (`motion`)
    const double t1 = now_seconds();
    const auto solver = fluid_only_solver(fp, solve);
    const fluid::ProjectionReport pr =
        fluid::project(pred.mesh, fp.min_dual_fraction, q_open, u, q, *solver);
    f.fluid_s = std::min(f.fluid_s, now_seconds() - t1);
    f.fluid_iterations = pr.iterations;
    f.groups = pr.groups;
    f.converged = f.converged && pr.converged;
  }
  return f;
}

/// (c) on the grid: the next step's classified grid and v* (GridCoupledFluid::predict), the
/// coupled solve on it against fluid::grid_project of the same v* with the bodies' faces
/// holding their velocities (the bodies' motion, apply_H).
SolveFigures time_grid_solves(coupling::FsiSimulation& fsi, const coupling::CoupledOptions& solve,
                              double h) {
  solid::SolidWorld world = fsi.world();
  NextStep n = next_step(world, h);
  PhaseTimes phases;
  const std::unique_ptr<coupling::CoupledFluid> fluid = fsi.fluid()->coupled(n.ifaces, phases);
  coupling::CoupledFluid& gf = *fluid;
  const std::unique_ptr<coupling::PredictedFluid> pred =
      gf.predict(n.positions, n.motion, h, phases);
  const auto& gp = dynamic_cast<const coupling::GridPredicted&>(*pred);
  const fluid::GridPrediction& g = gp.prediction();
  const fluid::FluidParams& fp = gf.params();
  SolveFigures f;
  f.cells = g.cells.grid.num_cells();
  for (int rep = 0; rep < 3; ++rep) {
    const double t0 = now_seconds();
    const coupling::CoupledSolution sol = pred->solve(n.cb, solve);
    f.coupled_s = std::min(f.coupled_s, now_seconds() - t0);
    f.coupled_iterations = sol.report.iterations;
    f.pressure_unknowns = sol.report.pressure_unknowns;
    f.solid_unknowns = sol.report.solid_unknowns;
    f.converged = f.converged && sol.report.converged;

    VecX u = g.u_star, q;
    gp.apply_H(n.velocity, u);
    const double t1 = now_seconds();
    const auto solver = fluid_only_solver(fp, solve);
    const fluid::ProjectionReport pr =
        fluid::grid_project(g.cells, g.p_open * (h / fp.density), u, q, *solver);
    f.fluid_s = std::min(f.fluid_s, now_seconds() - t1);
    f.fluid_iterations = pr.iterations;
    f.groups = pr.groups;
    f.converged = f.converged && pr.converged;
  }
  return f;
}

/// (c): after `warm` simultaneous steps at dt, the next step's coupled solve (schur_amg,
/// bodies free) against the fluid-only projection, best of 3 each.
SolveFigures time_solves(const Scene& scene, const solid::SolidWorld& world0, int warm) {
  const double h = scene.time.dt;
  Scene sc = scene;
  coupling::CouplingParams& p = sc.coupling->params;
  p.scheme = Scheme::Simultaneous;
  p.solve.solver = coupling::CoupledSolverKind::SchurAmg;
  coupling::FsiSimulation fsi = make_simulation(sc, world0);
  PhaseTimes phases;
  fsi.start(phases);
  for (int k = 0; k < warm; ++k) fsi.step(h, phases);
  return coupling::grid_fluid(fsi.fluid()) ? time_grid_solves(fsi, p.solve, h)
                                           : time_tet_solves(scene, fsi, p.solve, h);
}

nlohmann::json opt_json(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}
std::string opt_str(const std::optional<double>& v, const char* none) {
  return v ? fmt::format("{:.6g}", *v) : std::string(none);
}

/// What makes a run unstable (printed, and in the JSON).
const char* const k_criterion =
    "unstable: a step throws, or E = solid kinetic + elastic > 10 * max(E0, E_sim(h)), E0 at "
    "t = 0, E_sim(h) the max E of the simultaneous run at the same h if it was stable (else "
    "0; simultaneous runs: 10 * E0)";

/// What every part runs from: the scene, its bodies at t = 0, their energy E0, its dt.
struct Bench {
  const Scene& scene;
  const solid::SolidWorld& world0;
  double e0 = 0.0, dt = 0.0;
};

/// (a): the largest stable h of each scheme (unset: none), and the runs that found them.
struct StableSteps {
  std::optional<double> sim, split;
  nlohmann::json runs_sim = nlohmann::json::array(), runs_split = nlohmann::json::array();
};

/// (b): the mean seconds per step of simultaneous [0] and splitting [1], and the runs' counts.
struct StepTiming {
  std::optional<double> step_s[2];
  nlohmann::json timing;
};

/// The figures against the goals.
struct Goals {
  double solve_ratio = 0.0;          ///< coupled solve / fluid-only projection
  std::optional<double> step_ratio;  ///< simultaneous step / splitting step
  bool stable = false, solve = false, step = false;
};

/// Rejects out-of-range options.
void check_options(const BenchCoupledOptions& opt) {
  TETFSI_REQUIRE(InputError, std::isfinite(opt.time) && opt.time > 0,
                 "bench coupled: --time must be a positive number of seconds, got {}", opt.time);
  TETFSI_REQUIRE(InputError, opt.steps_down >= 0 && opt.steps_down <= 12,
                 "bench coupled: --steps-down must be in 0..12, got {}", opt.steps_down);
  TETFSI_REQUIRE(InputError, opt.timed_steps >= 4,
                 "bench coupled: --timed-steps must be at least 4 (a warm-up + 3), got {}",
                 opt.timed_steps);
}

/// Rejects a scene without a fluid or a static one.
void check_scene(const Scene& scene, const std::string& name) {
  TETFSI_REQUIRE(InputError, scene.fluid.has_value() && scene.coupling.has_value(),
                 "{}: bench coupled needs a fluid scene (no 'fluid' section)", name);
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "{}: bench coupled needs a dynamic scene (mode is 'static')", name);
}

/// The bodies' solid energy at t = 0, after checking that one is deformable and it is > 0.
double checked_initial_energy(const solid::SolidWorld& world0, const std::string& name) {
  TETFSI_REQUIRE(InputError,
                 std::any_of(world0.bodies.begin(), world0.bodies.end(),
                             [](const solid::SolidBody& b) { return !b.is_kinematic(); }),
                 "{}: bench coupled needs a deformable (non-kinematic) body", name);
  const double e0 = world0.kinetic_energy() + world0.elastic_energy();
  TETFSI_REQUIRE(InputError, e0 > 0,
                 "{}: the bodies start at rest and unstressed (solid energy 0 J); bench coupled "
                 "bounds the energy by a multiple of it: give an initial_velocity",
                 name);
  return e0;
}

/// Prints a run's row of (a) (and its failure) and appends its JSON to `list`.
void record_run(const Run& r, Scheme s, nlohmann::json& list, std::ostream& out) {
  fmt::print(out, "{:<13} {:>10.6g} {:>6} {:>6} {:>10.4g} {:>10.4g}  {}\n", coupling::to_string(s),
             r.h, r.steps, r.completed, r.max_energy, r.bound, r.outcome());
  if (!r.failure.empty()) fmt::print(out, "    {}\n", r.failure);
  out.flush();
  list.push_back({{"h", r.h},
                  {"steps", r.steps},
                  {"completed", r.completed},
                  {"stable", r.stable()},
                  {"outcome", r.outcome()},
                  {"max_energy", r.max_energy},
                  {"bound", r.bound},
                  {"failure", r.failure}});
}

/// (a): both schemes at h = 2 dt / 2^k from k = 0 down, until each has a stable h.
StableSteps largest_stable_steps(const Bench& b, const BenchCoupledOptions& opt,
                                 std::ostream& out) {
  fmt::print(out, "(a) largest stable step, h = 2 dt / 2^k, k = 0..{}\n", opt.steps_down);
  fmt::print(out, "{:<13} {:>10} {:>6} {:>6} {:>10} {:>10}  {}\n", "scheme", "h (s)", "steps",
             "done", "max E (J)", "bound (J)", "outcome");
  StableSteps a;
  double h_min = 2 * b.dt;
  for (int k = 0; k <= opt.steps_down && !(a.sim && a.split); ++k) {
    const double h = 2 * b.dt / std::pow(2.0, k);
    const int steps = static_cast<int>(std::ceil(opt.time / h - 1e-9));
    h_min = h;
    // simultaneous runs at every h splitting is tried at: its reference E_sim(h)
    const Run sim = run_scheme(b.scene, b.world0, Scheme::Simultaneous, h, steps, 10 * b.e0, true);
    record_run(sim, Scheme::Simultaneous, a.runs_sim, out);
    if (sim.stable() && !a.sim) a.sim = h;
    if (a.split) continue;
    const double bound = 10 * std::max(b.e0, sim.stable() ? sim.max_energy : 0.0);
    const Run split = run_scheme(b.scene, b.world0, Scheme::Splitting, h, steps, bound, true);
    record_run(split, Scheme::Splitting, a.runs_split, out);
    if (split.stable()) a.split = h;
  }
  const std::string none = fmt::format("none down to {:.6g}", h_min);
  fmt::print(out, "largest stable h: simultaneous {}, splitting {}\n\n",
             opt_str(a.sim, none.c_str()), opt_str(a.split, none.c_str()));
  return a;
}

/// (b): the mean wall seconds per step of each scheme at dt, the first step a warm-up.
StepTiming time_steps(const Bench& b, const BenchCoupledOptions& opt, std::ostream& out) {
  fmt::print(out, "(b) wall seconds per step at dt = {:.6g} s ({} steps, the first a warm-up)\n",
             b.dt, opt.timed_steps);
  StepTiming t;
  for (const Scheme s : {Scheme::Simultaneous, Scheme::Splitting}) {
    const Run r = run_scheme(b.scene, b.world0, s, b.dt, opt.timed_steps, 10 * b.e0, false);
    const int i = s == Scheme::Simultaneous ? 0 : 1;
    t.step_s[i] = mean_step(r);
    std::string note;
    if (!r.failure.empty())
      note = fmt::format(" (failed at step {}: timed the {} completed after the warm-up)",
                         r.completed + 1, std::max(0, r.completed - 1));
    else if (r.exceeded_at > 0)
      note = fmt::format(" (E > 10 E0 from step {}: blowing up)", r.exceeded_at);
    fmt::print(out, "{:<13} {:>10} s{}\n", coupling::to_string(s),
               opt_str(t.step_s[i], "n/a (< 3 steps)"), note);
    t.timing[coupling::to_string(s)] = {{"completed", r.completed},
                                        {"timed", std::max(0, r.completed - 1)},
                                        {"failed", !r.failure.empty()},
                                        {"exceeded_at", r.exceeded_at}};
  }
  return t;
}

/// Prints (c): the coupled solve against the fluid-only projection.
void print_solves(const SolveFigures& f, int warm_steps, double solve_ratio, std::ostream& out) {
  fmt::print(out,
             "\n(c) one solve after {} simultaneous steps at dt, {} cells ({} pressure unknowns, "
             "{} solid), best of 3:\n  coupled schur_amg {:.4g} s ({} iterations), fluid-only "
             "projection {:.4g} s ({} iterations), ratio {:.3g}{}\n",
             warm_steps, f.cells, f.pressure_unknowns, f.solid_unknowns, f.coupled_s,
             f.coupled_iterations, f.fluid_s, f.fluid_iterations, solve_ratio,
             f.converged ? "" : " (a solve did not converge)");
}

/// The figures against the goals, printed under "goals:".
Goals check_goals(const StableSteps& a, const StepTiming& t, double solve_ratio, double dt,
                  std::ostream& out) {
  Goals g;
  g.solve_ratio = solve_ratio;
  const bool sim_at_dt = a.sim && *a.sim >= dt * (1 - 1e-9);
  const bool split_at_dt = a.split && *a.split >= dt * (1 - 1e-9);
  g.stable = sim_at_dt && !split_at_dt;
  g.solve = solve_ratio <= 1.5;
  if (t.step_s[0] && t.step_s[1]) g.step_ratio = *t.step_s[0] / *t.step_s[1];
  g.step = g.step_ratio && *g.step_ratio <= 1.2;
  auto met = [](bool b) { return b ? "met" : "NOT met"; };
  auto yes = [](bool b) { return b ? "yes" : "no"; };
  fmt::print(out,
             "\ngoals:\n  simultaneous stable at h = dt = 1/{:.4g} where splitting is not (largest "
             "stable h >= dt: simultaneous {}, splitting {}) -> {}\n  coupled solve within 1.5x "
             "of the fluid-only projection: {:.3g}x -> {}\n  simultaneous step within 1.2x of a "
             "splitting step: {}x -> {}\n",
             1.0 / dt, yes(sim_at_dt), yes(split_at_dt), met(g.stable), solve_ratio, met(g.solve),
             opt_str(g.step_ratio, "n/a"), met(g.step));
  return g;
}

/// Writes the results as JSON to `path` (atomically).
void write_json(const std::filesystem::path& path, const Bench& b, const BenchCoupledOptions& opt,
                const StableSteps& a, const StepTiming& t, const SolveFigures& f, const Goals& g) {
  const nlohmann::json j{
      {"scene", b.scene.name},
      {"dt", b.dt},
      {"time", opt.time},
      {"criterion", k_criterion},
      {"initial_energy", b.e0},
      {"stable_dt", {{"simultaneous", opt_json(a.sim)}, {"splitting", opt_json(a.split)}}},
      {"step_s", {{"simultaneous", opt_json(t.step_s[0])}, {"splitting", opt_json(t.step_s[1])}}},
      {"coupled_solve_s", f.coupled_s},
      {"fluid_only_solve_s", f.fluid_s},
      {"solve_ratio", g.solve_ratio},
      {"step_ratio", opt_json(g.step_ratio)},
      {"runs", {{"simultaneous", a.runs_sim}, {"splitting", a.runs_split}}},
      {"timing", t.timing},
      {"solve",
       {{"cells", f.cells},
        {"pressure_unknowns", f.pressure_unknowns},
        {"solid_unknowns", f.solid_unknowns},
        {"coupled_iterations", f.coupled_iterations},
        {"fluid_only_iterations", f.fluid_iterations},
        {"fluid_only_groups", f.groups},
        {"converged", f.converged}}},
      {"goals", {{"stable", g.stable}, {"solve", g.solve}, {"step", g.step}}}};
  write_text_file_atomic(path, j.dump(2) + "\n");
}

}  // namespace

int bench_coupled(const std::filesystem::path& scene_file, const BenchCoupledOptions& opt,
                  std::ostream& out) {
  check_options(opt);
  const Scene scene = load_scene(scene_file, opt.overrides);
  const std::string name = scene_file.string();
  check_scene(scene, name);
  const solid::SolidWorld world0 = build_world(scene);
  const double e0 = checked_initial_energy(world0, name);
  const Bench b{scene, world0, e0, scene.time.dt};

  fmt::print(out, "tetfsi bench coupled: {} ('{}'), dt = {:.6g} s (1/{:.4g}), {:.4g} s per run\n",
             name, scene.name, b.dt, 1.0 / b.dt, opt.time);
  fmt::print(out, "{}; E0 = {:.4g} J\n\n", k_criterion, e0);
  const StableSteps a = largest_stable_steps(b, opt, out);
  const StepTiming t = time_steps(b, opt, out);

  const SolveFigures f = time_solves(scene, world0, opt.warm_steps);
  const double solve_ratio = f.coupled_s / f.fluid_s;
  print_solves(f, opt.warm_steps, solve_ratio, out);
  const Goals g = check_goals(a, t, solve_ratio, b.dt, out);
  if (!opt.json_path.empty()) write_json(opt.json_path, b, opt, a, t, f, g);
  return 0;
}

}  // namespace tetfsi::app
