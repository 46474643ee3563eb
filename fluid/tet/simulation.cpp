#include "fluid/tet/simulation.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/log.hpp"
#include "fluid/forces.hpp"
#include "fluid/tet/confinement.hpp"
#include "fluid/tet/interface.hpp"
#include "fluid/tet/operators.hpp"
#include "fluid/tet/reconstruct.hpp"
#include "fluid/tet/transfer.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;
using mesh::TetMesh;

FluidState FluidState::at_rest(const TetMesh& m, double ambient_temperature) {
  FluidState s;
  s.u = VecX::Zero(m.num_faces());
  s.p = VecX::Zero(m.num_tets());
  s.density = VecX::Zero(m.num_tets());
  s.temperature = VecX::Constant(m.num_tets(), ambient_temperature);
  return s;
}

namespace {

void check_params(const FluidParams& p) {
  auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0; };
  TETFSI_REQUIRE(InputError, std::isfinite(p.density) && p.density > 0,
                 "fluid density must be positive, got {}", p.density);
  TETFSI_REQUIRE(InputError, p.gravity.allFinite(), "fluid gravity must be finite");
  TETFSI_REQUIRE(InputError, std::isfinite(p.enclosed_density) && p.enclosed_density >= 0,
                 "fluid enclosed_density must be >= 0 (0: the fluid's density), got {}",
                 p.enclosed_density);
  TETFSI_REQUIRE(InputError, p.up.allFinite() && std::abs(p.up.norm() - 1.0) < 1e-9,
                 "fluid 'up' must be a unit vector");
  TETFSI_REQUIRE(InputError, finite_nonneg(p.buoyancy_alpha) && finite_nonneg(p.buoyancy_beta),
                 "buoyancy alpha and beta must be finite and >= 0");
  TETFSI_REQUIRE(InputError, std::isfinite(p.ambient_temperature),
                 "ambient temperature must be finite");
  TETFSI_REQUIRE(InputError, finite_nonneg(p.vorticity_confinement),
                 "vorticity confinement must be >= 0");
  TETFSI_REQUIRE(InputError, finite_nonneg(p.smoke_decay) && finite_nonneg(p.temperature_decay),
                 "decay rates must be >= 0");
  TETFSI_REQUIRE(InputError, p.min_dual_fraction > 0 && p.min_dual_fraction < 1,
                 "min_dual_fraction must be in (0, 1), got {}", p.min_dual_fraction);
}

}  // namespace

struct FluidSimulation::Impl {
  FluidParams params;
  TetMesh mesh;
  FluidState state;
  std::unique_ptr<LinearSolver> solver;
  double time = 0.0;
  bool initialized = false;

  /// Volume sources (density, temperature). Inflow patches emit through the transfer: a
  /// back-trace stopped at an Inflow face takes the patch's values (transfer.hpp).
  void apply_sources(const TetMesh& m, FluidState& s) const {
    if (!params.sources.empty()) {
      for (Index t = 0; t < m.num_tets(); ++t) {
        const Vec3 c = mesh::tet_centroid(m, t);
        for (const SmokeSource& src : params.sources) {
          if ((c.array() < src.lo.array()).any() || (c.array() > src.hi.array()).any()) continue;
          s.density[t] = std::max(s.density[t], src.smoke_density);
          if (src.emits_temperature) s.temperature[t] = src.temperature;
        }
      }
    }
  }

