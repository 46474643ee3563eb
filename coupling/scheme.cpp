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

namespace {

std::string fmt_point(const Vec3& v) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}]", v.x(), v.y(), v.z());
}

/// @param x the body's compact surface vertices (BodySurface::nodes order)
void check_inside(const mesh::FluidDomain& domain, const BodySurface& surface,
                  const std::string& name, size_t index, const MatX3& x) {
  const Vec3& lo = domain.lo;
  const Vec3& hi = domain.hi;
  for (Index k = 0; k < x.rows(); ++k) {
    const Vec3 p = x.row(k).transpose();
    if ((p.array() > lo.array()).all() && (p.array() < hi.array()).all()) continue;
    const Vec3 blo = x.colwise().minCoeff().transpose();
    const Vec3 bhi = x.colwise().maxCoeff().transpose();
    throw MeshError(fmt::format(
        "body '{}' (bodies[{}]) is not strictly inside the fluid box {}..{}: node {} is at {} "
        "and the body spans {}..{}; enlarge fluid.domain or keep the body inside",
        name, index, fmt_point(lo), fmt_point(hi), surface.nodes[k], fmt_point(p), fmt_point(blo),
        fmt_point(bhi)));
  }
}

}  // namespace

std::vector<mesh::SolidSurface> place_surfaces(const mesh::FluidDomain& domain,
                                               const std::vector<BodySurface>& surfaces,
                                               const std::vector<std::string>& names,
                                               const std::vector<MatX3>& positions) {
  TETFSI_CHECK(positions.size() == surfaces.size() && names.size() == surfaces.size(),
               "fluid surfaces: {} position sets and {} names for {} bodies", positions.size(),
               names.size(), surfaces.size());
  std::vector<mesh::SolidSurface> solids(surfaces.size());
  for (size_t i = 0; i < surfaces.size(); ++i) {
    const BodySurface& bd = surfaces[i];
    mesh::SolidSurface& s = solids[i];
    s.body = static_cast<int>(i);
    s.triangles = bd.triangles;
    TETFSI_CHECK(bd.nodes.size() == 0 || positions[i].rows() > bd.nodes.maxCoeff(),
                 "fluid surfaces: {} positions for body '{}', its surface uses node {}",
                 positions[i].rows(), names[i], bd.nodes.maxCoeff());
    s.vertices.resize(bd.nodes.size(), 3);
    for (Index k = 0; k < bd.nodes.size(); ++k) s.vertices.row(k) = positions[i].row(bd.nodes[k]);
    check_inside(domain, bd, names[i], i, s.vertices);
  }
  return solids;
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

std::unique_ptr<PredictedFluid> predict_around_predicted(StepContext& ctx, CoupledStepReport& rep) {
  const solid::SolidWorld& world = ctx.world;
  const std::vector<fluid::SolidSurfaceMotion> motion = surface_motion(world, ctx.surfaces);
  std::vector<MatX3> x = node_positions(world, [&](Index b) -> MatX3 {
    const auto& body = world.bodies[b];
    return body.is_kinematic() ? body.displacement
                               : MatX3(body.displacement + ctx.h * body.velocity);
  });
  try {
    return ctx.fluid.predict(x, motion, ctx.h, ctx.phases);
  } catch (const MeshError& e) {
    logger().debug(
        "coupled step: remesh around the predicted surfaces failed ({}); "
        "building around the surfaces at t = {:.6g} s",
        e.what(), world.time);
    rep.predicted_mesh = false;
    return predict_around_current(ctx);
  }
}

std::unique_ptr<PredictedFluid> predict_around_current(StepContext& ctx) {
  const solid::SolidWorld& world = ctx.world;
  return ctx.fluid.predict(
      node_positions(world, [&](Index b) -> MatX3 { return world.bodies[b].displacement; }),
      surface_motion(world, ctx.surfaces), ctx.h, ctx.phases);
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
