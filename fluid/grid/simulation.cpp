#include "fluid/grid/simulation.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "fluid/forces.hpp"
#include "fluid/grid/advect.hpp"
#include "fluid/grid/interface.hpp"
#include "fluid/grid/liquid.hpp"
#include "fluid/grid/projection.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;

namespace {

void check_grid_params(const FluidParams& p) {
  TETFSI_REQUIRE(InputError, std::isfinite(p.density) && p.density > 0,
                 "fluid.density must be positive, got {}", p.density);
  TETFSI_REQUIRE(InputError, p.gravity.allFinite(), "fluid.gravity must be finite");
  TETFSI_REQUIRE(InputError, std::isfinite(p.vorticity_confinement) && p.vorticity_confinement >= 0,
                 "fluid.vorticity_confinement must be >= 0, got {}", p.vorticity_confinement);
  TETFSI_REQUIRE(InputError, std::isfinite(p.enclosed_density) && p.enclosed_density >= 0,
                 "fluid.enclosed_density must be >= 0, got {}", p.enclosed_density);
  for (double v : {p.buoyancy_alpha, p.buoyancy_beta, p.smoke_decay, p.temperature_decay})
    TETFSI_REQUIRE(InputError, std::isfinite(v) && v >= 0,
                   "fluid: buoyancy and decay rates must be finite and >= 0, got {}", v);
}

/// +1 if +e_a points out of the box at a box face (its upper side), −1 at its lower side.
double outward_sign(const GridSpec& g, Index f) {
  return g.face_cells(f)[1] < 0 ? 1.0 : -1.0;
}

const PatchConditions* patch_of(const GridCells& gc, const FluidParams& p, Index f) {
  const Index pi = gc.face_patch[f];
  return pi >= 0 && pi < static_cast<Index>(p.patches.size()) ? &p.patches[pi] : nullptr;
}

/// Walls 0, Inflow faces the patch's speed into the box, Solid faces (H v)_f.
void set_boundary_velocity(const GridCells& gc, const FluidParams& p,
                           const std::vector<SolidSurfaceMotion>& motions, VecX& u) {
  const GridSpec& g = gc.grid;
  std::vector<double> area(p.patches.size(), 0.0);
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] == FaceKind::Inflow && patch_of(gc, p, f))
      area[gc.face_patch[f]] += g.face_area(g.face_axis(f));
  for (Index f = 0; f < g.num_faces(); ++f) {
    const FaceKind k = gc.face_kind[f];
    if (k == FaceKind::Interior || k == FaceKind::Open) continue;
    u[f] = 0.0;
    const PatchConditions* pc = patch_of(gc, p, f);
    if (k != FaceKind::Inflow || !pc) continue;
    double speed = pc->inflow_speed;
    if (pc->area > 0 && area[gc.face_patch[f]] > 0) speed *= pc->area / area[gc.face_patch[f]];
    u[f] = -outward_sign(g, f) * speed;
  }
  if (motions.empty()) return;
  std::vector<BodyInterface> bodies(motions.size());
  std::vector<VecX> v(motions.size());
  for (size_t b = 0; b < motions.size(); ++b) {
    const Index n = motions[b].velocity.rows();
    bodies[b] = BodyInterface{motions[b].triangles, VecXi::LinSpaced(n, 0, n - 1), n};
    v[b] = flat(motions[b].velocity);
  }
  GridInterface(gc, std::move(bodies)).apply_H(v, u);  // see [Chentanez06, §3.4]
}