  /// Prescribed normal velocities: walls 0, inflow −speed, solid faces n_f · Σ_a w_a v_a.
  void apply_boundary_velocity(const TetMesh& m, const std::vector<SolidSurfaceMotion>& solids,
                               VecX& u) const {
    const Index np = static_cast<Index>(params.patches.size());
    std::vector<double> speed(np, 0.0), area(np, 0.0);
    for (Index f = 0; f < m.num_faces(); ++f)
      if (m.face_kind[f] == FaceKind::Inflow && m.face_patch[f] >= 0 && m.face_patch[f] < np)
        area[m.face_patch[f]] += m.face_areas[f];
    for (Index i = 0; i < np; ++i) {
      speed[i] = params.patches[i].inflow_speed;
      if (params.patches[i].area > 0 && area[i] > 0) speed[i] *= params.patches[i].area / area[i];
    }
    for (Index f = 0; f < m.num_faces(); ++f) {
      switch (m.face_kind[f]) {
        case FaceKind::Interior:
        case FaceKind::Open:
          break;
        case FaceKind::Wall:
          u[f] = 0.0;
          break;
        case FaceKind::Inflow: {
          const Index pi = m.face_patch[f];
          u[f] = pi >= 0 && pi < np ? -speed[pi] : 0.0;
          break;
        }
        case FaceKind::Solid:
          u[f] = 0.0;  // (H u)_f below; 0 if no motion is given
          break;
      }
    }
    if (solids.empty()) return;
    // Solid faces: (H u)_f with the surface vertices as the bodies' nodes
    // [docs/method/tet_fluid.md]
    std::vector<BodyInterface> bodies(solids.size());
    std::vector<VecX> v(solids.size());
    for (size_t b = 0; b < solids.size(); ++b) {
      const Index n = solids[b].velocity.rows();
      bodies[b].triangles = solids[b].triangles;
      bodies[b].surface_node = VecXi::LinSpaced(n, 0, n - 1);
      bodies[b].num_nodes = n;
      v[b] = flat(solids[b].velocity);
    }
    InterfaceOperators(m, std::move(bodies)).apply_H(v, u);
  }

  VecX open_q(const TetMesh& m, double h) const {
    VecX q = VecX::Zero(m.num_faces());
    const double s = h / params.density;
    for (Index f = 0; f < m.num_faces(); ++f) {
      if (m.face_kind[f] != FaceKind::Open) continue;
      const Index pi = m.face_patch[f];
      const double p = pi >= 0 && pi < static_cast<Index>(params.patches.size())
                           ? params.patches[pi].pressure
                           : 0.0;
      q[f] = s * p;  // the pressure above the hydrostatic one
    }
    return q;
  }

  void ensure_solver() {
    if (solver) return;
    SolverOptions o;
    o.rel_tol = params.solver_rel_tol;
    o.max_iterations = params.solver_max_iterations;
    o.symmetric = true;
    solver = make_linear_solver(params.solver, o);
  }
};

FluidSimulation::FluidSimulation(FluidParams params) : m_impl(std::make_unique<Impl>()) {
  check_params(params);
  m_impl->params = std::move(params);
}
FluidSimulation::~FluidSimulation() = default;
FluidSimulation::FluidSimulation(FluidSimulation&&) noexcept = default;
FluidSimulation& FluidSimulation::operator=(FluidSimulation&&) noexcept = default;

void FluidSimulation::initialize(TetMesh m) {
  Impl& I = *m_impl;
  I.state = FluidState::at_rest(m, I.params.ambient_temperature);
  I.apply_sources(m, I.state);
  const VecX rho = cell_fluid_density(m, I.params);
  for (Index t = 0; t < m.num_tets(); ++t)
    I.state.p[t] = hydrostatic_pressure(rho[t], I.params.gravity, I.params.hydrostatic_origin,
                                        m.circumcentres.row(t).transpose());
  I.mesh = std::move(m);
  I.time = 0.0;
  I.initialized = true;
}

VecX cell_fluid_density(const TetMesh& m, const FluidParams& p) {
  VecX rho = VecX::Constant(m.num_tets(), p.density);
  if (!(p.enclosed_density > 0) || p.enclosed_density == p.density) return rho;
  const Regions regions = fluid_regions(m);
  std::vector<bool> enclosed(static_cast<size_t>(regions.count()), true);
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.is_boundary(f) && m.face_kind[f] != FaceKind::Solid)
      enclosed[regions.cell_region[m.face_tets(f, 0)]] = false;
  for (Index t = 0; t < m.num_tets(); ++t)
    if (enclosed[regions.cell_region[t]]) rho[t] = p.enclosed_density;
  return rho;
}

