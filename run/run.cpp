#include "run/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <limits>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "core/ranks.hpp"
#include "core/timer.hpp"
#include "io/output.hpp"
#include "io/state_io.hpp"
#include "mesh/quality.hpp"
#include "mesh/remesh.hpp"
#include "run/checkpoints.hpp"
#include "run/divergence.hpp"
#include "solid/static_solve.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

ProgressMode parse_progress_mode(const std::string& name) {
  return k_progress_mode_names.parse(name);
}

namespace {

/// "4.2 s", "3 min 12 s", "1 h 02 min".
std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  if (s < 60) return fmt::format("{:.1f} s", s);
  const long total = std::lround(s);
  if (total < 3600) return fmt::format("{} min {:02d} s", total / 60, static_cast<int>(total % 60));
  return fmt::format("{} h {:02d} min", total / 3600, static_cast<int>((total % 3600) / 60));
}

/// Progress on stderr. This is user-interface output (asked for with --progress), so it is
/// printed directly rather than through the logger, whose level may hide it.
class Progress {
 public:
  /// @param done_before steps done before this part of the run (a resumed run)
  Progress(ProgressMode mode, int total_steps, int done_before = 0)
      : m_total(total_steps), m_done0(done_before), m_start(now_seconds()) {
    if (mode == ProgressMode::Auto)
      mode = isatty(fileno(stderr)) ? ProgressMode::Tty : ProgressMode::Plain;
    m_mode = is_root_rank() ? mode : ProgressMode::Off;  // under mpirun, rank 0's line only
    m_last_print = m_start - 1.0;                        // the first step is shown at once
  }

  /// Call after step `step` (1-based) ended at time t.
  void update(int step, double t) {
    if (m_mode == ProgressMode::Off) return;
    const double now = now_seconds();
    const double elapsed = now - m_start;
    const double ms_per_step = 1e3 * elapsed / std::max(step - m_done0, 1);
    const double eta = 1e-3 * ms_per_step * (m_total - step);
    const int pct = m_total > 0 ? static_cast<int>(100.0 * step / m_total) : 100;
    if (m_mode == ProgressMode::Tty) {
      if (step < m_total && now - m_last_print < 0.1) return;
      std::fprintf(stderr, "\rstep %d/%d  t = %.6g s  %.3g ms/step  ETA %s\x1b[K", step, m_total, t,
                   ms_per_step, format_duration(eta).c_str());
      std::fflush(stderr);
      m_line_open = true;
    } else {
      const bool tenth = pct / 10 > m_last_tenth;
      if (!(tenth || now - m_last_print >= 2.0 || step == m_total)) return;
      m_last_tenth = pct / 10;
      std::fprintf(stderr, "step %d/%d (%d%%)  t = %.6g s  %.3g ms/step  ETA %s\n", step, m_total,
                   pct, t, ms_per_step, format_duration(eta).c_str());
      std::fflush(stderr);
    }
    m_last_print = now;
  }

  /// End the live line (TTY mode) so that later output starts on a fresh line.
  void finish() {
    if (m_line_open) {
      std::fputc('\n', stderr);
      std::fflush(stderr);
      m_line_open = false;
    }
  }

  ~Progress() { finish(); }

 private:
  ProgressMode m_mode = ProgressMode::Off;
  int m_total;
  int m_done0;
  double m_start;
  double m_last_print;
  int m_last_tenth = 0;
  bool m_line_open = false;
};

/// Energies of the whole world into a stats row, and the result's final values.
void fill_energies(const solid::SolidWorld& world, StepStats& row) {
  row.kinetic_energy = 0.0;
  row.elastic_energy = 0.0;
  row.gravity_potential = 0.0;
  for (const auto& b : world.bodies) {
    row.kinetic_energy += b.kinetic_energy();
    row.elastic_energy += b.elastic_energy();
    row.gravity_potential += b.gravity_potential(world.gravity);
  }
}

/// The bodies' poses into a stats row (solid::body_pose, up against the world's gravity), and
/// their extremes over the run into `r`.
void fill_poses(const solid::SolidWorld& world, StepStats& row, RunResult& r) {
  const Vec3 up = solid::up_direction(world.gravity);
  row.bodies.clear();
  r.pose_ranges.resize(world.bodies.size());
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    row.bodies.push_back(solid::body_pose(world.bodies[i], up));
    r.pose_ranges[i].add(row.bodies.back());
  }
}

void fill_final(const solid::SolidWorld& world, RunResult& r) {
  StepStats e;
  fill_energies(world, e);
  r.kinetic_energy = e.kinetic_energy;
  r.elastic_energy = e.elastic_energy;
  r.gravity_potential = e.gravity_potential;
  r.bodies.clear();
  for (const auto& b : world.bodies) {
    BodySummary s;
    s.name = b.name();
    s.nodes = b.num_nodes();
    s.tets = b.num_tets();
    s.max_displacement = b.num_nodes() > 0 ? b.displacement.rowwise().norm().maxCoeff() : 0.0;
    if (r.bodies.size() < r.pose_ranges.size()) s.pose = r.pose_ranges[r.bodies.size()];
    r.bodies.push_back(s);
  }
}

/// The state (d, u) of every body and the world's time, to go back to the last good state
/// when a step fails, so that the summary reports it rather than a diverged one.
class StateSnapshot {
 public:
  void save(const solid::SolidWorld& world) {
    m_time = world.time;
    m_state.resize(world.bodies.size());
    for (size_t i = 0; i < world.bodies.size(); ++i) {
      m_state[i].first = world.bodies[i].displacement;
      m_state[i].second = world.bodies[i].velocity;
    }
  }
  void restore(solid::SolidWorld& world) const {
    world.time = m_time;
    for (size_t i = 0; i < m_state.size() && i < world.bodies.size(); ++i) {
      world.bodies[i].displacement = m_state[i].first;
      world.bodies[i].velocity = m_state[i].second;
    }
  }

 private:
  double m_time = 0.0;
  std::vector<std::pair<MatX3, MatX3>> m_state;
};

/// One frame: the bodies and, in a fluid scene, the fluid's frame (its mesh or grid with
/// their fields) by its geometry.
void write_frame(OutputWriter& out, const coupling::FsiSimulation& sim, int step, double t) {
  const fluid::FluidFrame frame = sim.fluid_frame();
  if (const fluid::GridFrameFields* grid = frame.grid()) {
    out.write_grid_frame(sim.world(), step, t, *grid);
  } else if (const fluid::MeshFrame* mesh = frame.mesh()) {
    out.write_frame(sim.world(), step, t, mesh->mesh, &mesh->fields);
  } else {
    out.write_frame(sim.world(), step, t, nullptr);
  }
}

