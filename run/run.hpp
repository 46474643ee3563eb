#pragma once
/// @file run.hpp
/// The run loop behind `tetfsi run`: build the world of a scene, step it, write frames,
/// stats and a summary (layout in io/output.hpp), report progress.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "coupling/simulation.hpp"
#include "io/output.hpp"
#include "run/run_stats.hpp"
#include "scene/scene.hpp"
#include "solid/pose.hpp"
#include "solid/world.hpp"

namespace tetfsi::app {

/// How progress is shown on stderr.
enum class ProgressMode {
  Auto,   ///< Tty if stderr is a terminal, Plain otherwise
  Tty,    ///< one live line rewritten with '\r': step i/N, t, ms/step, ETA
  Plain,  ///< a line every ~2 s or 10% of the steps
  Off,
};

inline constexpr EnumNames<ProgressMode, 4> k_progress_mode_names{"progress mode",
                                                                  {{{ProgressMode::Auto, "auto"},
                                                                    {ProgressMode::Tty, "tty"},
                                                                    {ProgressMode::Plain, "plain"},
                                                                    {ProgressMode::Off, "off"}}}};
/// "auto" | "tty" | "plain" | "off". @throws InputError naming the value.
ProgressMode parse_progress_mode(const std::string& name);

struct RunOptions {
  std::filesystem::path out_dir;   ///< required: the output folder (created if missing)
  std::optional<int> steps;        ///< overrides the scene's step count (dynamic mode)
  std::optional<double> end_time;  ///< overrides it by end time: ceil(T / dt) steps
  ProgressMode progress = ProgressMode::Auto;
  /// If set, checked before every step: once true the run stops cleanly (output complete up to
  /// the last step, a checkpoint, summary written, `interrupted` set, stop_reason "signal").
  /// The CLI sets it on Ctrl-C / SIGTERM.
  const std::atomic<bool>* stop = nullptr;
  /// Override output.checkpoint_every / output.keep_checkpoints (recorded in `resolved`).
  std::optional<int> checkpoint_every;
  std::optional<int> keep_checkpoints;
  /// Seconds the run may take from its start (`--wall-time`): before each step, if the longest
  /// step so far (× 1.25) and a checkpoint's write would end past it, the run stops there with
  /// a checkpoint (stop_reason "wall_time").
  std::optional<double> wall_time;
};

/// `tetfsi resume OUT`: go on from the newest valid checkpoint of `run.out_dir`.
struct ResumeOptions {
  /// out_dir, steps / end_time (the whole run's length, default the stored scene's), progress,
  /// stop, checkpoint options and wall time, as for a run.
  RunOptions run;
  /// `--set key=value` on the checkpoint's stored scene: output.*, time.steps, time.end_time
  /// (and description) only; anything else changes the physics and is an error.
  std::vector<std::string> overrides;
  /// A newest checkpoint that cannot be used is an error, or with `fallback` a warning and
  /// the next older one is tried.
  bool fallback = false;
};

/// The extremes of a body's pose over a run's stats.csv rows (solid/pose.hpp): the lowest
/// `<body>_lowest` and the largest `<body>_rotation_deg`; NaN before the first row.
struct BodyPoseRange {
  double min_lowest = NAN;        ///< m
  double max_rotation_deg = NAN;  ///< degrees
  void add(const solid::BodyPose& p) {
    min_lowest = std::fmin(min_lowest, p.lowest);  // fmin: NaN only if both are
    max_rotation_deg = std::fmax(max_rotation_deg, p.rotation_deg);
  }
};

/// Contact between bodies over a run (the scene's `contact`, solid/contact.hpp).
struct ContactSummary {
  double gap = 0.0;          ///< d̂ (m)
  double min_gap = NAN;      ///< the smallest contact_min_gap of the rows (m)
  Index max_pairs = 0;       ///< the most pairs in one step
  double max_force = 0.0;    ///< the largest contact_force (N)
  int steps_in_contact = 0;  ///< steps with at least one pair
  Index crossings = 0;       ///< pairs found crossed, summed
  double seconds = 0.0;      ///< contact_s summed
  void add(const ContactStepStats& c) {
    min_gap = std::fmin(min_gap, c.min_gap);
    max_pairs = std::max(max_pairs, c.pairs);
    max_force = std::max(max_force, c.force);
    steps_in_contact += c.pairs > 0 ? 1 : 0;
    crossings += c.crossings;
    seconds += c.seconds;
  }
};

/// Final state of one body.
struct BodySummary {
  std::string name;
  Index nodes = 0;
  Index tets = 0;
  double max_displacement = 0.0;  ///< max over nodes of |d| (m)
  BodyPoseRange pose;             ///< over the run's rows
};

/// The equilibrium iteration over a run [BatheSonnad80] (core/equilibrium.hpp): runs whose
/// bodies step with a nonlinear solid.integrator, or two-way runs with an iterated coupling
/// scheme (bfgs, modified_newton, newton).
struct EquilibriumSummary {
  std::string method;  ///< "bfgs", "modified_newton" or "newton"
  std::string via;     ///< the scene key that chose it: "solid.integrator" or "coupling.scheme"
  int iteration_limit = 0;     ///< solid.max_iterations
  int steps = 0;               ///< completed steps
  int max_iterations = 0;      ///< the most iterations of one step
  long long iterations = 0;    ///< summed over steps (a step: the most of any body)
  long long evaluations = 0;   ///< residual evaluations, summed over steps (and bodies)
  long long fluid_solves = 0;  ///< coupling.scheme: fluid solves, summed (0 otherwise)
  double avg_iterations() const { return steps > 0 ? double(iterations) / steps : 0.0; }
  double evaluations_per_step() const { return steps > 0 ? double(evaluations) / steps : 0.0; }
  double fluid_solves_per_step() const { return steps > 0 ? double(fluid_solves) / steps : 0.0; }
};

struct RunResult {
  bool completed = false;  ///< every step ran; false if a step failed (see `error`)
  bool interrupted =
      false;  ///< stopped on request (signal, OUT/STOP, wall time); `error` says where
  /// "signal" (the CLI exits with 130), "stop_file" or "wall_time" (exit 0) if interrupted
  std::string stop_reason;
  /// The last checkpoint this run wrote (empty: none): a stopped run's resume point.
  std::filesystem::path checkpoint;
  int resumed_from = -1;  ///< resumed runs: the step of the checkpoint the last part started at
  std::string error;      ///< one line: where and why the run stopped (empty if completed)
  std::string scene_name;
  std::string mode;           ///< "dynamic" or "static"
  int steps_planned = 0;      ///< steps requested (1 for static)
  int steps_done = 0;         ///< steps completed
  double dt = 0.0;            ///< s (1.0 pseudo-time for static)
  double end_time = 0.0;      ///< s, time of the last completed step
  double wall_s = 0.0;        ///< wall-clock seconds of the whole run (build excluded)
  double build_s = 0.0;       ///< seconds to build the world
  int threads = 1;            ///< the thread count of the parallel loops (core/parallel.hpp)
  int ranks = 1;              ///< MPI ranks (core/ranks.hpp; 1 without mpirun)
  int frames_written = 0;     ///< frames (each: one .vtu per body)
  int solver_iterations = 0;  ///< linear (dynamic) or Newton (static) iterations, summed
  int unconverged_steps = 0;  ///< steps whose linear solve reported converged = false
  std::filesystem::path out_dir;
  double kinetic_energy = 0.0;     ///< final, J
  double elastic_energy = 0.0;     ///< final, J
  double gravity_potential = 0.0;  ///< final, J
  std::vector<BodySummary> bodies;
  /// Per body, in body order: its pose extremes over the rows written so far (a resumed run:
  /// since step 1, through the checkpoint).
  std::vector<BodyPoseRange> pose_ranges;
  std::optional<FluidSummary> fluid;              ///< set for a scene with a fluid
  std::optional<ContactSummary> contact;          ///< set for a scene with contact
  std::optional<CouplingSummary> coupling;        ///< set for a two-way coupled run
  std::optional<EquilibriumSummary> equilibrium;  ///< set if the run iterates to equilibrium