FluidPrediction FluidSimulation::predict(TetMesh nm, double h,
                                         const std::vector<SolidSurfaceMotion>& solids,
                                         PhaseTimes& phases) const {
  const Impl& I = *m_impl;
  TETFSI_CHECK(I.initialized, "FluidSimulation::predict before initialize");
  TETFSI_REQUIRE(InputError, std::isfinite(h) && h > 0, "fluid step: dt must be positive, got {}",
                 h);
  const FluidParams& P = I.params;
  FluidPrediction pred;
  pred.h = h;
  FluidState s;
  {  // [Chentanez06, Eq. (1)] without the pressure: advection (the transfer), then the forces
    ScopedTimer timer(phases, "transfer");
    TransferInput in;
    in.old_mesh = &I.mesh;
    in.old_u = &I.state.u;
    in.old_density = &I.state.density;
    in.old_temperature = &I.state.temperature;
    in.reconstruction = P.reconstruction;
    in.scalar_scheme = P.scalar_transfer;
    in.velocity_scheme = P.velocity_transfer;
    in.scalar_interpolation = P.scalar_interpolation;
    VecX old_rho;
    if (P.pressure_along_path && I.state.p.size() == I.mesh.num_tets()) {
      old_rho = cell_fluid_density(I.mesh, P);
      in.old_pressure = &I.state.p;
      in.old_cell_density = &old_rho;
    }
    for (const PatchConditions& pc : P.patches) {
      in.inflow_density.push_back(pc.smoke_density);
      in.inflow_temperature.push_back(pc.emits_temperature ? pc.temperature
                                                           : P.ambient_temperature);
    }
    TransferOutput out = transfer(in, nm, h);
    s.u = std::move(out.u);
    s.density = std::move(out.density);
    s.temperature = std::move(out.temperature);
    pred.traces_clamped = out.clamped;
  }
  {
    ScopedTimer timer(phases, "forces");
    if (P.smoke_decay > 0) s.density *= std::exp(-P.smoke_decay * h);
    if (P.temperature_decay > 0)
      s.temperature =
          (s.temperature.array() - P.ambient_temperature) * std::exp(-P.temperature_decay * h) +
          P.ambient_temperature;
    I.apply_sources(nm, s);
    if (P.buoyancy_alpha > 0 || P.buoyancy_beta > 0)
      add_cell_acceleration(nm, buoyancy(P, s.density, s.temperature), h, s.u);
    if (P.vorticity_confinement > 0) {
      const MatX3 U = vertex_least_squares(nm, s.u);
      add_cell_acceleration(nm, vorticity_confinement(nm, U, P.vorticity_confinement), h, s.u);
    }
    I.apply_boundary_velocity(nm, solids, s.u);
    pred.rho = cell_fluid_density(nm, P);
    pred.p_open = I.open_q(nm, h) * (P.density / h);
  }
  pred.u_star = std::move(s.u);
  pred.density = std::move(s.density);
  pred.temperature = std::move(s.temperature);
  pred.mesh = std::move(nm);
  return pred;
}

FluidStepReport FluidSimulation::step(TetMesh nm, double h,
                                      const std::vector<SolidSurfaceMotion>& solids,
                                      PhaseTimes& phases) {
  Impl& I = *m_impl;
  const FluidParams& P = I.params;
  FluidPrediction pred = predict(std::move(nm), h, solids, phases);
  I.ensure_solver();
  VecX q;
  VecX u = pred.u_star;
  const VecX qo = pred.p_open * (h / P.density);
  const ProjectionReport pr = project(pred.mesh, P.min_dual_fraction, qo, u, q, *I.solver);
  phases.add("assembly", pr.assembly_s);
  phases.add("solve", pr.setup_s + pr.solve_s);
  logger().debug("pressure solve: {} cells, setup {:.3f} s, solve {:.3f} s, {} iterations",
                 pred.mesh.num_tets(), pr.setup_s, pr.solve_s, pr.iterations);
  if (!pr.converged)
    logger().warn("fluid pressure solve did not converge: {} iterations, residual {:.3g}",
                  pr.iterations, pr.residual);
  // q = h p / ρ per region (the pressure matrix has no entries between regions).
  const VecX p_dyn = q.cwiseProduct(pred.rho) / h;
  TETFSI_REQUIRE(SolverError, u.allFinite() && p_dyn.allFinite(),
                 "fluid state became non-finite at t = {:.6g} s (pressure solve residual {:.3g}); "
                 "reduce time.dt",
                 I.time + h, pr.residual);
  FluidStepReport rep = commit(std::move(pred), std::move(u), p_dyn);
  rep.converged = pr.converged;
  rep.iterations = pr.iterations;
  rep.residual = pr.residual;
  rep.divergence_before = pr.divergence_before;
  rep.divergence_after = pr.divergence_after;
  return rep;
}