/// The scene with the command-line step/end-time overrides applied (also in `resolved`, so
/// that scene.resolved.json reproduces the run).
Scene apply_overrides(const Scene& scene, const RunOptions& opt) {
  Scene s = scene;
  TETFSI_REQUIRE(InputError, !(opt.steps && opt.end_time),
                 "give either a step count or an end time, not both");
  if (opt.checkpoint_every || opt.keep_checkpoints || opt.wall_time) {
    if (s.mode == Mode::Static) {
      logger().warn(
          "scene '{}' is static: --checkpoint-every, --keep-checkpoints and --wall-time are "
          "ignored (a static solve has no steps to resume)",
          s.name);
    } else {
      if (opt.checkpoint_every) {
        TETFSI_REQUIRE(InputError, *opt.checkpoint_every >= 0,
                       "--checkpoint-every must be >= 0, got {}", *opt.checkpoint_every);
        s.output.checkpoint_every = *opt.checkpoint_every;
        if (s.resolved.is_object())
          s.resolved["output"]["checkpoint_every"] = *opt.checkpoint_every;
      }
      if (opt.keep_checkpoints) {
        TETFSI_REQUIRE(InputError, *opt.keep_checkpoints >= 1,
                       "--keep-checkpoints must be >= 1, got {}", *opt.keep_checkpoints);
        s.output.keep_checkpoints = *opt.keep_checkpoints;
        if (s.resolved.is_object())
          s.resolved["output"]["keep_checkpoints"] = *opt.keep_checkpoints;
      }
    }
  }
  if (!opt.steps && !opt.end_time) return s;
  if (s.mode == Mode::Static) {
    logger().warn("scene '{}' is static: the step count / end time override is ignored", s.name);
    return s;
  }
  nlohmann::json* time = nullptr;
  if (s.resolved.is_object()) time = &s.resolved["time"];
  if (opt.steps) {
    TETFSI_REQUIRE(InputError, *opt.steps >= 1, "the step count must be at least 1, got {}",
                   *opt.steps);
    s.time.steps = *opt.steps;
    s.time.end_time.reset();
    if (time) {
      if (time->is_object()) time->erase("end_time");
      (*time)["steps"] = *opt.steps;
    }
  } else {
    TETFSI_REQUIRE(InputError, std::isfinite(*opt.end_time) && *opt.end_time > 0,
                   "the end time must be positive, got {}", *opt.end_time);
    s.time.end_time = *opt.end_time;
    s.time.steps.reset();
    if (time) {
      if (time->is_object()) time->erase("steps");
      (*time)["end_time"] = *opt.end_time;
    }
  }
  return s;
}

/// What one part of a dynamic run starts from: step 1 of a fresh run, or the step after a
/// checkpoint (`tetfsi resume`), and what the loop carries between steps beyond the
/// simulation.
struct Session {
  int first_step = 1;
  int last_frame = 0;        ///< the step of the last frame on the output.every schedule
  double wall_before = 0.0;  ///< wall seconds of the run's earlier parts (resume)
  double begin = 0.0;        ///< now_seconds() when this part began (before the build)
  double start = 0.0;        ///< now_seconds() when the loop's timing began (after the build)
  std::optional<DivergenceGuard> guard;
};

/// The layout version of the "run/" records (the file format has its own). 2: the bodies'
/// pose extremes ("run/pose/").
constexpr int k_run_records_version = 2;

template <class S, class F>
void visit_equilibrium(S& e, F&& f) {
  f("method", e.method);
  f("via", e.via);
  f("iteration_limit", e.iteration_limit);
  f("steps", e.steps);
  f("max_iterations", e.max_iterations);
  f("iterations", e.iterations);
  f("evaluations", e.evaluations);
  f("fluid_solves", e.fluid_solves);
}

template <class S, class F>
void visit_contact(S& c, F&& f) {  // ContactSummary
  f("min_gap", c.min_gap);
  f("max_pairs", c.max_pairs);
  f("max_force", c.max_force);
  f("steps_in_contact", c.steps_in_contact);
  f("crossings", c.crossings);
  f("seconds", c.seconds);
}

template <class S, class F>
void visit_result(S& r, F&& f) {  // the counters of RunResult a resumed run goes on from
  f("steps_done", r.steps_done);
  f("end_time", r.end_time);
  f("build_s", r.build_s);
  f("solver_iterations", r.solver_iterations);
  f("unconverged_steps", r.unconverged_steps);
}

/// The bodies' pose extremes (RunResult::pose_ranges) as "run/pose/<i>/..." records.
void save_pose_ranges(const RunResult& r, CheckpointWriter& w) {
  w.put("run/pose/count", static_cast<std::int64_t>(r.pose_ranges.size()));
  for (size_t i = 0; i < r.pose_ranges.size(); ++i) {
    const std::string p = fmt::format("run/pose/{}/", i);
    w.put(p + "min_lowest", r.pose_ranges[i].min_lowest);
    w.put(p + "max_rotation_deg", r.pose_ranges[i].max_rotation_deg);
  }
}

void load_pose_ranges(const CheckpointReader& ck, size_t bodies, RunResult& r) {
  const std::size_t n = ck.get_count("run/pose/count");
  if (n != bodies) ck.fail(fmt::format("run/pose/count: {} bodies, the scene has {}", n, bodies));
  r.pose_ranges.assign(n, BodyPoseRange{});
  for (size_t i = 0; i < n; ++i) {
    const std::string p = fmt::format("run/pose/{}/", i);
    r.pose_ranges[i].min_lowest = ck.get_double(p + "min_lowest");
    r.pose_ranges[i].max_rotation_deg = ck.get_double(p + "max_rotation_deg");
  }
}

/// The checkpoint after step `step`: the simulation's records ("sim/") and the run's ("run/"),
/// written atomically to OUT/checkpoints/step_NNNNNN.tfck; then the old ones are pruned.
fs::path write_checkpoint(const Scene& scene, const coupling::FsiSimulation& sim,
                          const RunRecorder* rec, const OutputWriter& out, const RunResult& r,
                          const Session& ses, int step) {
  const double t0 = now_seconds();
  CheckpointWriter w;
  sim.save_state(w);
  w.put("run/version", k_run_records_version);
  w.put("run/step", step);
  w.put("run/time", step * scene.time.dt);
  w.put("run/steps_planned", r.steps_planned);
  w.put("run/scene", scene.resolved.dump());
  w.put("run/scene_file", scene.file.string());
  w.put("run/physics_hash", static_cast<std::int64_t>(physics_hash(scene.resolved)));
  w.put("run/last_frame", ses.last_frame);
  w.put("run/wall_s", ses.wall_before + (now_seconds() - ses.start));
  visit_result(r, RecordSaver{w, "run/result/"});
  save_pose_ranges(r, w);
  w.put("run/has_contact", r.contact.has_value());
  if (r.contact) visit_contact(*r.contact, RecordSaver{w, "run/contact/"});
  w.put("run/has_equilibrium", r.equilibrium.has_value());
  if (r.equilibrium) visit_equilibrium(*r.equilibrium, RecordSaver{w, "run/equilibrium/"});
  w.put("run/has_recorder", rec != nullptr);
  if (rec) rec->save_state(w);
  ses.guard->save_state(w);
  out.save_state(w, ses.last_frame);
  const fs::path path = checkpoint_path(out.out_dir(), step);
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  w.write(path);
  prune_checkpoints(out.out_dir(), step, scene.output.keep_checkpoints);
  logger().info("checkpoint after step {}: {} ({:.3g} MB in {:.3g} s)", step, path.string(),
                1e-6 * static_cast<double>(w.bytes()), now_seconds() - t0);
  return path;
}