/// Volume sources, and the cells next to an Inflow face take the patch's smoke.
void apply_sources(const GridCells& gc, const FluidParams& p, VecX& density, VecX& temperature) {
  const GridSpec& g = gc.grid;
  for (Index c = 0; c < g.num_cells(); ++c) {
    if (!gc.fluid(c)) continue;
    const Vec3 x = g.cell_centre(c);
    for (const SmokeSource& s : p.sources) {
      if ((x.array() < s.lo.array()).any() || (x.array() > s.hi.array()).any()) continue;
      density[c] = std::max(density[c], s.smoke_density);
      if (s.emits_temperature) temperature[c] = s.temperature;
    }
  }
  for (Index f = 0; f < g.num_faces(); ++f) {
    if (gc.face_kind[f] != FaceKind::Inflow) continue;
    const PatchConditions* pc = patch_of(gc, p, f);
    const auto cells = g.face_cells(f);
    const Index c = cells[0] >= 0 ? cells[0] : cells[1];
    if (!pc || !gc.fluid(c)) continue;
    density[c] = pc->smoke_density;
    temperature[c] = pc->emits_temperature ? pc->temperature : p.ambient_temperature;
  }
}

/// Cells or faces per chunk of the parallel loops.
constexpr Index kGrain = 4096;

/// The fluid neighbours of cell c along each axis a: nb[a] = {below, above}, −1 where the
/// neighbour is not fluid or outside the box.
using AxisNeighbours = std::array<std::array<Index, 2>, 3>;
AxisNeighbours fluid_neighbours(const GridCells& gc, Index c) {
  const GridSpec& g = gc.grid;
  const auto ijk = g.cell_ijk(c);
  const Index stride[3] = {1, g.n[0], g.n[0] * g.n[1]};
  AxisNeighbours nb{};
  for (int a = 0; a < 3; ++a) {
    const Index below = ijk[a] > 0 ? c - stride[a] : -1;
    const Index above = ijk[a] + 1 < g.n[a] ? c + stride[a] : -1;
    nb[a] = {gc.fluid(below) ? below : -1, gc.fluid(above) ? above : -1};
  }
  return nb;
}

/// Central difference along axis a of a cell field at c from its fluid neighbours nb,
/// one-sided next to non-fluid cells and the box (0 if both neighbours are missing).
double cell_derivative(const GridSpec& g, const VecX& v, Index c, const std::array<Index, 2>& nb,
                       int a) {
  if (nb[0] >= 0 && nb[1] >= 0) return (v[nb[1]] - v[nb[0]]) / (2 * g.h[a]);
  if (nb[1] >= 0) return (v[nb[1]] - v[c]) / g.h[a];
  if (nb[0] >= 0) return (v[c] - v[nb[0]]) / g.h[a];
  return 0.0;
}

}  // namespace

VecX grid_cell_density(const GridCells& gc, const FluidParams& p) {
  const GridSpec& g = gc.grid;
  VecX rho = VecX::Constant(g.num_cells(), p.density);
  if (!(p.enclosed_density > 0) || p.enclosed_density == p.density) return rho;
  const Regions regions = grid_regions(gc);
  std::vector<bool> enclosed(static_cast<size_t>(regions.count()), true);
  for (Index f = 0; f < g.num_faces(); ++f) {
    const FaceKind k = gc.face_kind[f];
    if (k == FaceKind::Interior || k == FaceKind::Solid) continue;
    for (Index c : g.face_cells(f))
      if (gc.fluid(c)) enclosed[regions.cell_region[c]] = false;
  }
  for (Index c = 0; c < g.num_cells(); ++c)
    if (gc.fluid(c) && enclosed[regions.cell_region[c]]) rho[c] = p.enclosed_density;
  return rho;
}

MatX3 grid_vorticity(const GridCells& gc, const MatX3& uc) {
  const Index nc = gc.grid.num_cells();
  MatX3 w = MatX3::Zero(nc, 3);
  // contiguous components (a column of the row-major uc would be copied on every call)
  const std::array<VecX, 3> comp_of = {VecX(uc.col(0)), VecX(uc.col(1)), VecX(uc.col(2))};
  parallel_for_each(nc, kGrain, [&](Index c) {
    if (!gc.fluid(c)) return;
    const AxisNeighbours nb = fluid_neighbours(gc, c);
    const auto d = [&](int comp, int ax) {
      return cell_derivative(gc.grid, comp_of[comp], c, nb[ax], ax);
    };
    w.row(c) << d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1);
  });
  return w;
}