FluidStepReport FluidSimulation::commit(FluidPrediction pred, VecX u, VecX p_dyn) {
  Impl& I = *m_impl;
  const FluidParams& P = I.params;
  TetMesh& nm = pred.mesh;
  TETFSI_CHECK(u.size() == nm.num_faces() && p_dyn.size() == nm.num_tets(),
               "commit: u has {} of {} faces, p {} of {} cells", u.size(), nm.num_faces(),
               p_dyn.size(), nm.num_tets());
  TETFSI_REQUIRE(SolverError,
                 u.allFinite() && p_dyn.allFinite() && pred.density.allFinite() &&
                     pred.temperature.allFinite(),
                 "fluid state became non-finite at t = {:.6g} s; reduce time.dt", I.time + pred.h);
  const double h = pred.h;
  FluidStepReport rep;
  rep.traces_clamped = pred.traces_clamped;
  FluidState s;
  s.u = std::move(u);
  s.density = std::move(pred.density);
  s.temperature = std::move(pred.temperature);
  s.p = std::move(p_dyn);
  for (Index t = 0; t < nm.num_tets(); ++t)
    s.p[t] += hydrostatic_pressure(pred.rho[t], P.gravity, P.hydrostatic_origin,
                                   nm.circumcentres.row(t).transpose());
  I.mesh = std::move(nm);
  I.state = std::move(s);
  I.time += h;

  const TetMesh& m = I.mesh;
  const MatX3 uc = cell_velocities();
  const VecX speed = uc.rowwise().norm();
  const VecX dx = cell_sizes(m);
  rep.kinetic_energy = 0.5 * (m.volumes.array() * pred.rho.array() * speed.array().square()).sum();
  rep.smoke_mass = m.volumes.dot(I.state.density);
  rep.max_speed = I.state.u.size() ? I.state.u.cwiseAbs().maxCoeff() : 0.0;
  rep.cfl = m.num_tets() ? (h * speed.array() / dx.array()).maxCoeff() : 0.0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const double q_f = m.face_areas[f] * I.state.u[f];
    switch (m.face_kind[f]) {
      case FaceKind::Inflow:
        rep.inflow_flux -= q_f;
        break;
      case FaceKind::Open:
        rep.outflow_flux += q_f;
        break;
      case FaceKind::Solid:
        rep.solid_flux += q_f;
        break;
      default:
        break;
    }
  }
  return rep;
}

void FluidSimulation::set_state(FluidState s) {
  const TetMesh& m = m_impl->mesh;
  TETFSI_REQUIRE(InputError,
                 s.u.size() == m.num_faces() && s.p.size() == m.num_tets() &&
                     s.density.size() == m.num_tets() && s.temperature.size() == m.num_tets(),
                 "fluid state sizes (u {}, p {}, density {}, temperature {}) do not match the mesh "
                 "({} faces, {} cells)",
                 s.u.size(), s.p.size(), s.density.size(), s.temperature.size(), m.num_faces(),
                 m.num_tets());
  TETFSI_REQUIRE(
      InputError,
      s.u.allFinite() && s.p.allFinite() && s.density.allFinite() && s.temperature.allFinite(),
      "fluid state has non-finite values");
  m_impl->state = std::move(s);
}

const TetMesh& FluidSimulation::mesh() const {
  return m_impl->mesh;
}
const FluidState& FluidSimulation::state() const {
  return m_impl->state;
}
const FluidParams& FluidSimulation::params() const {
  return m_impl->params;
}
double FluidSimulation::time() const {
  return m_impl->time;
}

VelocityField FluidSimulation::velocity_field() const {
  return VelocityField(m_impl->mesh, m_impl->state.u, m_impl->params.reconstruction);
}

MatX3 FluidSimulation::cell_velocities() const {
  return velocity_field().cell_velocities();
}

MatX3 FluidSimulation::vertex_velocities() const {
  return velocity_field().vertex_velocities();
}

VecX FluidSimulation::vorticity_magnitude() const {
  return velocity_field().vorticity_magnitude();
}

