/// @file bench_step.cpp
/// `tetfsi bench step` (bench_step.hpp).
#include "tools/bench_step.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "coupling/simulation.hpp"
#include "fluid/operators.hpp"
#include "mesh/remesh.hpp"
#include "tools/output.hpp"
#include "tools/run.hpp"
#include "tools/scene.hpp"

namespace tetfsi::tools {

namespace {

/// A temporary folder for the frames, removed with its contents on destruction.
struct ScratchDir {
  std::filesystem::path path;
  ScratchDir() {
    path = std::filesystem::temp_directory_path() / fmt::format("tetfsi_bench_step_{}", getpid());
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

/// The scene's fluid with every mesh size scaled by `s` and no cell budget.
Scene scaled(const Scene& scene, double s) {
  Scene sc = scene;
  FluidSpec& f = *sc.fluid;
  f.sizing.surface_size *= s;
  f.sizing.far_size *= s;
  f.sizing.max_cells = 0;
  if (f.params.refine.size > 0) f.params.refine.size *= s;
  return sc;
}

/// Mean seconds per timed step of each phase (and of the whole step).
struct StepFigures {
  double step = 0, solid = 0, remesh = 0, transfer = 0, forces = 0, assembly = 0, solve = 0,
         output = 0, iterations = 0;
  double remesh_delaunay = 0;  ///< of remesh: the remesher's own Delaunay (RemeshReport)
  double other() const {
    return std::max(0.0, step - (solid + remesh + transfer + forces + assembly + solve + output));
  }
};

struct Case {
  double scale = 1.0;
  Index cells = 0, vertices = 0;
  double warmup_s = 0.0;
  StepFigures mean;
  double delaunay_s = 0.0, poisson_s = 0.0, poisson_setup_s = 0.0;
  int floor_iterations = 0;
  bool floor_converged = false;
  double floor_s() const { return delaunay_s + poisson_s; }
};

/// The scene's fluid, one-way, around `world`.
coupling::FsiSimulation make_one_way(const Scene& scene, solid::SolidWorld world) {
  return coupling::FsiSimulation(std::move(world),
                                 coupling::FluidSetup{scene.fluid->domain, scene.fluid->sizing,
                                                      scene.fluid->params, std::nullopt});
}

/// Cells of the scene's fluid mesh at t = 0 (one remesh).
Index cells_at_start(const Scene& scene) {
  coupling::FsiSimulation sim = make_one_way(scene, build_world(scene));
  PhaseTimes unused;
  sim.start(unused);
  return sim.mesh()->num_tets();
}

/// The floor's pressure solve on `m`: fluid::project of a random interior face field
/// (uniform in [−1, 1] m/s, walls and other boundaries 0) with a fresh AMG solver at the
/// scene's tolerance; seconds = setup + solve (the assembly is not in the floor).
/// @param setup_s the AMG setup's share (s)
double poisson_floor(const mesh::TetMesh& m, const fluid::FluidParams& p, int& iterations,
                     bool& converged, double& setup_s) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  VecX u = VecX::Zero(m.num_faces());
  for (Index f = 0; f < m.num_faces(); ++f)
    if (!m.is_boundary(f)) u[f] = uni(rng);
  SolverOptions o;
  o.rel_tol = p.solver_rel_tol;
  o.max_iterations = p.solver_max_iterations;
  o.symmetric = true;
  const auto solver = make_linear_solver(SolverKind::Amg, o);
  VecX q;
  const fluid::ProjectionReport r = fluid::project(m, p.min_dual_fraction, VecX(), u, q, *solver);
  iterations = r.iterations;
  converged = r.converged;
  setup_s = r.setup_s;
  return r.setup_s + r.solve_s;
}

Case run_case(const Scene& scene, double scale, int steps, const std::filesystem::path& dir) {
  const Scene sc = scaled(scene, scale);
  const double dt = sc.time.dt;
  const Compression compression = parse_compression(sc.output.compression);
  coupling::FsiSimulation sim = make_one_way(sc, build_world(sc));
  mesh::RemeshReport last_remesh;
  sim.set_mesh_observer([&](const mesh::TetMesh&, const mesh::RemeshReport& r, double,
                            PhaseTimes&) { last_remesh = r; });
  {
    PhaseTimes unused;
    sim.start(unused);
  }
  logger().debug("bench step: scale {:.4g}: {} cells at t = 0", scale, sim.mesh()->num_tets());
  Case c;
  c.scale = scale;
  StepFigures& mean = c.mean;
  const int timed = steps - 1;
  for (int k = 0; k < steps; ++k) {
    PhaseTimes ph;
    const double t0 = now_seconds();
    const coupling::FsiStepReport rep = sim.step(dt, ph);
    const double solid_s = rep.solid_s;
    {
      ScopedTimer timer(ph, "output");
      const FluidFrameFields fields = frame_fields(sim.fluid());
      write_fluid_vtu(dir / fmt::format("fluid_{:06d}.vtu", k), *sim.mesh(), compression, &fields);
    }
    const double step_s = now_seconds() - t0;
    logger().debug("bench step: scale {:.4g}, step {}: {:.3f} s, {} cells", scale, k + 1, step_s,
                   sim.mesh()->num_tets());
    if (k == 0) {
      c.warmup_s = step_s;
      continue;
    }
    mean.step += step_s / timed;
    mean.solid += solid_s / timed;
    mean.remesh += ph.get("remesh") / timed;
    mean.transfer += ph.get("transfer") / timed;
    mean.forces += ph.get("forces") / timed;
    mean.assembly += ph.get("pressure_assembly") / timed;
    mean.solve += ph.get("pressure_solve") / timed;
    mean.output += ph.get("output") / timed;
    mean.remesh_delaunay += last_remesh.seconds_delaunay / timed;
    mean.iterations += static_cast<double>(rep.fluid->iterations) / timed;
  }
  const mesh::TetMesh& m = *sim.mesh();
  c.cells = m.num_tets();
  c.vertices = m.num_vertices();
  const double t1 = now_seconds();
  const MatX4i tets = mesh::delaunay_tets(m.vertices);
  c.delaunay_s = now_seconds() - t1;
  (void)tets;
  c.poisson_s =
      poisson_floor(m, sc.fluid->params, c.floor_iterations, c.floor_converged, c.poisson_setup_s);
  return c;
}

}  // namespace

int bench_step(const std::filesystem::path& scene_file, const BenchStepOptions& opt,
               std::ostream& out) {
  const Scene scene = load_scene(scene_file);
  TETFSI_REQUIRE(InputError, scene.fluid.has_value(),
                 "{}: bench step needs a fluid scene (no 'fluid' section)", scene_file.string());
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "{}: bench step needs a dynamic scene (mode is 'static')", scene_file.string());
  TETFSI_REQUIRE(InputError, !scene.fluid->grid_spec,
                 "{}: bench step times the tet mesh's steps; fluid.discretization \"grid\" is not "
                 "benchmarked yet (time it with `tetfsi run`: stats.csv has the phases)",
                 scene_file.string());
  TETFSI_REQUIRE(InputError, opt.steps >= 2,
                 "bench step: --steps must be at least 2 (the first is a warm-up), got {}",
                 opt.steps);
  for (const double s : opt.scales)
    TETFSI_REQUIRE(InputError, std::isfinite(s) && s > 0,
                   "bench step: --sizes: every scale factor must be positive, got {}", s);