/// A stop requested before the next step, as this process sees it: the reason ("signal",
/// "stop_file", "wall_time") and the one-line message, or nothing.
std::optional<std::pair<std::string, std::string>> stop_request_here(const RunOptions& opt,
                                                                     const fs::path& stop_file,
                                                                     const Session& ses,
                                                                     double longest_step,
                                                                     double longest_checkpoint) {
  if (opt.stop && opt.stop->load())
    return std::pair{std::string("signal"), std::string("interrupted")};
  std::error_code ec;
  if (fs::exists(stop_file, ec))
    return std::pair{std::string("stop_file"), fmt::format("stopped by '{}'", stop_file.string())};
  if (opt.wall_time && longest_step > 0.0) {
    const double elapsed = now_seconds() - ses.begin;
    const double checkpoint = longest_checkpoint > 0.0 ? longest_checkpoint : longest_step;
    if (elapsed + 1.25 * longest_step + checkpoint > *opt.wall_time)
      return std::pair{std::string("wall_time"),
                       fmt::format("stopped before the wall time runs out ({:.0f} of {:.0f} s "
                                   "used, the longest step took {:.3g} s)",
                                   elapsed, *opt.wall_time, longest_step)};
  }
  return std::nullopt;
}

/// stop_request_here on rank 0, the same answer on every rank (signals, the file and the
/// clock can differ between ranks; every rank must stop after the same step).
std::optional<std::pair<std::string, std::string>> stop_request(const RunOptions& opt,
                                                                const fs::path& stop_file,
                                                                const Session& ses,
                                                                double longest_step,
                                                                double longest_checkpoint) {
  std::optional<std::pair<std::string, std::string>> stop;
  if (is_root_rank())
    stop = stop_request_here(opt, stop_file, ses, longest_step, longest_checkpoint);
  if (simulation_rank_count() == 1) return stop;
  const std::string reason = root_decides(stop ? stop->first : std::string());
  const std::string message = root_decides(stop ? stop->second : std::string());
  if (reason.empty()) return std::nullopt;
  return std::pair{reason, message};
}

/// The stats row's solver and equilibrium columns from a step's report, and the run's
/// counters; returns the fluid solves of an iterated coupling scheme (0 otherwise).
int record_report(const coupling::FsiStepReport& rep, RunRecorder* fluid, StepStats& row,
                  RunResult& r) {
  int fluid_solves = 0;
  const std::optional<solid::ContactReport>& bc =
      rep.coupled ? rep.coupled->body_contact : rep.solid->body_contact;
  row.contact.reset();
  if (bc) {
    ContactStepStats c;
    c.pairs = bc->active;
    c.min_gap = bc->min_gap;
    c.force = bc->force;
    c.crossings = bc->crossings;
    c.rounds = bc->rounds;
    c.seconds = row.phases.get("contact");
    row.contact = c;
    if (r.contact) r.contact->add(c);
  }
  if (rep.coupled) {
    // two-way: the bodies and the fluid advance together (coupling/scheme.hpp)
    const coupling::CoupledStepReport& c = *rep.coupled;
    row.solver_iterations = c.solve.iterations + c.solid_iterations;
    row.solver_residual = c.solve.residual;
    row.contacts = c.contacts;
    r.solver_iterations += row.solver_iterations;
    if (!c.solve.converged) ++r.unconverged_steps;  // the recorder has logged it
    const bool iterated = coupling::is_iterated(c.scheme);
    row.equilibrium_iterations = iterated ? c.equilibrium.iterations : 0;
    row.equilibrium_evaluations = iterated ? c.equilibrium.evaluations : 0;
    fluid_solves = c.fluid_solves;
    row.coupled = fluid->coupled_stats();
  } else {
    const solid::SolidStepReport& s = *rep.solid;
    row.solver_iterations = s.iterations;
    row.solver_residual = s.residual;
    row.contacts = s.contacts;
    r.solver_iterations += s.iterations;
    if (!s.converged) ++r.unconverged_steps;  // SolidWorld::step has logged it
    row.equilibrium_iterations = s.equilibrium_iterations;
    row.equilibrium_evaluations = s.equilibrium_evaluations;
  }
  return fluid_solves;
}

/// Under mpirun every rank advances the same state (core/ranks.hpp): check, from the step's
/// energies and fluid figures, that they still do.
/// @throws InternalError if the ranks disagree.
void check_ranks_agree(const StepStats& row) {
  if (simulation_rank_count() == 1) return;
  double sum = row.kinetic_energy + 3.0 * row.elastic_energy + 5.0 * row.gravity_potential;
  if (row.fluid) {
    for (const double v :
         {row.fluid->fluid_kinetic_energy, row.fluid->smoke_mass, row.fluid->pressure_residual})
      if (std::isfinite(v)) sum = 7.0 * sum + v;
  }
  TETFSI_REQUIRE(InternalError, same_on_all_ranks(sum),
                 "the MPI ranks' states differ after this step (rank {} has {:.17g}): every "
                 "rank must compute the same; run with one rank and report this",
                 rank_index(), sum);
}

/// The loop of a dynamic run: steps ses.first_step..n, a frame on the output.every schedule,
/// a stats row per step, checkpoints; a stop request (signal, OUT/STOP, wall time) or a failed
/// step ends it with the output complete up to the last good step.
class DynamicLoop {
 public:
  DynamicLoop(const Scene& scene, coupling::FsiSimulation& sim, RunRecorder* fluid,
              OutputWriter& out, const RunOptions& opt, RunResult& r, Session& ses)
      : m_scene(scene),
        m_sim(sim),
        m_fluid(fluid),
        m_out(out),
        m_opt(opt),
        m_r(r),
        m_ses(ses),
        m_dt(scene.time.dt),
        m_n(scene.time.num_steps()),
        m_every(std::max(1, scene.output.every)),
        m_progress(opt.progress, m_n, ses.first_step - 1),
        m_last_frame(ses.last_frame),
        m_stop_file(out.out_dir() / "STOP") {}

  void run() {
    m_r.steps_planned = m_n;
    m_r.dt = m_dt;
    for (int step = m_ses.first_step; step <= m_n; ++step) {
      if (stopped_before(step)) return;
      const double t0 = now_seconds();
      int fluid_solves = 0;  // iterated coupling schemes
      if (!advance(step, fluid_solves)) return;
      finish_step(step, fluid_solves, t0);
    }
    m_progress.finish();
    m_r.completed = true;
  }

 private:
  /// When the run stops early, also write the last completed step as a frame if it is not one
  /// yet, so that the collection ends where the run did (best effort: the stop is reported).
  void write_last_good_frame(int done) {
    if (done <= m_last_frame) return;
    try {
      write_frame(m_out, m_sim, done, done * m_dt);
    } catch (const Error& e) {
      logger().warn("could not write the frame of step {}: {}", done, e.what());
    }
  }

  /// A checkpoint after step `done`, once; a failure is logged and the run goes on.
  void checkpoint(int done) {
    if (done == m_last_checkpoint) return;
    const double t0 = now_seconds();
    try {
      // Rank 0 writes the checkpoint (the state is the same on every rank).
      m_r.checkpoint = is_root_rank()
                           ? write_checkpoint(m_scene, m_sim, m_fluid, m_out, m_r, m_ses, done)
                           : checkpoint_path(m_out.out_dir(), done);
      m_last_checkpoint = done;
    } catch (const Error& e) {
      logger().error("no checkpoint after step {}: {}", done, one_line(e.what()));
    }
    m_longest_checkpoint = std::max(m_longest_checkpoint, now_seconds() - t0);
  }