RefineField FluidSimulation::refinement_field() const {
  const RefineParams& rp = m_impl->params.refine;
  const TetMesh& m = m_impl->mesh;
  if (!(rp.size > 0) || m.num_tets() == 0) return {};
  // A voxel grid of spacing `size` over the mesh's box, marking the voxels that hold the
  // centroid of a significant cell, dilated by one voxel.
  const Vec3 lo = m.vertices.colwise().minCoeff().transpose();
  const Vec3 hi = m.vertices.colwise().maxCoeff().transpose();
  double cell = rp.size;
  Vec3i n;
  for (;;) {
    for (int a = 0; a < 3; ++a)
      n[a] = std::max(1, static_cast<int>(std::ceil((hi[a] - lo[a]) / cell)));
    if (static_cast<double>(n[0]) * n[1] * n[2] <= 8e6) break;
    cell *= 1.25;
  }
  std::vector<std::uint8_t> mark(static_cast<size_t>(n[0]) * n[1] * n[2], 0);
  auto idx = [&](int i, int j, int k) { return (static_cast<size_t>(k) * n[1] + j) * n[0] + i; };
  const VecX vort = rp.vorticity_threshold > 0 ? vorticity_magnitude() : VecX();
  Index marked = 0;
  for (Index t = 0; t < m.num_tets(); ++t) {
    const bool smoke = m_impl->state.density[t] > rp.density_threshold;
    const bool swirl = vort.size() && vort[t] > rp.vorticity_threshold;
    if (!smoke && !swirl) continue;
    const Vec3 c = mesh::tet_centroid(m, t);
    Vec3i v;
    for (int a = 0; a < 3; ++a)
      v[a] = std::clamp(static_cast<int>((c[a] - lo[a]) / cell), 0, n[a] - 1);
    for (int dk = -1; dk <= 1; ++dk)
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
          const int i = v[0] + di, j = v[1] + dj, k = v[2] + dk;
          if (i < 0 || j < 0 || k < 0 || i >= n[0] || j >= n[1] || k >= n[2]) continue;
          mark[idx(i, j, k)] = 1;
        }
    ++marked;
  }
  if (marked == 0) return {};
  const double size = rp.size;
  return [mark = std::move(mark), lo, n, cell, size](const Vec3& x) -> double {
    Vec3i v;
    for (int a = 0; a < 3; ++a) {
      const int i = floor_index((x[a] - lo[a]) / cell);
      if (i < 0 || i >= n[a]) return 0.0;
      v[a] = i;
    }
    return mark[(static_cast<size_t>(v[2]) * n[1] + v[1]) * n[0] + v[0]] ? size : 0.0;
  };
}

void FluidSimulation::save_state(CheckpointWriter& w, const std::string& prefix) const {
  const Impl& I = *m_impl;
  TETFSI_CHECK(I.initialized, "FluidSimulation::save_state before initialize");
  mesh::save_mesh(I.mesh, w, prefix + "mesh/");
  w.put(prefix + "u", I.state.u);
  w.put(prefix + "p", I.state.p);
  w.put(prefix + "density", I.state.density);
  w.put(prefix + "temperature", I.state.temperature);
  w.put(prefix + "time", I.time);
}

void FluidSimulation::load_state(const CheckpointReader& r, const std::string& prefix) {
  TetMesh m = mesh::load_mesh(r, prefix + "mesh/");
  FluidState s;
  s.u = r.get<VecX>(prefix + "u");
  s.p = r.get<VecX>(prefix + "p");
  s.density = r.get<VecX>(prefix + "density");
  s.temperature = r.get<VecX>(prefix + "temperature");
  if (s.u.size() != m.num_faces() || s.p.size() != m.num_tets() ||
      s.density.size() != m.num_tets() || s.temperature.size() != m.num_tets())
    r.fail(
        fmt::format("its fluid fields (u {}, p {}, density {}, temperature {}) do not fit its "
                    "mesh ({} faces, {} cells)",
                    s.u.size(), s.p.size(), s.density.size(), s.temperature.size(), m.num_faces(),
                    m.num_tets()));
  const double t = r.get_double(prefix + "time");
  Impl& I = *m_impl;
  I.mesh = std::move(m);
  I.state = std::move(s);
  I.time = t;
  I.initialized = true;
}

MeshFrameFields mesh_frame_fields(const FluidSimulation& sim) {
  MeshFrameFields f;
  const FluidState& s = sim.state();
  f.pressure = s.p;
  f.face_velocity = s.u;
  f.density = s.density;
  f.temperature = s.temperature;
  const VelocityField v = sim.velocity_field();  // one reconstruction for all three
  f.vorticity = v.vorticity_magnitude();
  f.divergence = divergence(sim.mesh(), s.u);
  f.cell_velocity = v.cell_velocities();
  f.vertex_velocity = v.vertex_velocities();
  return f;
}

}  // namespace tetfsi::fluid