namespace {

/// Per-cell vorticity confinement ε h (N × ω), N = ∇|ω| / |∇|ω|| [Fedkiw01, Eq. (11)] on the
/// grid's cell-centred velocity (see tet/confinement.hpp for the tet mesh's).
MatX3 grid_confinement(const GridCells& gc, const MatX3& uc, double epsilon) {
  const GridSpec& g = gc.grid;
  const Index nc = g.num_cells();
  const MatX3 w = grid_vorticity(gc, uc);
  MatX3 a = MatX3::Zero(nc, 3);
  const VecX wn = w.rowwise().norm();
  const double hc = g.h.mean();
  parallel_for_each(nc, kGrain, [&](Index c) {
    if (!gc.fluid(c)) return;
    const AxisNeighbours nb = fluid_neighbours(gc, c);
    const Vec3 grad(cell_derivative(g, wn, c, nb[0], 0), cell_derivative(g, wn, c, nb[1], 1),
                    cell_derivative(g, wn, c, nb[2], 2));
    const double gn = grad.norm();
    if (gn < 1e-12 * (wn[c] / hc + 1e-300)) return;
    // see [Fedkiw01, Eq. (11)]: f_conf = ε h (N × ω)
    a.row(c) = epsilon * hc * (grad / gn).cross(w.row(c).transpose()).transpose();
  });
  return a;
}

/// u_f += h e_a · (mean of its fluid cells' acceleration) on Interior and Open faces.
void add_cell_acceleration(const GridCells& gc, const MatX3& a, double h, VecX& u) {
  const GridSpec& g = gc.grid;
  parallel_for_each(g.num_faces(), kGrain, [&](Index f) {
    const FaceKind k = gc.face_kind[f];
    if (k != FaceKind::Interior && k != FaceKind::Open) return;
    const int ax = g.face_axis(f);
    double s = 0;
    int n = 0;
    for (Index c : g.face_cells(f))
      if (gc.fluid(c)) {
        s += a(c, ax);
        ++n;
      }
    if (n > 0) u[f] += h * s / n;
  });
}

/// Buoyancy [Fedkiw01, Eq. (8)] and vorticity confinement, averaged from the cells to faces.
/// Confinement reads the advected velocity before buoyancy is added.
void add_forces(const GridCells& gc, const FluidParams& p, const VecX& density,
                const VecX& temperature, double h, VecX& u) {
  const MatX3 confinement =
      p.vorticity_confinement > 0
          ? grid_confinement(gc, cell_velocities(gc, u), p.vorticity_confinement)
          : MatX3();
  if (p.buoyancy_alpha != 0 || p.buoyancy_beta != 0)
    add_cell_acceleration(gc, buoyancy(p, density, temperature), h, u);
  if (p.vorticity_confinement > 0) add_cell_acceleration(gc, confinement, h, u);
}

}  // namespace

GridFluid::GridFluid(FluidParams params, GridSpec grid, mesh::FluidDomain domain)
    : m_params(std::move(params)), m_grid(grid), m_domain(std::move(domain)) {
  check_grid_params(m_params);
  const LiquidParams& lq = m_params.liquid;
  if (!lq.enabled) return;
  TETFSI_REQUIRE(InputError, std::isfinite(lq.flip) && lq.flip >= 0 && lq.flip <= 1,
                 "fluid.liquid.flip must be in [0, 1], got {}", lq.flip);
  TETFSI_REQUIRE(InputError,
                 std::isfinite(lq.density_correction) && lq.density_correction >= 0 &&
                     lq.density_correction <= 1,
                 "fluid.liquid.density_correction must be in [0, 1], got {}",
                 lq.density_correction);
  TETFSI_REQUIRE(InputError, lq.particles_per_axis >= 1 && lq.particles_per_axis <= 4,
                 "fluid.liquid.particles_per_axis must be 1 to 4, got {}", lq.particles_per_axis);
  TETFSI_REQUIRE(InputError, !lq.regions.empty() || !lq.sources.empty(),
                 "fluid.liquid has neither regions nor sources: give one of them");
  // The free surface needs the whole pressure (p = 0 at the surface): gravity acts on the
  // velocity, and there is no hydrostatic split.
  m_liquid_gravity = m_params.gravity;
  m_params.gravity = Vec3::Zero();
  m_surface = liquid_surface_params(m_grid, lq.particles_per_axis);
}