  /// A stop asked for before `step` (signal, OUT/STOP, wall time): checkpoint, last frame,
  /// the reason in the result; true if the run stops.
  bool stopped_before(int step) {
    const auto stop = stop_request(m_opt, m_stop_file, m_ses, m_longest_step, m_longest_checkpoint);
    if (!stop) return false;
    m_progress.finish();
    checkpoint(step - 1);
    write_last_good_frame(step - 1);
    if (stop->first == "stop_file" && is_root_rank()) {
      std::error_code ec;
      fs::remove(m_stop_file, ec);  // consumed: a resumed run must not stop at once
    }
    m_r.interrupted = true;
    m_r.stop_reason = stop->first;
    m_r.error =
        fmt::format("{} after step {}/{} (t = {:.6g} s); the output is complete up to there; {}",
                    stop->second, step - 1, m_n, (step - 1) * m_dt,
                    m_last_checkpoint == step - 1 ? "resume with: " + resume_command(m_r)
                                                  : std::string("no checkpoint could be written"));
    return true;
  }

  /// The simulation's step, its figures into the row and, on schedule, a frame. On failure
  /// the world is back at the last good step, its frame written, the error in the result.
  bool advance(int step, int& fluid_solves) {
    const double t = step * m_dt;
    solid::SolidWorld& world = m_sim.world();
    m_row.phases.reset();
    m_last_good.save(world);
    m_ses.guard->before_step(world);
    try {
      const coupling::FsiStepReport rep = m_sim.step(m_dt, m_row.phases);
      if (const auto diverged = m_ses.guard->after_step(world, rep)) throw SolverError(*diverged);
      if (m_fluid) {
        m_fluid->record(rep, m_sim);
        m_row.fluid = m_fluid->stats();
      }
      fluid_solves = record_report(rep, m_fluid, m_row, m_r);
      if (step % m_every == 0 || step == m_n) {
        ScopedTimer timer(m_row.phases, "output");
        write_frame(m_out, m_sim, step, t);
        m_last_frame = step;
        // A frame off the schedule (the last step's) is not one of a longer run's frames.
        if (step % m_every == 0) m_ses.last_frame = step;
      }
      fill_energies(world, m_row);
      fill_poses(world, m_row, m_r);
      check_ranks_agree(m_row);
    } catch (const Error& e) {
      m_progress.finish();
      m_last_good.restore(world);  // the summary reports the state after the last good step
      write_last_good_frame(step - 1);
      m_r.error =
          one_line(fmt::format("step {}/{} (t = {:.6g} s) failed: {}", step, m_n, t, e.what()));
      return false;
    }
    return true;
  }

  /// The step's stats row, the equilibrium totals, the progress and a scheduled checkpoint.
  void finish_step(int step, int fluid_solves, double t0) {
    const double t = step * m_dt;
    m_row.phases.add("total", now_seconds() - t0);
    m_longest_step = std::max(m_longest_step, now_seconds() - t0);
    m_row.step = step;
    m_row.time = t;
    m_row.dt = m_dt;
    m_out.write_stats(m_row);
    if (m_r.equilibrium) {
      EquilibriumSummary& e = *m_r.equilibrium;
      e.steps += 1;
      e.max_iterations = std::max(e.max_iterations, m_row.equilibrium_iterations);
      e.iterations += m_row.equilibrium_iterations;
      e.evaluations += m_row.equilibrium_evaluations;
      e.fluid_solves += fluid_solves;
    }
    m_r.steps_done = step;
    m_r.end_time = t;
    m_progress.update(step, t);
    const int every = m_scene.output.checkpoint_every;
    if (every > 0 && (step % every == 0 || step == m_n)) checkpoint(step);
  }

  const Scene& m_scene;
  coupling::FsiSimulation& m_sim;
  RunRecorder* m_fluid;
  OutputWriter& m_out;
  const RunOptions& m_opt;
  RunResult& m_r;
  Session& m_ses;
  const double m_dt;
  const int m_n;
  const int m_every;
  Progress m_progress;
  StepStats m_row;
  StateSnapshot m_last_good;
  int m_last_frame;  ///< step of the last frame written, on schedule or not
  double m_longest_step = 0.0, m_longest_checkpoint = 0.0;
  int m_last_checkpoint = -1;
  const fs::path m_stop_file;
};

void run_dynamic(const Scene& scene, coupling::FsiSimulation& sim, RunRecorder* fluid,
                 OutputWriter& out, const RunOptions& opt, RunResult& r, Session& ses) {
  DynamicLoop(scene, sim, fluid, out, opt, r, ses).run();
}

/// The equilibrium summary a dynamic run starts with, if it iterates to equilibrium: an
/// iterated coupling scheme in a two-way run, else a nonlinear integrator of the bodies.
std::optional<EquilibriumSummary> equilibrium_summary(const Scene& scene) {
  EquilibriumSummary e;
  e.iteration_limit = scene.solid.equilibrium.max_iterations;
  if (scene.two_way()) {
    const coupling::Scheme s = scene.coupling->params.scheme;
    if (!coupling::is_iterated(s)) return std::nullopt;
    e.method = coupling::to_string(s);
    e.via = "coupling.scheme";
    return e;
  }
  if (scene.solid.integrator == solid::Integrator::Linearized) return std::nullopt;
  e.method = solid::to_string(scene.solid.integrator);
  e.via = "solid.integrator";
  return e;
}

void run_static(const Scene& scene, coupling::FsiSimulation& sim, RunRecorder* fluid,
                OutputWriter& out, RunResult& r) {
  solid::SolidWorld& world = sim.world();
  r.steps_planned = 1;
  r.dt = 1.0;
  if (!world.obstacles.empty())
    logger().warn("scene '{}' is static: its {} obstacle(s) are ignored", scene.name,
                  world.obstacles.size());
  if (scene.coupling && scene.coupling->two_way)
    logger().warn(
        "scene '{}' is static: its coupling ({}) is ignored, the fluid is meshed "
        "around the bodies' equilibrium",
        scene.name, scene.coupling->scheme_name());
  solid::StaticSolveOptions so;
  so.rel_tol = scene.statics.rel_tol;
  so.max_iterations = scene.statics.max_iterations;
  so.load_steps = scene.statics.load_steps;
  so.linear_solver = world.linear_solver;
  StepStats row;
  StateSnapshot initial;
  initial.save(world);
  const double t0 = now_seconds();
  try {
    {
      ScopedTimer timer(row.phases, "solve");
      for (auto& body : world.bodies) {
        if (body.is_kinematic()) {
          logger().info("body '{}' is kinematic: it stays at its t = 0 pose in a static solve",
                        body.name());
          continue;
        }
        const solid::StaticSolveReport rep =
            solid::solve_static(body, body.external_forces(world.gravity), so);
        logger().info("body '{}': static equilibrium in {} Newton iterations (residual {:.3g})",
                      body.name(), rep.iterations, rep.residual);
        row.solver_iterations += rep.iterations;
        row.solver_residual = std::max(row.solver_residual, rep.residual);
      }
    }
    if (fluid) {
      sim.rebuild_at_rest(row.phases);
      row.fluid = fluid->stats();
    }
    {
      ScopedTimer timer(row.phases, "output");
      write_frame(out, sim, 1, 1.0);
    }
  } catch (const Error& e) {
    initial.restore(world);
    r.error = one_line(fmt::format("static solve failed: {}", e.what()));
    return;
  }
  row.phases.add("total", now_seconds() - t0);
  fill_energies(world, row);
  fill_poses(world, row, r);
  row.step = 1;
  row.time = 1.0;
  row.dt = 1.0;
  out.write_stats(row);
  r.solver_iterations = row.solver_iterations;
  r.steps_done = 1;
  r.end_time = 1.0;
  r.completed = true;
}

}  // namespace

