/// @file bench_step.cpp
/// `tetfsi bench step` (bench_step.hpp).
#include "bench/bench_step.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "bench/bench_step_liquid.hpp"
#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "coupling/grid_fluid.hpp"
#include "coupling/simulation.hpp"
#include "coupling/tet_fluid.hpp"
#include "fluid/grid/projection.hpp"
#include "fluid/tet/operators.hpp"
#include "io/output.hpp"
#include "mesh/remesh.hpp"
#include "run/run.hpp"
#include "run/run_stats.hpp"
#include "scene/scene.hpp"

namespace tetfsi::app {

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
  LiquidPhases liquid;                     ///< a liquid scene (grid): its phases, per step
  std::optional<LiquidComparison> levels;  ///< a liquid scene: the level sets on its particles
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
  return coupling::tet_fluid(sim.fluid())->mesh().num_tets();
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
  logger().debug("bench step: scale {:.4g}: {} cells at t = 0", scale,
                 coupling::tet_fluid(sim.fluid())->mesh().num_tets());
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
      const FluidFrameFields fields = fluid::mesh_frame_fields(*coupling::tet_fluid(sim.fluid()));
      write_fluid_vtu(dir / fmt::format("fluid_{:06d}.vtu", k),
                      coupling::tet_fluid(sim.fluid())->mesh(), compression, &fields);
    }
    const double step_s = now_seconds() - t0;
    logger().debug("bench step: scale {:.4g}, step {}: {:.3f} s, {} cells", scale, k + 1, step_s,
                   coupling::tet_fluid(sim.fluid())->mesh().num_tets());
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
  const mesh::TetMesh& m = coupling::tet_fluid(sim.fluid())->mesh();
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

// ---- grid scenes ---------------------------------------------------------------------

/// The scene's grid with n_a / s cells per axis (at least 1).
fluid::GridSpec scaled_grid(const fluid::GridSpec& g, double s) {
  std::array<Index, 3> n{};
  for (int a = 0; a < 3; ++a)
    n[a] = std::max<Index>(1, std::llround(static_cast<double>(g.n[a]) / s));
  return fluid::GridSpec::from_cells(g.lo, g.hi(), n);
}

/// One AMG Poisson solve (setup + solve) of the grid: fluid::grid_project of a random Interior
/// face field (uniform in [−1, 1] m/s) with a fresh AMG solver at the scene's tolerance.
double grid_poisson_floor(const fluid::GridCells& gc, const fluid::FluidParams& p, int& iterations,
                          bool& converged, double& setup_s) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  VecX u = VecX::Zero(gc.grid.num_faces());
  for (Index f = 0; f < u.size(); ++f)
    if (gc.interior(f)) u[f] = uni(rng);
  SolverOptions o;
  o.rel_tol = p.solver_rel_tol;
  o.max_iterations = p.solver_max_iterations;
  o.symmetric = true;
  const auto solver = make_linear_solver(SolverKind::Amg, o);
  VecX q;
  const fluid::ProjectionReport r = fluid::grid_project(gc, VecX(), u, q, *solver);
  iterations = r.iterations;
  converged = r.converged;
  setup_s = r.setup_s;
  return r.setup_s + r.solve_s;
}