bool GridFluid::has_liquid() const {
  return m_params.liquid.enabled;
}

double GridFluid::particle_volume(Index n) const {
  const int m = m_params.liquid.particles_per_axis;
  return static_cast<double>(n) * m_grid.cell_volume() / (m * m * m);
}

int GridFluid::extrapolation_layers(const VecX& u, double h) const {
  const double reach = h * (u.size() ? u.cwiseAbs().maxCoeff() : 0.0) / m_grid.h.minCoeff();
  return 3 + static_cast<int>(std::ceil(std::min(reach, 50.0)));
}

void GridFluid::predict_liquid(GridPrediction& pred, double h) const {
  const LiquidParams& lq = m_params.liquid;
  double t0 = now_seconds();
  pred.particles = m_state.particles;
  pred.particles_removed = advect_particles(pred.cells, m_state.u, h, pred.particles);
  separate_particles(pred.cells, lq.particles_per_axis, pred.particles);
  pred.particles_added = emit_liquid(pred.cells, lq, m_time + h, pred.particles);
  pred.liquid_advect_s = now_seconds() - t0;
  t0 = now_seconds();
  VecX phi = liquid_level_set(pred.cells, pred.particles.x, m_surface);
  if (!lq.hold_volume)
    set_free_surface(pred.cells, std::move(phi));
  else {  // the hold sets the air cells from the shifted φ
    pred.cells.phi = std::move(phi);
    pred.liquid_moved = hold_liquid_volume(
        pred.cells,
        m_liquid_expected + particle_volume(pred.particles_added - pred.particles_removed),
        m_surface);
  }
  if (lq.density_correction > 0)
    pred.cells.volume_source = liquid_volume_source(
        pred.cells, pred.particles.x, lq.particles_per_axis, lq.density_correction, h);
  pred.liquid_surface_s = now_seconds() - t0;
  t0 = now_seconds();
  pred.rho = grid_cell_density(pred.cells, m_params);
  pred.u_star = particles_to_faces(m_grid, pred.particles, pred.particle_faces);
  extrapolate_faces(m_grid, pred.particle_faces, extrapolation_layers(pred.u_star, h), pred.u_star);
  pred.liquid_p2g_s = now_seconds() - t0;
  pred.density = VecX::Zero(m_grid.num_cells());
  pred.temperature = VecX::Constant(m_grid.num_cells(), m_params.ambient_temperature);
}

void GridFluid::initialize(std::vector<mesh::SolidSurface> surfaces) {
  m_cells = classify_grid(m_grid, m_domain, std::move(surfaces));
  const Index nc = m_grid.num_cells();
  m_state.u = VecX::Zero(m_grid.num_faces());
  m_state.density = VecX::Zero(nc);
  m_state.temperature = VecX::Constant(nc, m_params.ambient_temperature);
  m_state.p = VecX::Zero(nc);
  apply_sources(m_cells, m_params, m_state.density, m_state.temperature);
  if (has_liquid()) {
    m_state.particles = seed_liquid(m_cells, m_params.liquid);
    set_free_surface(m_cells, liquid_level_set(m_cells, m_state.particles.x, m_surface));
    m_liquid_expected = liquid_measures(m_cells).volume;
  }
  const VecX rho = grid_cell_density(m_cells, m_params);
  for (Index c = 0; c < nc; ++c)
    if (m_cells.fluid(c))
      m_state.p[c] = hydrostatic_pressure(rho[c], m_params.gravity, m_params.hydrostatic_origin,
                                          m_grid.cell_centre(c));
  m_time = 0.0;
  m_initialized = true;
}

