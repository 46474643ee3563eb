/// Tests of the simultaneous coupled solve (coupling/coupled_system.cpp) and the coupled
/// step (coupling/coupled_step.cpp) [Chentanez06, Eqs. (6)–(8)], [VALIDATION.md, "Coupled
/// fluid–solid"].
#include <doctest/doctest.h>

#include <cmath>

#include "coupling/coupled_system.hpp"
#include "fluid/operators.hpp"
#include "solid/integrator.hpp"
#include "tests/coupling/coupled_test_utils.hpp"
#include "tests/solid/solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;
using namespace tetfsi::test;
using solid::testing::make_material;

namespace {

/// A soft cube (ρ_s = 2000) in a water box open at the top, with a swirl in the water.
CoupledRig cube_in_water(double size) {
  CoupledRig r;
  r.world.gravity = Vec3(0, 0, -9.81);
  r.world.bodies.emplace_back(
      "cube", mesh::make_box(Vec3(0.4, 0.4, 0.35), Vec3(0.6, 0.6, 0.55), Vec3i(3, 3, 3)),
      make_material(2000, 2e4, 0.3, 0.0, 0.01));
  r.domain = box_domain(Vec3::Zero(), Vec3::Ones());
  mesh::DomainPatch top;
  top.kind = mesh::FaceKind::Open;
  top.side = 5;
  top.lo = Vec2(0, 0);
  top.hi = Vec2(1, 1);
  r.domain.patches.push_back(top);
  r.sizing = sizing(size, 3 * size);
  r.fluid_params.density = 1000;
  r.fluid_params.gravity = Vec3(0, 0, -9.81);
  r.fluid_params.patches.resize(1);
  r.start();
  // a swirl about the vertical axis, so that v* is not zero
  const mesh::TetMesh& m = r.fluid->mesh();
  fluid::FluidState s = r.fluid->state();
  s.u = face_field(m, [](const Vec3& x) { return Vec3(-(x[1] - 0.5), x[0] - 0.5, 0.0); });
  r.fluid->set_state(s);
  return r;
}

/// The coupled input of the rig's next step (the solve without the stepper).
struct Problem {
  fluid::FluidPrediction pred;
  std::vector<CoupledBody> bodies;
  CoupledInput input(VolumeTargets* targets = nullptr) const {
    CoupledInput in;
    in.mesh = &pred.mesh;
    in.u_star = &pred.u_star;
    in.rho = &pred.rho;
    in.p_open = &pred.p_open;
    in.h = pred.h;
    in.gravity = Vec3(0, 0, -9.81);
    in.bodies = &bodies;
    in.volume_targets = targets;
    return in;
  }
};

Problem next_problem(CoupledRig& r, double h) {
  Problem pb;
  std::vector<MatX3> x;
  for (const auto& b : r.world.bodies) x.push_back(b.positions());
  PhaseTimes ph;
  std::vector<fluid::SolidSurfaceMotion> motion(r.world.bodies.size());
  for (size_t b = 0; b < motion.size(); ++b) {
    motion[b].triangles = r.stepper->surfaces()[b].triangles;
    motion[b].velocity = MatX3::Zero(r.stepper->surfaces()[b].nodes.size(), 3);
  }
  pb.pred = r.fluid->predict(r.build(x), h, motion, ph);
  for (size_t b = 0; b < r.world.bodies.size(); ++b) {
    const solid::SolidBody& body = r.world.bodies[b];
    CoupledBody cb;
    cb.interface.triangles = r.stepper->surfaces()[b].triangles;
    cb.interface.surface_node = r.stepper->surfaces()[b].nodes;
    cb.interface.num_nodes = body.num_nodes();
    solid::TrapezoidalSystem sys =
        solid::assemble_trapezoidal(body, h, body.external_forces(r.world.gravity));
    cb.free = true;
    cb.A = sys.A;
    cb.b = sys.b;
    cb.fixed = body.fixed_dofs();
    cb.x = body.positions();
    cb.u = flat(body.velocity);
    pb.bodies.push_back(cb);
  }
  return pb;
}

}  // namespace

TEST_CASE(
    "coupled solve: the paper's form (UMFPACK, BiCGSTAB+ILU), the symmetric form and the "
    "Schur complement with AMG give the same u and p") {
  CoupledRig r = cube_in_water(0.06);
  const Problem pb = next_problem(r, 0.01);
  CoupledOptions o;
  o.rel_tol = 1e-11;
  o.max_iterations = 5000;
  o.solver = CoupledSolverKind::Umfpack;
  const CoupledSolution ref = solve_coupled(pb.input(), o);
  MESSAGE(ref.report.solid_unknowns << " solid + " << ref.report.pressure_unknowns
                                    << " pressure unknowns");
  const double un = ref.u[0].norm(), pn = ref.p.norm();
  REQUIRE(un > 0);
  REQUIRE(pn > 0);
  for (CoupledSolverKind k : {CoupledSolverKind::SymmetricUmfpack, CoupledSolverKind::SchurAmg,
                              CoupledSolverKind::BiCgStabIlut}) {
    o.solver = k;
    const CoupledSolution s = solve_coupled(pb.input(), o);
    const double du = (s.u[0] - ref.u[0]).norm() / un, dp = (s.p - ref.p).norm() / pn;
    const double df = (s.u_face - ref.u_face).norm() / ref.u_face.norm();
    MESSAGE(std::string(to_string(k)) << ": " << s.report.iterations << " iterations, |du|/|u| = "
                                      << du << ", |dp|/|p| = " << dp << ", faces " << df);
    CHECK(s.report.converged);
    CHECK(du < 1e-6);
    CHECK(dp < 1e-6);
    CHECK(df < 1e-6);
  }
}

TEST_CASE(
    "coupled solve: interface power p^T J^T u equals the fluid's flux power, and the fluid "
    "ends divergence-free") {
  CoupledRig r = cube_in_water(0.06);
  const Problem pb = next_problem(r, 0.01);
  const CoupledSolution s = solve_coupled(pb.input(), CoupledOptions{});
  const mesh::TetMesh& m = pb.pred.mesh;
  // Σ over the body's faces of A_f u_f p_t: the power the solid does on the fluid.
  double fluid_side = 0.0, scale = 0.0;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.face_kind[f] == mesh::FaceKind::Solid) {
      const double w = m.face_areas[f] * s.u_face[f] * s.p[m.face_tets(f, 0)];
      fluid_side += w;
      scale += std::abs(w);
    }
  MESSAGE("p^T J^T u = " << s.report.interface_power << " W, fluid side " << fluid_side
                         << " W, max divergence " << s.report.divergence_before << " -> "
                         << s.report.divergence_after << " 1/s");
  CHECK(std::abs(s.report.interface_power - fluid_side) <= 1e-10 * scale);
  CHECK(s.report.divergence_after < 1e-6 * s.report.divergence_before);
  CHECK(s.report.pinned_regions == 0);
}
