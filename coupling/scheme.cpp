#include "coupling/scheme.hpp"

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::coupling {

// Implemented in their own files.
std::unique_ptr<CouplingScheme> make_simultaneous_scheme(const CouplingParams& params);
std::unique_ptr<CouplingScheme> make_splitting_scheme(const CouplingParams& params);
std::unique_ptr<CouplingScheme> make_iterated_scheme(const CouplingParams& params);

Scheme parse_scheme(const std::string& name) {
  return k_scheme_names.parse(name);
}

const char* to_string(Scheme s) {
  return k_scheme_names.name(s);
}

bool is_iterated(Scheme s) {
  return s == Scheme::Bfgs || s == Scheme::ModifiedNewton || s == Scheme::Newton;
}

std::unique_ptr<CouplingScheme> make_scheme(const CouplingParams& params) {
  switch (params.scheme) {
    case Scheme::Simultaneous:
      return make_simultaneous_scheme(params);
    case Scheme::Splitting:
      return make_splitting_scheme(params);
    case Scheme::Bfgs:
    case Scheme::ModifiedNewton:
    case Scheme::Newton:
      return make_iterated_scheme(params);
  }
  throw InputError("unknown coupling scheme");
}

BodySurface body_surface(const solid::SolidBody& b) {
  BodySurface bd;
  const MatX3i& tris = b.boundary_triangles();
  VecXi local = VecXi::Constant(b.num_nodes(), -1);
  std::vector<Index> nodes;
  bd.triangles.resize(tris.rows(), 3);
  for (Index t = 0; t < tris.rows(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const Index v = tris(t, k);
      if (local[v] < 0) {
        local[v] = static_cast<Index>(nodes.size());
        nodes.push_back(v);
      }
      bd.triangles(t, k) = local[v];
    }
  }
  bd.nodes = Eigen::Map<const VecXi>(nodes.data(), static_cast<Index>(nodes.size()));
  return bd;
}

std::vector<MatX3> node_positions(const solid::SolidWorld& world,
                                  const std::function<MatX3(Index)>& disp) {
  const Index nb = static_cast<Index>(world.bodies.size());
  std::vector<MatX3> x(nb);
  for (Index b = 0; b < nb; ++b) x[b] = world.bodies[b].rest_positions() + disp(b);
  return x;
}

std::vector<fluid::SolidSurfaceMotion> surface_motion(const solid::SolidWorld& world,
                                                      const std::vector<BodySurface>& surfaces) {
  std::vector<fluid::SolidSurfaceMotion> s(world.bodies.size());
  for (size_t b = 0; b < s.size(); ++b) {
    s[b].triangles = surfaces[b].triangles;
    s[b].velocity.resize(surfaces[b].nodes.size(), 3);
    for (Index k = 0; k < surfaces[b].nodes.size(); ++k)
      s[b].velocity.row(k) = world.bodies[b].velocity.row(surfaces[b].nodes[k]);
  }
  return s;
}

std::vector<BodyInterface> body_interfaces(const solid::SolidWorld& world,
                                           const std::vector<BodySurface>& surfaces) {
  std::vector<BodyInterface> ifaces(world.bodies.size());
  for (size_t b = 0; b < ifaces.size(); ++b) {
    ifaces[b].triangles = surfaces[b].triangles;
    ifaces[b].surface_node = surfaces[b].nodes;
    ifaces[b].num_nodes = world.bodies[b].num_nodes();
  }
  return ifaces;
}

mesh::TetMesh build_predicted(StepContext& ctx, CoupledStepReport& rep) {
  const solid::SolidWorld& world = ctx.world;
  try {
    return ctx.build(node_positions(world, [&](Index b) -> MatX3 {
      const auto& body = world.bodies[b];
      return body.is_kinematic() ? body.displacement
                                 : MatX3(body.displacement + ctx.h * body.velocity);
    }));
  } catch (const MeshError& e) {
    logger().debug(
        "coupled step: remesh around the predicted surfaces failed ({}); "
        "building around the surfaces at t = {:.6g} s",
        e.what(), world.time);
    rep.predicted_mesh = false;
    return ctx.build(
        node_positions(world, [&](Index b) -> MatX3 { return world.bodies[b].displacement; }));
  }
}

void add_solve_phases(PhaseTimes& phases, const CoupledReport& r) {
  phases.add("coupled_assembly", r.assembly_s);
  phases.add("coupled_solve", r.setup_s + r.solve_s);
}

void check_finite(const solid::SolidBody& body, double h) {
  TETFSI_REQUIRE(SolverError, body.displacement.allFinite() && body.velocity.allFinite(),
                 "body '{}': state became non-finite at a step with h = {}; reduce time.dt or "
                 "raise rayleigh damping",
                 body.name(), h);
}

}  // namespace tetfsi::coupling