/// A grid case: the one-way grid steps (solid, transfer, forces, pressure assembly and solve,
/// one .vti frame) and the floor on the last grid.
Case run_grid_case(const Scene& scene, double scale, int steps, const std::filesystem::path& dir) {
  const fluid::GridSpec spec = scaled_grid(*scene.fluid->grid_spec, scale);
  const Compression compression = parse_compression(scene.output.compression);
  coupling::FsiSimulation sim(
      build_world(scene),
      coupling::FluidSetup{scene.fluid->domain, scene.fluid->sizing, scene.fluid->params,
                           coupling::GridSetup{spec, scene.fluid->grid.pressure_forces}});
  {
    PhaseTimes unused;
    sim.start(unused);
  }
  Case c;
  c.scale = scale;
  StepFigures& mean = c.mean;
  const int timed = steps - 1;
  for (int k = 0; k < steps; ++k) {
    PhaseTimes ph;
    const double t0 = now_seconds();
    const coupling::FsiStepReport rep = sim.step(scene.time.dt, ph);
    {
      ScopedTimer timer(ph, "output");
      write_grid_vti(dir / fmt::format("fluid_{:06d}.vti", k), *sim.fluid_frame().grid(),
                     compression);
    }
    const double step_s = now_seconds() - t0;
    if (k == 0) {
      c.warmup_s = step_s;
      continue;
    }
    mean.step += step_s / timed;
    mean.solid += rep.solid_s / timed;
    mean.transfer += ph.get("transfer") / timed;
    mean.forces += ph.get("forces") / timed;
    mean.assembly += ph.get("pressure_assembly") / timed;
    mean.solve += ph.get("pressure_solve") / timed;
    mean.output += ph.get("output") / timed;
    mean.iterations += static_cast<double>(rep.fluid->iterations) / timed;
    c.liquid.advect += rep.fluid->liquid_advect_s / timed;
    c.liquid.surface += rep.fluid->liquid_surface_s / timed;
    c.liquid.p2g += rep.fluid->liquid_p2g_s / timed;
  }
  if (scene.fluid->params.liquid.enabled)
    c.levels = compare_liquid_level_sets(*coupling::grid_fluid(sim.fluid()),
                                         scene.fluid->params.liquid.particles_per_axis);
  const fluid::GridCells& gc = coupling::grid_fluid(sim.fluid())->cells();
  c.vertices = spec.num_cells();  // (the grid's cells, solid ones included)
  for (Index k = 0; k < spec.num_cells(); ++k) c.cells += gc.fluid(k) ? 1 : 0;
  c.poisson_s = grid_poisson_floor(gc, scene.fluid->params, c.floor_iterations, c.floor_converged,
                                   c.poisson_setup_s);
  return c;
}

/// The JSON of a grid case and its tet counterpart.
nlohmann::json grid_case_json(const Case& c, const Case& t) {
  const StepFigures& f = c.mean;
  return {{"scale", c.scale},
          {"cells", c.cells},
          {"grid_cells", c.vertices},
          {"step_s", f.step},
          {"floor_s", c.poisson_s},
          {"ratio", f.step / c.poisson_s},
          {"phases",
           {{"transfer", f.transfer},
            {"forces", f.forces},
            {"assembly", f.assembly},
            {"solve", f.solve},
            {"output", f.output},
            {"solid", f.solid},
            {"other", f.other()}}},
          {"iterations", f.iterations},
          {"poisson_s", c.poisson_s},
          {"poisson_setup_s", c.poisson_setup_s},
          {"solve_ratio", f.solve / c.poisson_s},
          {"floor_iterations", c.floor_iterations},
          {"warmup_s", c.warmup_s},
          {"tet", {{"scale", t.scale}, {"cells", t.cells}, {"step_s", t.mean.step}}},
          {"grid_over_tet", f.step / t.mean.step}};
}

/// The tet mesh's scale for about `target` cells at t = 0: from cells ∝ scale⁻³, corrected by
/// up to three remeshes (a mesh held by its bodies' surfaces does not scale exactly so).
double tet_scale_for(const Scene& tet, Index cells_at_1, Index target) {
  double s = std::cbrt(static_cast<double>(cells_at_1) / static_cast<double>(target));
  for (int k = 0; k < 3; ++k) {
    const Index n = cells_at_start(scaled(tet, s));
    if (std::abs(static_cast<double>(n - target)) <= 0.05 * static_cast<double>(target)) break;
    s *= std::cbrt(static_cast<double>(n) / static_cast<double>(target));
  }
  return s;
}