GridPrediction GridFluid::predict(std::vector<mesh::SolidSurface> surfaces,
                                  const std::vector<SolidSurfaceMotion>& motions, double h,
                                  PhaseTimes& phases) const {
  TETFSI_CHECK(m_initialized, "GridFluid::predict before initialize");
  TETFSI_REQUIRE(InputError, std::isfinite(h) && h > 0, "fluid step: dt must be positive, got {}",
                 h);
  GridPrediction pred;
  pred.h = h;
  {  // see [Chentanez06, Eq. (1)] without the pressure: advection, then the forces
    ScopedTimer timer(phases, "transfer");
    pred.cells = classify_grid(m_grid, m_domain, std::move(surfaces));
    if (has_liquid()) predict_liquid(pred, h);
  }
  if (has_liquid()) return predict_forces(std::move(pred), motions, phases);
  {
    ScopedTimer timer(phases, "transfer");
    pred.rho = grid_cell_density(pred.cells, m_params);
    Eigen::MatrixXd s(m_grid.num_cells(), 2);
    s.col(0) = m_state.density;
    s.col(1) = m_state.temperature;
    const GridAdvected a = grid_advect(m_cells, pred.cells, m_state.u, s, h,
                                       Eigen::Vector2d(0.0, m_params.ambient_temperature));
    pred.u_star = a.u;
    pred.density = a.scalars.col(0);
    pred.temperature = a.scalars.col(1);
    pred.traces_clamped = a.traces_clamped;
  }
  return predict_forces(std::move(pred), motions, phases);
}

GridPrediction GridFluid::predict_forces(GridPrediction pred,
                                         const std::vector<SolidSurfaceMotion>& motions,
                                         PhaseTimes& phases) const {
  ScopedTimer timer(phases, "forces");
  const double h = pred.h;
  if (has_liquid()) {
    // the particles' velocity with the boundary values is what FLIP subtracts [ZhuBridson05]
    set_boundary_velocity(pred.cells, m_params, motions, pred.u_star);
    pred.u_old = pred.u_star;
    parallel_for_each(m_grid.num_faces(), kGrain, [&](Index f) {
      const FaceKind k = pred.cells.face_kind[f];
      if (k == FaceKind::Interior || k == FaceKind::Open)
        pred.u_star[f] += h * m_liquid_gravity[m_grid.face_axis(f)];
    });
    pred.p_open = VecX::Zero(m_grid.num_faces());
    return pred;
  }
  const double T0 = m_params.ambient_temperature;
  if (m_params.smoke_decay > 0) pred.density *= std::exp(-m_params.smoke_decay * h);
  if (m_params.temperature_decay > 0)
    pred.temperature =
        ((pred.temperature.array() - T0) * std::exp(-m_params.temperature_decay * h) + T0).matrix();
  apply_sources(pred.cells, m_params, pred.density, pred.temperature);
  add_forces(pred.cells, m_params, pred.density, pred.temperature, h, pred.u_star);
  set_boundary_velocity(pred.cells, m_params, motions, pred.u_star);
  pred.p_open = VecX::Zero(m_grid.num_faces());
  for (Index f = 0; f < m_grid.num_faces(); ++f)
    if (pred.cells.face_kind[f] == FaceKind::Open)
      if (const PatchConditions* pc = patch_of(pred.cells, m_params, f))
        pred.p_open[f] = pc->pressure;
  return pred;
}

