/// @file tet_fluid.cpp
/// TetCoupledFluid (tet_fluid.hpp): the tet fluid's side of every coupling scheme; TetSimFluid:
/// the tet fluid of a simulation.
#include "coupling/tet_fluid.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "coupling/half_cells.hpp"
#include "fluid/tet/interface.hpp"
#include "fluid/tet/operators.hpp"

namespace tetfsi::coupling {

TetPrediction::TetPrediction(fluid::FluidPrediction pred, const fluid::FluidParams& params,
                             const std::vector<BodyInterface>& bodies,
                             const std::vector<MatX3>& positions)
    : m_pred(std::move(pred)),
      m_params(params),
      m_ops(m_pred.mesh, bodies),
      m_half_cells(half_cell_lengths(m_pred.mesh, bodies, positions)) {}

CoupledSolution TetPrediction::solve(const std::vector<CoupledBody>& bodies,
                                     const CoupledOptions& opt, const SolveVariant& v) const {
  CoupledInput in = make_input(m_pred, m_params, m_ops, bodies, v.targets);
  in.half_cell_lengths = &m_half_cells;
  if (v.u_star) in.u_star = v.u_star;
  VecX zero_f;
  if (v.homogeneous) {
    zero_f = VecX::Zero(m_pred.mesh.num_faces());
    in.u_star = &zero_f;
    in.u_ref = &zero_f;
    in.p_open = &zero_f;
    in.gravity = Vec3::Zero();
  }
  return solve_coupled(in, opt);
}

void TetPrediction::refuse_sealed_regions(const solid::SolidWorld& world,
                                          const char* scheme) const {
  const mesh::TetMesh& m = m_pred.mesh;
  const fluid::Regions regions = fluid::fluid_regions(m);
  std::vector<Index> cells(regions.count(), 0);
  for (Index t = 0; t < m.num_tets(); ++t) ++cells[regions.cell_region[t]];
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (!m.is_boundary(f) || m.face_kind[f] != mesh::FaceKind::Solid) continue;
    const Index r = regions.cell_region[m.face_tets(f, 0)];
    const solid::SolidBody& body = world.bodies[m.face_body[f]];
    TETFSI_REQUIRE(InputError, regions.has_open[r] || body.is_kinematic(),
                   "coupling.scheme {}: a fluid region of {} cells has no open face and is "
                   "bounded by body '{}': a fluid-only projection cannot keep its volume; use "
                   "coupling.scheme simultaneous, or give the region an open patch",
                   scheme, cells[r], body.name());
  }
}

TetCoupledFluid::TetCoupledFluid(fluid::FluidSimulation& fluid, MeshBuilder build,
                                 std::vector<BodyInterface> bodies)
    : m_fluid(fluid), m_build(std::move(build)), m_bodies(std::move(bodies)) {}

std::unique_ptr<PredictedFluid> TetCoupledFluid::predict(
    const std::vector<MatX3>& positions, const std::vector<fluid::SolidSurfaceMotion>& motions,
    double h, PhaseTimes& phases) {
  mesh::TetMesh m = m_build(positions);
  return std::make_unique<TetPrediction>(m_fluid.predict(std::move(m), h, motions, phases),
                                         m_fluid.params(), m_bodies, positions);
}

fluid::FluidStepReport TetCoupledFluid::commit(std::unique_ptr<PredictedFluid> pred,
                                               CoupledSolution& sol) {
  auto* tp = dynamic_cast<TetPrediction*>(pred.get());
  TETFSI_CHECK(tp, "TetCoupledFluid::commit: a prediction of another fluid");
  return m_fluid.commit(std::move(tp->prediction()), std::move(sol.u_face), std::move(sol.p));
}