/// bench step on a grid scene: the grid cases, and per case the same scene on the tet mesh
/// at about the grid's fluid cells, in the same run.
int bench_step_grid(const std::filesystem::path& scene_file, const Scene& scene,
                    const BenchStepOptions& opt, std::ostream& out) {
  const fluid::GridSpec& g0 = *scene.fluid->grid_spec;
  std::vector<double> scales = opt.scales;
  if (scales.empty())
    for (const double target : opt.target_cells)
      scales.push_back(std::cbrt(static_cast<double>(g0.num_cells()) / target));
  Scene tet = scene;
  tet.fluid->grid_spec.reset();
  // The grid's structured multigrid has no tet counterpart: the tet mesh's default there.
  if (tet.fluid->params.solver == SolverKind::Pfmg) tet.fluid->params.solver = SolverKind::Amg;
  const Index tet_base = cells_at_start(scaled(tet, 1.0));
  TETFSI_REQUIRE(MeshError, tet_base > 0, "{}: the tet fluid mesh at t = 0 has no cells",
                 scene_file.string());
  fmt::print(out,
             "tetfsi bench step: {} ('{}') on its {} x {} x {} grid, dt = {:.6g} s, {} steps per "
             "case (the first is a warm-up; figures are means of the others)\n",
             scene_file.string(), scene.name, g0.n[0], g0.n[1], g0.n[2], scene.time.dt, opt.steps);
  fmt::print(out,
             "grid step = solid + transfer + forces + pressure assembly + solve + output (one "
             ".vti frame);\nfloor = one AMG Poisson solve (setup + solve) of the same grid; tet = "
             "the same scene on the tet mesh\n(fluid.mesh sizes scaled to about the grid's fluid "
             "cells; {} cells at scale 1), same run\n\n",
             tet_base);
  fmt::print(out,
             "{:>6} {:>8} {:>8} {:>8} {:>6} | {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} | {:>5} "
             "{:>5} | {:>8} {:>8} {:>6}\n",
             "scale", "cells", "step_s", "floor_s", "ratio", "solid", "transf", "forces", "assem",
             "solve", "output", "other", "iters", "s/fl", "tet_cell", "tet_s", "g/tet");
  const ScratchDir dir;
  nlohmann::json cases = nlohmann::json::array();
  std::vector<Case> grid_cases;
  for (const double s : scales) {
    const Case c = run_grid_case(scene, s, opt.steps, dir.path);
    grid_cases.push_back(c);
    const double tet_scale = tet_scale_for(tet, tet_base, c.cells);
    const Case t = run_case(tet, tet_scale, opt.steps, dir.path);
    const StepFigures& f = c.mean;
    fmt::print(out,
               "{:>6.3f} {:>8} {:>8.3f} {:>8.3f} {:>6.2f} | {:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f} "
               "{:>6.3f} {:>6.3f} {:>6.3f} | {:>5.1f} {:>5.2f} | {:>8} {:>8.3f} {:>6.3f}\n",
               c.scale, c.cells, f.step, c.poisson_s, f.step / c.poisson_s, f.solid, f.transfer,
               f.forces, f.assembly, f.solve, f.output, f.other(), f.iterations,
               f.solve / c.poisson_s, t.cells, t.mean.step, f.step / t.mean.step);
    out.flush();
    if (!c.floor_converged)
      logger().warn("bench step: the floor's pressure solve at scale {:.4g} did not converge",
                    c.scale);
    cases.push_back(grid_case_json(c, t));
    if (c.levels) cases.back()["liquid"] = liquid_json(c.liquid, f.solve, *c.levels);
  }
  if (!grid_cases.empty() && grid_cases.front().levels) {
    print_liquid_header(out);
    for (const Case& c : grid_cases)
      print_liquid_row(out, c.scale, c.vertices, c.liquid, c.mean.solve, *c.levels);
    fmt::print(out,
               "grid = the grid's cells; advect = particles moved, separated, emitted (with p2g); "
               "surface = the level set, the free\nsurface and the volume hold; p2g = particles "
               "to faces, extrapolated; su/so = surface / solve; ours_s, vdb_s = the\nliquid's "
               "level set (fluid::liquid_level_set, no hold) and OpenVDB's ParticlesToLevelSet "
               "(spheres of the particles'\nspacing, voxels of h/4, band 1.5 cells, sampled at "
               "the cells) on the same particles; vol_us, vol_vd = their\nvolumes / the "
               "particles'; area_u, area_v = their surfaces' areas (m²).\n");
  }
  fmt::print(out,
             "\ncells = fluid cells of the grid; ratio = step / floor; s/fl = the step's pressure "
             "solve / the floor;\ntet_cell, tet_s = the tet mesh's cells and step (remesh "
             "included); g/tet = grid step / tet step.\n");
  if (!opt.json_path.empty()) {
    const nlohmann::json j{
        {"scene", scene.name}, {"discretization", "grid"}, {"steps", opt.steps}, {"cases", cases}};
    write_text_file_atomic(opt.json_path, j.dump(2) + "\n");
  }
  return 0;
}