std::pair<VecX, VecX> GridFluid::project(const GridPrediction& pred, FluidStepReport& rep,
                                         PhaseTimes& phases) {
  if (!m_solver)
    m_solver = make_linear_solver(m_params.solver,
                                  SolverOptions{.rel_tol = m_params.solver_rel_tol,
                                                .max_iterations = m_params.solver_max_iterations});
  // q = (h/ρ) p per cell (an enclosed region has its own ρ and no Open face)
  const double s = pred.h / m_params.density;
  VecX u = pred.u_star, q;  // zero initial guess
  const ProjectionReport pr = grid_project(pred.cells, s * pred.p_open, u, q, *m_solver);
  phases.add("assembly", pr.assembly_s);
  phases.add("solve", pr.setup_s + pr.solve_s);
  logger().debug("grid pressure solve: {} unknowns, setup {:.3f} s, solve {:.3f} s, {} iterations",
                 pr.groups, pr.setup_s, pr.solve_s, pr.iterations);
  rep.converged = pr.converged;
  rep.iterations = pr.iterations;
  rep.residual = pr.residual;
  rep.divergence_before = pr.divergence_before;
  rep.divergence_after = pr.divergence_after;
  TETFSI_REQUIRE(SolverError, pr.converged,
                 "grid pressure solve did not converge ({} iterations, residual {:.3g}): lower "
                 "the time step or raise fluid.solver_max_iterations",
                 pr.iterations, pr.residual);
  return {std::move(u), VecX(q.cwiseProduct(pred.rho) / pred.h)};
}

FluidStepReport GridFluid::commit(GridPrediction pred, VecX u, VecX p_dyn, FluidStepReport rep) {
  TETFSI_REQUIRE(SolverError, u.allFinite() && p_dyn.allFinite(),
                 "the grid fluid's velocity or pressure became non-finite at t = {}: lower the "
                 "time step",
                 m_time + pred.h);
  const GridSpec& g = m_grid;
  const GridCells& gc = pred.cells;
  if (has_liquid()) {
    // the projected faces, the prescribed ones and those the particles reached (in the air:
    // v* with gravity, a free fall) stand; the rest are filled from them
    std::vector<std::uint8_t> known = liquid_faces(gc);
    for (Index f = 0; f < g.num_faces(); ++f) known[f] = known[f] || pred.particle_faces[f];
    extrapolate_faces(g, std::move(known), extrapolation_layers(u, pred.h), u);
    faces_to_particles(g, u, pred.u_old, m_params.liquid.flip, pred.particles);
    const LiquidMeasures lm = liquid_measures(gc);
    m_liquid_expected += particle_volume(pred.particles_added - pred.particles_removed);
    rep.liquid_volume = lm.volume;
    rep.liquid_shift = lm.area > 0 ? pred.liquid_moved / lm.area : 0.0;
    rep.liquid_volume_drift =
        m_liquid_expected > 0 ? (lm.volume - m_liquid_expected) / m_liquid_expected : 0.0;
    rep.liquid_area = lm.area;
    rep.liquid_particles = pred.particles.size();
    rep.liquid_advect_s = pred.liquid_advect_s;
    rep.liquid_surface_s = pred.liquid_surface_s;
    rep.liquid_p2g_s = pred.liquid_p2g_s;
  }
  for (Index c = 0; c < g.num_cells(); ++c)
    p_dyn[c] = gc.fluid(c)
                   ? p_dyn[c] + hydrostatic_pressure(pred.rho[c], m_params.gravity,
                                                     m_params.hydrostatic_origin, g.cell_centre(c))
                   : 0.0;
  m_state = GridState{std::move(u), std::move(p_dyn), std::move(pred.density),
                      std::move(pred.temperature), std::move(pred.particles)};
  m_cells = std::move(pred.cells);
  m_time += pred.h;
  rep.traces_clamped = pred.traces_clamped;
  const MatX3 uc = cell_velocities();
  rep.kinetic_energy = rep.smoke_mass = rep.max_speed = rep.cfl = 0.0;
  for (Index c = 0; c < g.num_cells(); ++c) {
    if (!m_cells.fluid(c)) continue;
    rep.kinetic_energy += 0.5 * pred.rho[c] * g.cell_volume() * uc.row(c).squaredNorm();
    rep.smoke_mass += g.cell_volume() * m_state.density[c];
    rep.cfl = std::max(rep.cfl, pred.h * uc.row(c).norm() / g.h.minCoeff());
  }
  rep.inflow_flux = rep.outflow_flux = rep.solid_flux = 0.0;
  for (Index f = 0; f < g.num_faces(); ++f) {
    const double q = g.face_area(g.face_axis(f)) * m_state.u[f];
    rep.max_speed = std::max(rep.max_speed, std::abs(m_state.u[f]));
    if (m_cells.face_kind[f] == FaceKind::Inflow) rep.inflow_flux -= outward_sign(g, f) * q;
    if (m_cells.face_kind[f] == FaceKind::Open) rep.outflow_flux += outward_sign(g, f) * q;
    if (m_cells.face_kind[f] == FaceKind::Solid) {
      const auto c = g.face_cells(f);  // out of each fluid cell next to it
      rep.solid_flux += (m_cells.fluid(c[0]) ? q : 0.0) - (m_cells.fluid(c[1]) ? q : 0.0);
    }
  }
  return rep;
}