  double ms_per_step() const { return steps_done > 0 ? 1e3 * wall_s / steps_done : 0.0; }
};

/// The simulation of a scene (its fluid and coupling, if any) around `world`
/// (build_world(scene)).
coupling::FsiSimulation make_simulation(const Scene& scene, solid::SolidWorld world);

/// Run a scene. Writes frame 0 at t = 0, then
///  - dynamic: `world.step(dt)` per step (then the fluid, one-way), or, two-way coupled
///    (Scene::two_way), the coupling scheme (coupling::FsiSimulation::step); a frame every
///    `output.every` steps and always the last one; a stats row every step;
///  - static: `solid::solve_static` on each body with f_e = external_forces(gravity) and the
///    scene's static options (kinematic bodies stay at their t = 0 pose), then frame 1 at
///    pseudo-time 1.0 and one stats row.
/// A scene may have no body (a fluid-only scene): the frames then hold the fluid mesh only.
/// A scene with a fluid also gets a fluid mesh built by mesh::remesh around every body's
/// boundary triangles at their current positions X + d: at t = 0 and after every step (timed
/// as the phase `remesh`), written with each frame and summarised in each stats row
/// (io/output.hpp). Before each remesh every body's boundary must lie strictly inside the
/// fluid box, else the step fails with a message naming the body.
/// Ends by writing summary.json. A step that throws a tetfsi::Error (e.g. SolverError:
/// diverged, or a MeshError from the remesh) does not throw out of here: the run stops, the
/// frames, the `.pvd` files and the stats rows written so far stay valid, the state after the
/// last good step is written as a frame if it is not one yet (with the fluid mesh built for
/// it), and the result says `completed = false` with a one-line `error` (also recorded in
/// summary.json). If the fluid mesh of t = 0 cannot be built, frame 0 has the bodies only and
/// no step is taken. A stop request (RunOptions::stop) ends the run the same way between two
/// steps, with `interrupted = true`.
/// @throws InputError / MeshError for a scene that cannot be built or an output folder that
///   cannot be written.
RunResult run_scene(const Scene& scene, const RunOptions& options);

/// `tetfsi resume`: the run of the output folder `options.run.out_dir` goes on from its newest
/// valid checkpoint (run/checkpoints.hpp) as if it had never stopped: the scene is the
/// checkpoint's stored one (with the allowed overrides), the simulation is rebuilt as
/// run_scene builds it and then given the checkpoint's state (FsiSimulation::load_state,
/// instead of start), and so are the run's counters, summaries, divergence budget and
/// collections. stats.csv keeps its rows up to the checkpoint's step and the collections their
/// frames up to it (later ones, from a run that went past it, are dropped), then both go on;
/// scene.resolved.json and summary.json describe the whole run. A restarted run equals the
/// continuous one bit for bit (every VTU array and every non-timing stats.csv column).
/// @throws CheckpointError naming the file (no checkpoint, or an unusable newest one without
///   `fallback`, or none usable), InputError for an override that changes the physics (naming
///   the first differing key and both values) or a run that is already at its last step.
RunResult resume_run(const ResumeOptions& options);

/// The command that continues a stopped run: "tetfsi resume OUT".
std::string resume_command(const RunResult& r);

/// The summary of a run as JSON text (what summary.json holds).
std::string summary_json(const RunResult& r);

/// Print a human-readable summary of a run (a few lines).
void print_summary(const RunResult& r, std::ostream& out);

/// Print one line per body (nodes, tets, mass, fixed DOFs, or "kinematic" with its motion;
/// "bodies: none" without any), the obstacle count and, for a fluid scene, its box, mesh and
/// physics, for `tetfsi validate`.
void print_world_summary(const Scene& scene, const solid::SolidWorld& world, std::ostream& out);
/// The first deformable (non-kinematic) body of `world`, or world.bodies.size() if none: the
/// body the benchmarks probe.
size_t first_deformable_body(const solid::SolidWorld& world);

/// The rest node closest to (lo.x, c.y, c.z) (`high`: (hi.x, c.y, c.z)) of the bounding box
/// lo..hi, centre c, of `rest`: a bar's or cantilever's end, the benchmarks' probe (the first
/// such node on a tie).
Index end_node(const MatX3& rest, bool high);

/// `tetfsi validate`: every check `run` makes before its first time step, without writing
/// anything: builds the bodies, checks their output file names, prints the summary
/// (print_world_summary), and in a fluid scene builds the t = 0 fluid mesh (or classifies
/// the grid) and prints its size: so "ok" means the run starts.
/// @throws InputError as `run` reports it ("step 0 (t = 0 s) failed: ..." for the fluid).
void validate_scene(const Scene& scene, std::ostream& out);

}  // namespace tetfsi::app