/// The scales of the tet cases: the options', else those giving the target cells from the
/// scene's mesh at t = 0 (then `base_cells` is set to its cells).
std::vector<double> tet_scales(const std::filesystem::path& scene_file, const Scene& scene,
                               const BenchStepOptions& opt, Index& base_cells) {
  std::vector<double> scales = opt.scales;
  if (scales.empty()) {
    base_cells = cells_at_start(scaled(scene, 1.0));
    TETFSI_REQUIRE(MeshError, base_cells > 0, "{}: the fluid mesh at t = 0 has no cells",
                   scene_file.string());
    for (const double target : opt.target_cells)
      scales.push_back(std::cbrt(static_cast<double>(base_cells) / target));
  }
  return scales;
}

/// The title, what the figures are and the column heads of the tet table.
void print_tet_header(const std::filesystem::path& scene_file, const Scene& scene,
                      const BenchStepOptions& opt, Index base_cells, std::ostream& out) {
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
}

/// The row of a tet case (and a warning if its floor's solve did not converge).
void print_tet_row(const Case& c, std::ostream& out) {
  const StepFigures& f = c.mean;
  const double ratio = f.step / c.floor_s();
  fmt::print(out,
             "{:>6.3f} {:>8} {:>8.3f} {:>8.3f} {:>6.2f} | {:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f} "
             "{:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f} | {:>5.1f} | {:>7.3f} {:>7.3f} {:>5}\n",
             c.scale, c.cells, f.step, c.floor_s(), ratio, f.solid, f.remesh, f.transfer, f.forces,
             f.assembly, f.solve, f.output, f.other(), f.iterations, c.delaunay_s, c.poisson_s,
             c.floor_iterations);
  out.flush();
  if (!c.floor_converged)
    logger().warn("bench step: the floor's pressure solve at scale {:.4g} did not converge",
                  c.scale);
}

/// The JSON of a tet case.
nlohmann::json tet_case_json(const Case& c) {
  const StepFigures& f = c.mean;
  const double ratio = f.step / c.floor_s();
  return {{"scale", c.scale},
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
          {"warmup_s", c.warmup_s}};
}

/// bench step on a tet scene: one case per scale, against its Delaunay + Poisson floor.
int bench_step_tet(const std::filesystem::path& scene_file, const Scene& scene,
                   const BenchStepOptions& opt, std::ostream& out) {
  Index base_cells = 0;
  const std::vector<double> scales = tet_scales(scene_file, scene, opt, base_cells);
  print_tet_header(scene_file, scene, opt, base_cells, out);

  const ScratchDir dir;
  nlohmann::json cases = nlohmann::json::array();
  for (const double s : scales) {
    const Case c = run_case(scene, s, opt.steps, dir.path);
    print_tet_row(c, out);
    cases.push_back(tet_case_json(c));
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

}  // namespace

int bench_step(const std::filesystem::path& scene_file, const BenchStepOptions& opt,
               std::ostream& out) {
  const Scene scene = load_scene(scene_file);
  TETFSI_REQUIRE(InputError, scene.fluid.has_value(),
                 "{}: bench step needs a fluid scene (no 'fluid' section)", scene_file.string());
  TETFSI_REQUIRE(InputError, scene.mode == Mode::Dynamic,
                 "{}: bench step needs a dynamic scene (mode is 'static')", scene_file.string());
  TETFSI_REQUIRE(InputError, opt.steps >= 2,
                 "bench step: --steps must be at least 2 (the first is a warm-up), got {}",
                 opt.steps);
  for (const double s : opt.scales)
    TETFSI_REQUIRE(InputError, std::isfinite(s) && s > 0,
                   "bench step: --sizes: every scale factor must be positive, got {}", s);

  if (scene.fluid->grid_spec) return bench_step_grid(scene_file, scene, opt, out);
  return bench_step_tet(scene_file, scene, opt, out);
}

}  // namespace tetfsi::app