coupling::FsiSimulation make_simulation(const Scene& scene, solid::SolidWorld world) {
  std::optional<coupling::FluidSetup> fluid;
  std::optional<coupling::CouplingParams> coupling;
  if (scene.fluid) {
    fluid = coupling::FluidSetup{scene.fluid->domain, scene.fluid->sizing, scene.fluid->params,
                                 std::nullopt};
    if (scene.fluid->grid_spec)
      fluid->grid = coupling::GridSetup{*scene.fluid->grid_spec, scene.fluid->grid.pressure_forces};
    if (scene.two_way()) coupling = scene.coupling->params;
  }
  return coupling::FsiSimulation(std::move(world), std::move(fluid), std::move(coupling));
}

namespace {

/// A stale OUT/STOP (left from before this run) would stop it after its first step.
void remove_stale_stop_file(const fs::path& out_dir) {
  if (!is_root_rank()) return;  // rank 0 owns the folder (stop_request)
  const fs::path stop = out_dir / "STOP";
  std::error_code ec;
  if (!fs::exists(stop, ec)) return;
  fs::remove(stop, ec);
  logger().warn("removed '{}', left from before this run (create it during a run to stop it)",
                stop.string());
}

/// The end of run_scene and resume_run: the wall seconds, final state and summaries, and
/// summary.json.
void finish_run(const solid::SolidWorld& world, const std::optional<RunRecorder>& fluid,
                OutputWriter& out, const Session& ses, RunResult& r) {
  r.wall_s = ses.wall_before + (now_seconds() - ses.start);
  r.threads = thread_count();
  r.ranks = rank_count();
  r.frames_written = out.frames_written();
  fill_final(world, r);
  if (fluid) {
    r.fluid = fluid->summary();
    r.coupling = fluid->coupling_summary();
  }
  try {
    out.write_summary(summary_json(r));
  } catch (const Error& e) {
    if (r.completed) throw;
    logger().warn("{}", e.what());  // the step error is the one to report
  }
}

/// The simulation of `scene` with its recorder installed, as run_scene and resume_run build it.
coupling::FsiSimulation build_simulation(const Scene& scene, RunResult& r,
                                         std::optional<RunRecorder>& fluid) {
  if (scene.fluid) start_amg_backends();  // before the meshes exist (linear_solver.hpp)
  const double t = now_seconds();
  solid::SolidWorld world0 = build_world(scene);
  r.build_s += now_seconds() - t;
  logger().info("scene '{}': {} bod{} built in {:.3g} s", scene.name, world0.bodies.size(),
                world0.bodies.size() == 1 ? "y" : "ies", now_seconds() - t);
  if (world0.contact.enabled) {
    r.contact.emplace();
    r.contact->gap = world0.contact.gap;
  }
  coupling::FsiSimulation sim = make_simulation(scene, std::move(world0));
  if (sim.has_fluid()) fluid.emplace(sim);
  return sim;
}

}  // namespace

RunResult run_scene(const Scene& scene_in, const RunOptions& opt) {
  TETFSI_REQUIRE(InputError, !opt.out_dir.empty(), "no output folder given");
  Session ses;
  ses.begin = now_seconds();
  const Scene scene = apply_overrides(scene_in, opt);
  RunResult r;
  r.scene_name = scene.name;
  r.mode = scene.mode == Mode::Static ? "static" : "dynamic";
  r.out_dir = opt.out_dir;

  std::optional<RunRecorder> fluid;
  coupling::FsiSimulation sim = build_simulation(scene, r, fluid);
  if (fluid) sim.set_mesh_observer(fluid->mesh_observer());
  const solid::SolidWorld& world = sim.world();

  ses.start = now_seconds();
  OutputWriter out(opt.out_dir, output_plan(scene), world);
  if (is_root_rank()) remove_earlier_checkpoints(opt.out_dir);
  bool initial_ok = true;
  if (fluid) {
    PhaseTimes unused;  // step 0 has no stats row
    try {
      sim.start(unused);
    } catch (const Error& e) {
      initial_ok = false;
      r.error = one_line(fmt::format("step 0 (t = 0 s) failed: {}", e.what()));
    }
  }
  write_frame(out, sim, 0, 0.0);
  RunRecorder* rec = fluid ? &*fluid : nullptr;
  if (!initial_ok) {
    r.steps_planned = scene.mode == Mode::Static ? 1 : scene.time.num_steps();
    r.dt = scene.mode == Mode::Static ? 1.0 : scene.time.dt;
  } else if (scene.mode == Mode::Static) {
    run_static(scene, sim, rec, out, r);
  } else {
    remove_stale_stop_file(opt.out_dir);
    r.equilibrium = equilibrium_summary(scene);
    ses.guard.emplace(world, divergence_scales(scene));
    run_dynamic(scene, sim, rec, out, opt, r, ses);
  }
  finish_run(world, fluid, out, ses, r);
  return r;
}

namespace {

std::string read_text_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// The checkpoint's run records checked before anything is built from them: their layout
/// version, the stored scene against its hash and against the folder's scene.resolved.json
/// (a checkpoint copied from another run's folder). Returns the stored resolved scene.
/// @throws CheckpointError naming the file and the fault.
nlohmann::json check_run_records(const CheckpointReader& ck, const fs::path& out_dir) {
  const auto version = ck.get_int("run/version");
  if (version != k_run_records_version)
    ck.fail(fmt::format("run/version: the run's records are of layout {}, this tetfsi reads {}",
                        version, k_run_records_version));
  const nlohmann::json stored = nlohmann::json::parse(ck.get_text("run/scene"), nullptr, false);
  if (!stored.is_object()) ck.fail("run/scene: not a JSON scene");
  if (static_cast<std::uint64_t>(ck.get_int("run/physics_hash")) != physics_hash(stored))
    ck.fail("run/scene: does not match its run/physics_hash");
  const fs::path folder_scene = out_dir / "scene.resolved.json";
  std::error_code ec;
  if (fs::exists(folder_scene, ec)) {
    const nlohmann::json here = nlohmann::json::parse(read_text_file(folder_scene), nullptr, false);
    if (here.is_object()) {
      if (auto d = first_difference(physics_part(here), physics_part(stored)))
        ck.fail(
            fmt::format("its scene is not this folder's ('{}'): {}", folder_scene.string(), *d));
    }
  }
  return stored;
}

}  // namespace