namespace {

/// The fluid's nodal forces on the bodies (3n each) of the pressure on the fluid's mesh: the
/// dynamic part through J at the cells, the hydrostatic part at the face centroids.
std::vector<VecX> mesh_forces(const fluid::FluidSimulation& fluid,
                              const std::vector<BodyInterface>& bodies) {
  const mesh::TetMesh& m0 = fluid.mesh();
  const fluid::FluidParams& fp = fluid.params();
  const VecX rho = fluid::cell_fluid_density(m0, fp);
  VecX p_dyn = fluid.state().p;
  for (Index t = 0; t < m0.num_tets(); ++t)
    p_dyn[t] -= fluid::hydrostatic_pressure(rho[t], fp.gravity, fp.hydrostatic_origin,
                                            m0.circumcentres.row(t).transpose());
  const InterfaceOperators ops(m0, bodies);
  return fluid_forces(ops, p_dyn, rho, fp.gravity, fp.hydrostatic_origin);
}

}  // namespace

std::vector<VecX> TetCoupledFluid::current_forces(const std::vector<BodyInterface>& bodies) const {
  return mesh_forces(m_fluid, bodies);
}

// ---- the tet fluid of a simulation -------------------------------------------------------

TetSimFluid::TetSimFluid(const fluid::FluidParams& params, const RemeshPolicy& policy)
    : m_fluid(params), m_policy(policy) {}

mesh::TetMesh TetSimFluid::build_mesh(const std::vector<MatX3>& positions, PhaseTimes& phases) {
  ScopedTimer timer(phases, "remesh");
  mesh::RemeshReport report;
  fluid::RefineField refine;
  if (m_started) refine = m_fluid.refinement_field();
  mesh::TetMesh m = m_policy.build(positions, m_started ? &refine : nullptr, &report);
  const double seconds = timer.stop();
  if (m_observer) m_observer(m, report, seconds, phases);
  return m;
}

void TetSimFluid::start(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_started = false;
  m_fluid.initialize(build_mesh(body_positions(world), phases));
  m_started = true;
}

void TetSimFluid::rebuild_at_rest(const solid::SolidWorld& world, PhaseTimes& phases) {
  m_fluid.initialize(build_mesh(body_positions(world), phases));
  m_started = true;
}

FluidStepAlone TetSimFluid::step_alone(const solid::SolidWorld& world, double h, PhaseTimes& phases,
                                       PhaseTimes& fluid_phases) {
  const std::vector<fluid::SolidSurfaceMotion> motion = surface_motion(world, m_policy.surfaces());
  mesh::TetMesh m = build_mesh(body_positions(world), phases);
  FluidStepAlone r;
  const double t0 = now_seconds();
  r.report = m_fluid.step(std::move(m), h, motion, fluid_phases);
  r.seconds = now_seconds() - t0;
  return r;
}

std::unique_ptr<CoupledFluid> TetSimFluid::coupled(std::vector<BodyInterface> bodies,
                                                   PhaseTimes& phases) {
  MeshBuilder build = [this, &phases](const std::vector<MatX3>& x) {
    return build_mesh(x, phases);
  };
  return std::make_unique<TetCoupledFluid>(m_fluid, std::move(build), std::move(bodies));
}

std::vector<VecX> TetSimFluid::body_forces(const solid::SolidWorld& world) const {
  TETFSI_CHECK(m_started, "TetSimFluid::body_forces: the tet fluid has not started");
  return mesh_forces(m_fluid, body_interfaces(world, m_policy.surfaces()));
}

fluid::FluidFrame TetSimFluid::frame(const solid::SolidWorld&) const {
  fluid::FluidFrame frame;
  if (m_started)
    frame.geometry = fluid::MeshFrame{&m_fluid.mesh(), fluid::mesh_frame_fields(m_fluid)};
  return frame;
}

std::string TetSimFluid::start_summary(double seconds) const {
  const mesh::TetMesh& m = m_fluid.mesh();
  return fmt::format("fluid mesh at t = 0: {} tets, {} vertices, {} faces, built in {:.3g} s\n",
                     m.num_tets(), m.num_vertices(), m.num_faces(), seconds);
}

void TetSimFluid::save_state(CheckpointWriter& w, const std::string& prefix) const {
  m_fluid.save_state(w, prefix + "fluid/");
}

void TetSimFluid::load_state(const CheckpointReader& r, const std::string& prefix) {
  m_fluid.load_state(r, prefix + "fluid/");
  m_started = true;
}

}  // namespace tetfsi::coupling
