/// Tests of the schemes as parts (coupling/scheme.hpp): every scheme is made by make_scheme
/// and advances a rig alone, through the CouplingScheme interface, without CoupledStepper or
/// the command line; the result is a consistent step (the fluid's solution on the step's mesh,
/// divergence-free to the solve's tolerance, the bodies moved and finite).
#include <doctest/doctest.h>

#include <cmath>

#include "core/error.hpp"
#include "coupling/scheme.hpp"
#include "coupling/tet_fluid.hpp"
#include "fluid/tet/operators.hpp"
#include "mesh/generate.hpp"
#include "tests/coupling/coupled_test_utils.hpp"
#include "tests/solid/solid_test_utils.hpp"

using namespace tetfsi;
using namespace tetfsi::coupling;
using namespace tetfsi::test;
using solid::testing::make_material;

namespace {

/// A soft, heavy cube (ρ_s = 8000: its added mass, ~0.1 of its own, lets modified Newton with
/// Eq. (15)'s fluid-free matrix converge too) in a water box open at the top.
CoupledRig cube(Scheme scheme) {
  CoupledRig r;
  r.world().gravity = Vec3(0, 0, -9.81);
  r.world().bodies.emplace_back(
      "cube", mesh::make_box(Vec3(0.4, 0.4, 0.35), Vec3(0.6, 0.6, 0.55), Vec3i(2, 2, 2)),
      make_material(8000, 2e4, 0.3, 0.0, 0.01));
  water_box_open_top(r);
  r.sizing = sizing(0.08, 0.25);
  r.coupling.scheme = scheme;
  r.start();
  return r;
}

}  // namespace

TEST_CASE("schemes: each one, made by make_scheme, advances the bodies and the fluid alone") {
  const double h = 0.01;
  for (Scheme s : {Scheme::Simultaneous, Scheme::Splitting, Scheme::Bfgs, Scheme::ModifiedNewton,
                   Scheme::Newton}) {
    const std::string name = to_string(s);
    CAPTURE(name);
    CoupledRig r = cube(s);
    CouplingParams p;
    p.scheme = s;
    const std::unique_ptr<CouplingScheme> scheme = make_scheme(p);
    CHECK(scheme->kind() == s);
    CHECK(parse_scheme(to_string(s)) == s);

    solid::SolidWorld& world = r.world();
    const MatX3 d0 = world.bodies[0].displacement;
    const MeshBuilder build = [&](const std::vector<MatX3>& x) { return r.build(x); };
    PhaseTimes phases;
    TetCoupledFluid fluid(r.fluid(), build, body_interfaces(world, r.surfaces()));
    StepContext ctx{world, fluid, r.surfaces(), h, phases};
    std::unique_ptr<PredictedFluid> pred;
    CoupledStepReport rep;
    const CoupledSolution sol = scheme->advance(ctx, pred, rep);

    const auto* tp = dynamic_cast<const TetPrediction*>(pred.get());
    REQUIRE(tp);
    const mesh::TetMesh& m = tp->prediction().mesh;
    REQUIRE(m.num_tets() > 0);
    CHECK(sol.u_face.size() == m.num_faces());
    CHECK(sol.p.size() == m.num_tets());
    CHECK(sol.report.converged);
    // the face velocities are divergence-free on the step's mesh, relative to the flow's
    // scale max |u| / cell size (the iterated schemes' fluid-only solves stop at 1e-5)
    const double div =
        fluid::net_flux(m, sol.u_face).cwiseQuotient(m.volumes).cwiseAbs().maxCoeff();
    const double scale = sol.u_face.cwiseAbs().maxCoeff() / 0.08;
    MESSAGE(name << ": max |D u| = " << div << " (1/s), max |u| / cell = " << scale);
    CHECK(scale > 0.0);
    CHECK(div <= 1e-4 * scale);
    // the heavy cube sinks: it moved, and its state is finite
    const solid::SolidBody& body = world.bodies[0];
    CHECK(body.displacement.allFinite());
    CHECK(body.velocity.allFinite());
    CHECK((body.displacement - d0).cwiseAbs().maxCoeff() > 0.0);
    CHECK(body.velocity.col(2).mean() < 0.0);
    if (is_iterated(s)) CHECK(rep.equilibrium.converged);
  }
  CHECK_THROWS_AS(parse_scheme("implicit"), InputError);
}