namespace {

/// Open the newest valid checkpoint of the run's folder into `ck` (older ones only with
/// --fallback) and return the run records' resolved scene.
/// @throws CheckpointError if there is none.
nlohmann::json open_newest_checkpoint(const ResumeOptions& ro,
                                      std::optional<CheckpointReader>& ck) {
  const RunOptions& opt = ro.run;
  const std::vector<CheckpointFile> files = list_checkpoints(opt.out_dir);
  if (files.empty())
    throw CheckpointError(fmt::format(
        "no checkpoint to resume from in '{}' (a run writes them with --checkpoint-every N, and "
        "when it is stopped)",
        checkpoint_dir(opt.out_dir).string()));
  nlohmann::json stored;
  for (auto it = files.rbegin(); it != files.rend() && !ck; ++it) {
    try {
      ck.emplace(it->path);
      stored = check_run_records(*ck, opt.out_dir);
    } catch (const CheckpointError& e) {
      ck.reset();
      const bool older = std::next(it) != files.rend();
      if (!ro.fallback)
        throw CheckpointError(fmt::format("{}{}", one_line(e.what()),
                                          older ? "; `tetfsi resume --fallback` resumes from the "
                                                  "previous checkpoint"
                                                : ""));
      logger().warn(
          "{}{}", one_line(e.what()),
          older ? fmt::format("; falling back to '{}'", std::next(it)->path.string()) : "");
    }
  }
  if (!ck)
    throw CheckpointError(
        fmt::format("no valid checkpoint in '{}'", checkpoint_dir(opt.out_dir).string()));
  return stored;
}

/// The checkpoint's scene with the allowed overrides; the physics must not change and the run
/// must have steps left after `step`.
Scene resumed_scene(const ResumeOptions& ro, const CheckpointReader& ck,
                    const nlohmann::json& stored, int step) {
  Scene scene = apply_overrides(
      parse_scene_text(ck.get_text("run/scene"), ck.get_text("run/scene_file"), ro.overrides),
      ro.run);
  if (auto d = first_difference(physics_part(stored), physics_part(scene.resolved)))
    throw InputError(fmt::format(
        "checkpoint '{}': the resumed scene differs in {} (a resumed run may change output.*, "
        "time.steps and time.end_time only)",
        ck.path().string(), *d));
  const int n = scene.time.num_steps();
  TETFSI_REQUIRE(InputError, n > step,
                 "checkpoint '{}' is at step {}, the run's last step is {}: give --steps N (more "
                 "than {}) or --end-time T to go on",
                 ck.path().string(), step, n, step);
  logger().info("resuming '{}' from '{}' (step {} of {})", ro.run.out_dir.string(),
                ck.path().string(), step, n);
  return scene;
}

/// The simulation, the run's figures and the session as the checkpoint left them.
void restore_run(const CheckpointReader& ck, int step, const Scene& scene,
                 coupling::FsiSimulation& sim, std::optional<RunRecorder>& fluid, RunResult& r,
                 Session& ses) {
  const solid::SolidWorld& world = sim.world();
  load_pose_ranges(ck, world.bodies.size(), r);
  if (ck.get_bool("run/has_contact") != r.contact.has_value())
    ck.fail("run/has_contact: the run's scene and the checkpoint's differ in contact");
  if (r.contact) visit_contact(*r.contact, RecordLoader{ck, "run/contact/"});
  sim.load_state(ck);  // instead of start(): the state after the checkpoint's step
  if (fluid) {
    if (!ck.get_bool("run/has_recorder")) ck.fail("run/has_recorder: the run had no fluid");
    fluid->load_state(ck);
    sim.set_mesh_observer(fluid->mesh_observer());
  }
  if (ck.get_bool("run/has_equilibrium")) {
    r.equilibrium.emplace();
    visit_equilibrium(*r.equilibrium, RecordLoader{ck, "run/equilibrium/"});
  }
  ses.guard.emplace(world, divergence_scales(scene));
  ses.guard->load_state(ck);
  ses.first_step = step + 1;
  ses.last_frame = static_cast<int>(ck.get_int("run/last_frame"));
  ses.wall_before = ck.get_double("run/wall_s");
}

}  // namespace

RunResult resume_run(const ResumeOptions& ro) {
  const RunOptions& opt = ro.run;
  TETFSI_REQUIRE(InputError, !opt.out_dir.empty(), "no output folder given");
  Session ses;
  ses.begin = now_seconds();
  std::optional<CheckpointReader> ck;
  const nlohmann::json stored = open_newest_checkpoint(ro, ck);
  const int step = static_cast<int>(ck->get_int("run/step"));
  const Scene scene = resumed_scene(ro, *ck, stored, step);

  RunResult r;
  r.scene_name = scene.name;
  r.mode = "dynamic";
  r.out_dir = opt.out_dir;
  r.resumed_from = step;
  visit_result(r, RecordLoader{*ck, "run/result/"});
  std::optional<RunRecorder> fluid;
  coupling::FsiSimulation sim = build_simulation(scene, r, fluid);
  restore_run(*ck, step, scene, sim, fluid, r, ses);

  ses.start = now_seconds();
  OutputWriter out(opt.out_dir, output_plan(scene), sim.world(), step);
  out.load_state(*ck);
  remove_stale_stop_file(opt.out_dir);
  ck.reset();  // its memory, before the run goes on
  run_dynamic(scene, sim, fluid ? &*fluid : nullptr, out, opt, r, ses);
  finish_run(sim.world(), fluid, out, ses, r);
  return r;
}

std::string resume_command(const RunResult& r) {
  return "tetfsi resume " + shell_quote(r.out_dir.string());
}

namespace {

/// summary.json's "bodies": name, size, the largest displacement and pose extremes of each.
nlohmann::json bodies_json(const RunResult& r) {
  nlohmann::json bodies = nlohmann::json::array();
  for (const auto& b : r.bodies)
    bodies.push_back({{"name", b.name},
                      {"nodes", b.nodes},
                      {"tets", b.tets},
                      {"max_displacement", b.max_displacement},
                      {"min_lowest", b.pose.min_lowest},
                      {"max_rotation_deg", b.pose.max_rotation_deg}});
  return bodies;
}

/// summary.json's "contact" (scenes with contact between bodies).
nlohmann::json contact_json(const ContactSummary& c) {
  return {{"gap", c.gap},
          {"min_gap", c.min_gap},
          {"steps_in_contact", c.steps_in_contact},
          {"max_pairs", c.max_pairs},
          {"max_force", c.max_force},
          {"crossings", c.crossings},
          {"seconds", c.seconds}};
}

/// summary.json's "fluid" (fluid scenes).
nlohmann::json fluid_json(const FluidSummary& f) {
  return {{"remeshes", f.remeshes},
          {"remesh_seconds", f.remesh_s},
          {"ms_per_remesh", f.ms_per_remesh()},
          {"max_remesh_seconds", f.max_remesh_s},
          {"cells", f.cells},
          {"vertices", f.vertices},
          {"min_dihedral_deg", f.min_dihedral_deg},
          {"max_slivers", f.max_slivers},
          {"fluid_steps", f.fluid_steps},
          {"fluid_seconds", f.fluid_s},
          {"pressure_iterations", f.pressure_iterations},
          {"unconverged_pressure_solves", f.unconverged_pressure_solves},
          {"max_divergence", f.max_divergence},
          {"max_cfl", f.max_cfl},
          {"smoke_mass", f.smoke_mass},
          {"kinetic_energy", f.fluid_kinetic_energy}};
}

/// summary.json's "coupling" (two-way runs).
nlohmann::json coupling_json(const CouplingSummary& c) {
  return {{"scheme", c.scheme},
          {"solver", c.solver},
          {"coupled_steps", c.coupled_steps},
          {"coupled_iterations", c.iterations},
          {"max_residual", c.max_residual},
          {"unconverged_solves", c.unconverged_solves},
          {"steps_at_round_off_floor", c.steps_at_floor},
          {"max_round_off_floor", c.max_floor},
          {"max_interface_power", c.max_interface_power},
          {"max_interface_imbalance", c.max_interface_imbalance},
          {"max_enclosed_regions", c.max_enclosed_regions},
          {"max_volume_drift", c.max_volume_drift},
          {"enclosed_volume", c.enclosed_volume},
          {"unpredicted_meshes", c.unpredicted_meshes},
          {"solid_iterations", c.solid_iterations},
          {"total_energy", c.total_energy}};
}

/// summary.json's "equilibrium" (runs that iterate to equilibrium).
nlohmann::json equilibrium_json(const EquilibriumSummary& e) {
  nlohmann::json j = {{"method", e.method},
                      {"via", e.via},
                      {"steps", e.steps},
                      {"max_iterations", e.max_iterations},
                      {"avg_iterations", e.avg_iterations()},
                      {"evaluations_per_step", e.evaluations_per_step()},
                      {"iterations", e.iterations},
                      {"evaluations", e.evaluations},
                      {"iteration_limit", e.iteration_limit}};
  if (e.via == "coupling.scheme") j["fluid_solves_per_step"] = e.fluid_solves_per_step();
  return j;
}

}  // namespace