FluidStepReport GridFluid::step(std::vector<mesh::SolidSurface> surfaces,
                                const std::vector<SolidSurfaceMotion>& motions, double h,
                                PhaseTimes& phases,
                                const std::function<void(const GridCells&)>& alongside) {
  GridPrediction pred = predict(std::move(surfaces), motions, h, phases);
  FluidStepReport rep;
  std::pair<VecX, VecX> up;
  if (alongside)
    run_alongside([&] { up = project(pred, rep, phases); }, [&] { alongside(pred.cells); });
  else
    up = project(pred, rep, phases);
  return commit(std::move(pred), std::move(up.first), std::move(up.second), rep);
}

void GridFluid::set_state(GridState s) {
  const Index nc = m_grid.num_cells(), nf = m_grid.num_faces();
  TETFSI_REQUIRE(
      InputError,
      s.u.size() == nf && s.p.size() == nc && s.density.size() == nc && s.temperature.size() == nc,
      "grid state sizes u {}, p {}, density {}, temperature {} for {} faces, {} cells", s.u.size(),
      s.p.size(), s.density.size(), s.temperature.size(), nf, nc);
  TETFSI_REQUIRE(InputError, s.u.allFinite() && s.p.allFinite(), "grid state is not finite");
  m_state = std::move(s);
}

MatX3 GridFluid::cell_velocities() const {
  return fluid::cell_velocities(m_cells, m_state.u);
}

MatX3 cell_velocities(const GridCells& gc, const VecX& u) {
  const GridSpec& g = gc.grid;
  MatX3 uc = MatX3::Zero(g.num_cells(), 3);
  for (Index c = 0; c < g.num_cells(); ++c) {
    const auto ijk = g.cell_ijk(c);
    for (int a = 0; a < 3; ++a) {
      std::array<Index, 3> up = ijk;
      ++up[a];
      uc(c, a) = 0.5 * (u[g.face(a, ijk[0], ijk[1], ijk[2])] + u[g.face(a, up[0], up[1], up[2])]);
    }
  }
  return uc;
}

void GridFluid::save_state(CheckpointWriter& w, const std::string& prefix) const {
  TETFSI_CHECK(m_initialized, "GridFluid::save_state before initialize");
  const std::vector<mesh::SolidSurface>& surfaces = m_cells.solids.surfaces();
  w.put(prefix + "surfaces", static_cast<std::int64_t>(surfaces.size()));
  for (size_t i = 0; i < surfaces.size(); ++i) {
    const std::string p = fmt::format("{}surface/{}/", prefix, i);
    w.put(p + "body", surfaces[i].body);
    w.put(p + "vertices", surfaces[i].vertices);
    w.put(p + "triangles", surfaces[i].triangles);
  }
  w.put(prefix + "u", m_state.u);
  w.put(prefix + "p", m_state.p);
  w.put(prefix + "density", m_state.density);
  w.put(prefix + "temperature", m_state.temperature);
  if (has_liquid()) {
    w.put(prefix + "liquid/x", m_state.particles.x);
    w.put(prefix + "liquid/v", m_state.particles.v);
    w.put(prefix + "liquid/expected", m_liquid_expected);
  }
  w.put(prefix + "time", m_time);
}