  std::vector<double> scales = opt.scales;
  Index base_cells = 0;
  if (scales.empty()) {
    base_cells = cells_at_start(scaled(scene, 1.0));
    TETFSI_REQUIRE(MeshError, base_cells > 0, "{}: the fluid mesh at t = 0 has no cells",
                   scene_file.string());
    for (const double target : opt.target_cells)
      scales.push_back(std::cbrt(static_cast<double>(base_cells) / target));
  }

  fmt::print(out,
             "tetfsi bench step: {} ('{}'), dt = {:.6g} s, {} steps per case (the first is a "
             "warm-up; figures are means of the others)\n",
             scene_file.string(), scene.name, scene.time.dt, opt.steps);
  if (base_cells > 0)
    fmt::print(out,
               "scene mesh sizes give {} cells at t = 0; scale = (that / target)^(1/3) for "
               "targets {}\n",
               base_cells, fmt::join(opt.target_cells, ", "));
  fmt::print(out,
             "step = solid + remesh + transfer + forces + pressure assembly + solve + output "
             "(one fluid frame);\nfloor = CGAL Delaunay of the last mesh's vertices + one AMG "
             "pressure solve (setup + solve) on it, same run\n\n");
  fmt::print(out,
             "{:>6} {:>8} {:>8} {:>8} {:>6} | {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} | "
             "{:>5} | {:>7} {:>7} {:>5}\n",
             "scale", "cells", "step_s", "floor_s", "ratio", "solid", "remesh", "transf", "forces",
             "assem", "solve", "output", "other", "iters", "delny_s", "poiss_s", "f_it");

  const ScratchDir dir;
  nlohmann::json cases = nlohmann::json::array();
  for (const double s : scales) {
    const Case c = run_case(scene, s, opt.steps, dir.path);
    const StepFigures& f = c.mean;
    const double ratio = f.step / c.floor_s();
    fmt::print(out,
               "{:>6.3f} {:>8} {:>8.3f} {:>8.3f} {:>6.2f} | {:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f} "
               "{:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f} | {:>5.1f} | {:>7.3f} {:>7.3f} {:>5}\n",
               c.scale, c.cells, f.step, c.floor_s(), ratio, f.solid, f.remesh, f.transfer,
               f.forces, f.assembly, f.solve, f.output, f.other(), f.iterations, c.delaunay_s,
               c.poisson_s, c.floor_iterations);
    out.flush();
    if (!c.floor_converged)
      logger().warn("bench step: the floor's pressure solve at scale {:.4g} did not converge",
                    c.scale);
    cases.push_back({{"scale", c.scale},
                     {"cells", c.cells},
                     {"vertices", c.vertices},
                     {"step_s", f.step},
                     {"floor_s", c.floor_s()},
                     {"ratio", ratio},
                     {"phases",
                      {{"remesh", f.remesh},
                       {"transfer", f.transfer},
                       {"forces", f.forces},
                       {"assembly", f.assembly},
                       {"solve", f.solve},
                       {"output", f.output},
                       {"solid", f.solid},
                       {"other", f.other()}}},
                     {"iterations", f.iterations},
                     {"delaunay_s", c.delaunay_s},
                     {"poisson_s", c.poisson_s},
                     {"poisson_setup_s", c.poisson_setup_s},
                     {"remesh_delaunay_s", f.remesh_delaunay},
                     {"floor_iterations", c.floor_iterations},
                     {"warmup_s", c.warmup_s}});
  }
  fmt::print(out,
             "\nphases (s, mean per step): remesh = the fluid mesh around the bodies, transf = "
             "semi-Lagrangian transfer,\nassem = pressure matrix and right-hand side, solve = "
             "AMG setup + solve, output = mesh quality\nsummary + fields + one .vtu; iters = "
             "pressure iterations per step, f_it = the floor solve's.\n");
  if (!opt.json_path.empty()) {
    const nlohmann::json j{{"scene", scene.name}, {"steps", opt.steps}, {"cases", cases}};
    write_text_file_atomic(opt.json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace tetfsi::tools