std::string summary_json(const RunResult& r) {
  nlohmann::json j;
  j["scene"] = r.scene_name;
  j["mode"] = r.mode;
  j["completed"] = r.completed;
  j["interrupted"] = r.interrupted;
  j["stop_reason"] =
      r.stop_reason.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.stop_reason);
  j["checkpoint"] =
      r.checkpoint.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.checkpoint.string());
  if (r.resumed_from >= 0) j["resumed_from_step"] = r.resumed_from;
  j["error"] = r.error.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.error);
  j["steps"] = r.steps_done;
  j["steps_planned"] = r.steps_planned;
  j["dt"] = r.dt;
  j["end_time"] = r.end_time;
  j["build_seconds"] = r.build_s;
  j["wall_seconds"] = r.wall_s;
  j["ms_per_step"] = r.ms_per_step();
  j["threads"] = r.threads;
  j["ranks"] = r.ranks;
  j["frames_written"] = r.frames_written;
  j["solver_iterations"] = r.solver_iterations;
  j["unconverged_steps"] = r.unconverged_steps;
  j["output_dir"] = r.out_dir.string();
  j["energy"] = {{"kinetic", r.kinetic_energy},
                 {"elastic", r.elastic_energy},
                 {"gravity_potential", r.gravity_potential},
                 {"total", r.kinetic_energy + r.elastic_energy + r.gravity_potential}};
  j["bodies"] = bodies_json(r);
  if (r.contact) j["contact"] = contact_json(*r.contact);
  if (r.fluid) j["fluid"] = fluid_json(*r.fluid);
  if (r.coupling) j["coupling"] = coupling_json(*r.coupling);
  if (r.equilibrium) j["equilibrium"] = equilibrium_json(*r.equilibrium);
  return j.dump(2) + "\n";
}

namespace {

/// The summary's first line: the scene, how far it got, in how long, on what.
void print_headline(const RunResult& r, std::ostream& out) {
  // "2 threads", or under mpirun "2 ranks x 1 thread"
  const std::string on = fmt::format(
      "{}{} thread{}", r.ranks > 1 ? fmt::format("{} ranks x ", r.ranks) : std::string(), r.threads,
      r.threads == 1 ? "" : "s");
  if (r.mode == "static") {
    out << fmt::format(
        "scene '{}' (static): {} in {} Newton iterations, {:.3g} s wall on {}, {} frame{}\n",
        r.scene_name, r.completed ? "equilibrium" : "FAILED", r.solver_iterations, r.wall_s, on,
        r.frames_written, r.frames_written == 1 ? "" : "s");
  } else {
    out << fmt::format(
        "scene '{}' (dynamic): {}{}/{} steps of {:.6g} s to t = {:.6g} s in {:.3g} s wall "
        "({:.3g} ms/step) on {}, {} frame{}\n",
        r.scene_name, r.completed ? "" : (r.interrupted ? "INTERRUPTED after " : "FAILED after "),
        r.steps_done, r.steps_planned, r.dt, r.end_time, r.wall_s, r.ms_per_step(), on,
        r.frames_written, r.frames_written == 1 ? "" : "s");
  }
}

/// The summary's fluid lines: the remeshes and the flow.
void print_fluid_summary(const FluidSummary& f, std::ostream& out) {
  out << fmt::format(
      "fluid: {} remeshes, {:.3g} ms each on average (max {:.3g} ms); last mesh {} cells, {} "
      "vertices; min dihedral {:.3g} deg, at most {} slivers\n",
      f.remeshes, f.ms_per_remesh(), 1e3 * f.max_remesh_s, f.cells, f.vertices, f.min_dihedral_deg,
      f.max_slivers);
  if (f.fluid_steps > 0)
    out << fmt::format(
        "fluid flow: {} steps, {:.3g} ms each (transfer + forces + pressure), {:.3g} pressure "
        "iterations per step, max divergence {:.3g} 1/s, max CFL {:.3g}; smoke mass {:.6g} "
        "kg, kinetic energy {:.6g} J{}\n",
        f.fluid_steps, 1e3 * f.fluid_s / f.fluid_steps,
        static_cast<double>(f.pressure_iterations) / f.fluid_steps, f.max_divergence, f.max_cfl,
        f.smoke_mass, f.fluid_kinetic_energy,
        f.unconverged_pressure_solves > 0
            ? fmt::format("; {} unconverged pressure solves", f.unconverged_pressure_solves)
            : std::string());
}

/// The summary's coupling line.
void print_coupling_summary(const CouplingSummary& c, std::ostream& out) {
  out << fmt::format(
      "coupling: {} ({}), {} coupled steps, {:.3g} iterations per step, max residual {:.3g}, "
      "max |interface power| {:.3g} W, fluid + solid energy {:.6g} J",
      c.scheme, c.solver, c.coupled_steps,
      c.coupled_steps > 0 ? static_cast<double>(c.iterations) / c.coupled_steps : 0.0,
      c.max_residual, c.max_interface_power, c.total_energy);
  if (c.max_enclosed_regions > 0)
    out << fmt::format("; {} enclosed region{}, {:.6g} m^3, max volume drift {:.3g}",
                       c.max_enclosed_regions, c.max_enclosed_regions == 1 ? "" : "s",
                       c.enclosed_volume, c.max_volume_drift);
  if (c.unpredicted_meshes > 0)
    out << fmt::format("; {} step(s) meshed around t^n (x* not meshable)", c.unpredicted_meshes);
  if (c.unconverged_solves > 0)
    out << fmt::format("; {} unconverged coupled solves", c.unconverged_solves);
  if (c.steps_at_floor > 0)
    out << fmt::format(
        "; {} step(s) solved to their round-off floor (up to {:.3g}), above coupling.rel_tol",
        c.steps_at_floor, c.max_floor);
  out << "\n";
}

/// The summary's equilibrium line.
void print_equilibrium_summary(const EquilibriumSummary& e, std::ostream& out) {
  out << fmt::format(
      "equilibrium: {} ({}), {:.3g} iterations per step on average, at most {} (limit {}), "
      "{:.3g} residual evaluations per step",
      e.method, e.via, e.avg_iterations(), e.max_iterations, e.iteration_limit,
      e.evaluations_per_step());
  if (e.via == "coupling.scheme")
    out << fmt::format(", {:.3g} fluid solves per step", e.fluid_solves_per_step());
  out << "\n";
}

}  // namespace