void GridFluid::load_state(const CheckpointReader& r, const std::string& prefix) {
  std::vector<mesh::SolidSurface> surfaces(r.get_count(prefix + "surfaces"));
  for (size_t i = 0; i < surfaces.size(); ++i) {
    const std::string p = fmt::format("{}surface/{}/", prefix, i);
    surfaces[i].body = static_cast<int>(r.get_int(p + "body"));
    surfaces[i].vertices = r.get<MatX3>(p + "vertices");
    surfaces[i].triangles = r.get<MatX3i>(p + "triangles");
    const Index nv = static_cast<Index>(surfaces[i].vertices.rows());
    if (surfaces[i].triangles.size() > 0 &&
        (surfaces[i].triangles.minCoeff() < 0 || surfaces[i].triangles.maxCoeff() >= nv))
      r.fail(fmt::format("record '{}triangles' refers to vertices outside 0..{}", p, nv - 1));
  }
  GridState s;
  s.u = r.get<VecX>(prefix + "u");
  s.p = r.get<VecX>(prefix + "p");
  s.density = r.get<VecX>(prefix + "density");
  s.temperature = r.get<VecX>(prefix + "temperature");
  const Index nc = m_grid.num_cells(), nf = m_grid.num_faces();
  if (s.u.size() != nf || s.p.size() != nc || s.density.size() != nc || s.temperature.size() != nc)
    r.fail(
        fmt::format("its grid fields (u {}, p {}, density {}, temperature {}) do not fit the "
                    "scene's grid ({} faces, {} cells): it is from another scene",
                    s.u.size(), s.p.size(), s.density.size(), s.temperature.size(), nf, nc));
  if (has_liquid()) {
    s.particles.x = r.get<MatX3>(prefix + "liquid/x");
    s.particles.v = r.get<MatX3>(prefix + "liquid/v");
    m_liquid_expected = r.get_double(prefix + "liquid/expected");
    if (s.particles.v.rows() != s.particles.x.rows() || !s.particles.x.allFinite() ||
        !s.particles.v.allFinite())
      r.fail(
          fmt::format("its liquid particles ({} positions, {} velocities) are not a finite "
                      "matching pair",
                      s.particles.x.rows(), s.particles.v.rows()));
  }
  const double t = r.get_double(prefix + "time");
  m_cells = classify_grid(m_grid, m_domain, std::move(surfaces));
  if (has_liquid()) {
    set_free_surface(m_cells, liquid_level_set(m_cells, s.particles.x, m_surface));
    if (m_params.liquid.hold_volume) hold_liquid_volume(m_cells, m_liquid_expected, m_surface);
  }
  m_state = std::move(s);
  m_time = t;
  m_initialized = true;
}

GridFrameFields grid_frame_fields(const GridFluid& g) {
  const GridCells& gc = g.cells();
  const GridSpec& spec = gc.grid;
  const GridState& st = g.state();
  GridFrameFields f;
  f.origin = spec.lo;
  f.spacing = spec.h;
  f.cells = spec.n;
  f.pressure = st.p;
  f.density = st.density;
  f.temperature = st.temperature;
  f.divergence = grid_net_flux(gc, st.u) / spec.cell_volume();
  f.velocity = g.cell_velocities();
  f.vorticity = grid_vorticity(gc, f.velocity).rowwise().norm();
  f.solid.resize(spec.num_cells());
  for (Index c = 0; c < spec.num_cells(); ++c) f.solid[c] = gc.open_cell(c) ? 0 : 1;
  f.phi = gc.phi;
  return f;
}

}  // namespace tetfsi::fluid