void print_summary(const RunResult& r, std::ostream& out) {
  print_headline(r, out);
  out << fmt::format("output: {}\n", r.out_dir.string());
  out << fmt::format("energy (J): kinetic {:.6g}, elastic {:.6g}, gravity {:.6g}, total {:.6g}\n",
                     r.kinetic_energy, r.elastic_energy, r.gravity_potential,
                     r.kinetic_energy + r.elastic_energy + r.gravity_potential);
  for (const auto& b : r.bodies)
    out << fmt::format("body '{}': max |d| = {:.6g} m\n", b.name, b.max_displacement);
  if (r.contact) {
    const ContactSummary& c = *r.contact;
    out << fmt::format(
        "contact: gap {:.3g} m; smallest gap {:.3g} m ({:.3g} of the gap); {} steps in contact, "
        "at most {} pairs, largest total force {:.3g} N, {} crossings caught; {:.3g} s\n",
        c.gap, c.min_gap, c.min_gap / c.gap, c.steps_in_contact, c.max_pairs, c.max_force,
        c.crossings, c.seconds);
  }
  if (r.fluid && r.fluid->remeshes > 0) print_fluid_summary(*r.fluid, out);
  if (r.coupling) print_coupling_summary(*r.coupling, out);
  if (r.equilibrium) print_equilibrium_summary(*r.equilibrium, out);
  if (r.unconverged_steps > 0)
    out << fmt::format("warning: {} step(s) with an unconverged linear solve\n",
                       r.unconverged_steps);
}

size_t first_deformable_body(const solid::SolidWorld& world) {
  for (size_t b = 0; b < world.bodies.size(); ++b)
    if (!world.bodies[b].is_kinematic()) return b;
  return world.bodies.size();
}

Index end_node(const MatX3& rest, bool high) {
  const Vec3 lo = rest.colwise().minCoeff().transpose();
  const Vec3 hi = rest.colwise().maxCoeff().transpose();
  const Vec3 target(high ? hi.x() : lo.x(), 0.5 * (lo.y() + hi.y()), 0.5 * (lo.z() + hi.z()));
  Index node = 0;
  double best = std::numeric_limits<double>::infinity();
  for (Index v = 0; v < rest.rows(); ++v) {
    const double d = (rest.row(v).transpose() - target).squaredNorm();
    if (d < best) {
      best = d;
      node = v;
    }
  }
  return node;
}

void validate_scene(const Scene& scene, std::ostream& out) {
  solid::SolidWorld world = build_world(scene);
  output_file_names(output_plan(scene),
                    world);  // the checks OutputWriter makes before writing anything
  print_world_summary(scene, world, out);
  coupling::FsiSimulation sim = make_simulation(scene, std::move(world));
  if (!sim.has_fluid()) return;
  PhaseTimes phases;
  const double t = now_seconds();
  try {
    sim.start(phases);  // the t = 0 fluid mesh or grid: every check run makes at step 0
  } catch (const Error& e) {
    throw InputError(one_line(fmt::format("step 0 (t = 0 s) failed: {}", e.what())));
  }
  out << sim.fluid()->start_summary(now_seconds() - t);
}

void print_world_summary(const Scene& scene, const solid::SolidWorld& world, std::ostream& out) {
  out << fmt::format("scene '{}' ({}): ", scene.name,
                     scene.mode == Mode::Static ? "static" : "dynamic");
  if (scene.mode == Mode::Static)
    out << fmt::format("load steps {}, rel_tol {:.3g}\n", scene.statics.load_steps,
                       scene.statics.rel_tol);
  else
    out << fmt::format("dt = {:.6g} s, {} steps, a frame every {} ({})\n", scene.time.dt,
                       scene.time.num_steps(), scene.output.every, scene.output.compression);
  for (const auto& b : world.bodies) {
    if (b.is_kinematic()) {
      const solid::KinematicMotion& k = *b.kinematic;
      out << fmt::format(
          "body '{}': {} nodes, {} tets, mass {:.6g} kg, kinematic: velocity {} m/s, angular "
          "velocity {} deg/s about {}\n",
          b.name(), b.num_nodes(), b.num_tets(), b.total_mass(), fmt_vec(k.linear_velocity),
          fmt_vec(k.angular_velocity * (180.0 / M_PI)), fmt_vec(k.center));
    } else {
      out << fmt::format("body '{}': {} nodes, {} tets, mass {:.6g} kg, {} fixed DOFs\n", b.name(),
                         b.num_nodes(), b.num_tets(), b.total_mass(), b.num_fixed_dofs());
    }
  }
  if (world.bodies.empty()) out << "bodies: none\n";
  out << fmt::format("obstacles: {}\n", world.obstacles.size());
  if (scene.mode == Mode::Dynamic && !world.bodies.empty()) {
    const EquilibriumOptions& e = scene.solid.equilibrium;
    const std::optional<EquilibriumSummary> it = equilibrium_summary(scene);
    if (it) {
      out << fmt::format(
          "equilibrium: {} ({}), rtol {:.3g}, etol {:.3g}, stol {:.3g}, at most {} iterations "
          "per step{}, line search {}{}\n",
          it->method, it->via, e.rtol, e.etol, e.stol, e.max_iterations,
          it->method == "bfgs" ? fmt::format(" and {} updates", e.max_updates) : std::string(),
          e.line_search ? "on" : "off",
          it->method == "newton" ? std::string()
                                 : fmt::format(", starting matrix formed once per {}",
                                               e.keep_matrix ? "run" : "step"));
    } else if (!scene.two_way()) {
      out << fmt::format("solid integrator: linearized (trapezoid {})\n", scene.solid.trapezoid);
    }
  }
  if (scene.fluid) {
    const mesh::FluidDomain& d = scene.fluid->domain;
    const mesh::Sizing& z = scene.fluid->sizing;
    out << fmt::format(
        "fluid: box {}..{}, {} by default, {} patch{}; mesh surface_size {:.6g} m, far_size "
        "{:.6g} m, grading {:.6g}{}\n",
        fmt_vec(d.lo), fmt_vec(d.hi), mesh::to_string(d.default_kind), d.patches.size(),
        d.patches.size() == 1 ? "" : "es", z.surface_size, z.far_size, z.grading,
        z.max_cells > 0 ? fmt::format(", at most {} cells", z.max_cells) : std::string());
    const fluid::FluidParams& fp = scene.fluid->params;
    out << fmt::format(
        "fluid physics: density {:.6g} kg/m^3, gravity {}, reconstruction {}, pressure solver "
        "{}, {} source{}{}\n",
        fp.density, scene.fluid->gravity ? fmt_vec(fp.gravity) + " m/s^2" : std::string("off"),
        fluid::to_string(fp.reconstruction), to_string(fp.solver), fp.sources.size(),
        fp.sources.size() == 1 ? "" : "s",
        fp.refine.size > 0 ? fmt::format(", refine to {:.6g} m", fp.refine.size) : std::string());
    if (fp.enclosed_density > 0)
      out << fmt::format("fluid enclosed in closed bodies: density {:.6g} kg/m^3\n",
                         fp.enclosed_density);
    if (scene.coupling && scene.coupling->two_way) {
      const coupling::CoupledOptions& o = scene.coupling->params.solve;
      out << fmt::format(
          "coupling: {} two-way{}, solver {}, rel_tol {:.3g}, max_iterations {}, volume of "
          "enclosed regions {}\n",
          scene.coupling->scheme_name(), scene.two_way() ? "" : " (ignored: static)",
          coupling::to_string(o.solver), o.rel_tol, o.max_iterations,
          o.conserve_volume ? "conserved" : "not corrected");
    } else {
      out << "coupling: none (one-way: the bodies move the fluid)\n";
    }
  }
}

}  // namespace tetfsi::app
