#include "coupling/coupled_step.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include <Eigen/QR>

#include "core/error.hpp"
#include "core/log.hpp"
#include "fluid/operators.hpp"
#include "solid/integrator.hpp"
#include "solid/nonlinear_trapezoid.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::coupling {

Scheme parse_scheme(const std::string& name) {
  if (name == "simultaneous") return Scheme::Simultaneous;
  if (name == "splitting") return Scheme::Splitting;
  if (name == "bfgs") return Scheme::Bfgs;
  if (name == "modified_newton") return Scheme::ModifiedNewton;
  if (name == "newton") return Scheme::Newton;
  throw InputError(fmt::format(
      "unknown coupling scheme '{}': use simultaneous, splitting, bfgs, modified_newton or newton",
      name));
}

const char* to_string(Scheme s) {
  switch (s) {
    case Scheme::Simultaneous:
      return "simultaneous";
    case Scheme::Splitting:
      return "splitting";
    case Scheme::Bfgs:
      return "bfgs";
    case Scheme::ModifiedNewton:
      return "modified_newton";
    case Scheme::Newton:
      return "newton";
  }
  return "?";
}

bool is_iterated(Scheme s) {
  return s == Scheme::Bfgs || s == Scheme::ModifiedNewton || s == Scheme::Newton;
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

CoupledStepper::CoupledStepper(CouplingParams params, const solid::SolidWorld& world)
    : m_params(std::move(params)) {
  for (const solid::SolidBody& b : world.bodies) m_surfaces.push_back(body_surface(b));
}

namespace {

/// d, u and time of the world, to leave it at tⁿ when a step fails.
struct Snapshot {
  double time = 0.0;
  std::vector<std::pair<MatX3, MatX3>> state;
  explicit Snapshot(const solid::SolidWorld& w) : time(w.time) {
    for (const auto& b : w.bodies) state.emplace_back(b.displacement, b.velocity);
  }
  void restore(solid::SolidWorld& w) const {
    w.time = time;
    for (size_t i = 0; i < state.size(); ++i) {
      w.bodies[i].displacement = state[i].first;
      w.bodies[i].velocity = state[i].second;
    }
  }
};

/// A node held on a floor (an axis-aligned Plane obstacle) during a coupled step.
struct Contact {
  Index node = -1;
  int axis = 0;
  double sign = 1.0;      ///< the plane's normal is sign · e_axis
  double incoming = 0.0;  ///< normal velocity at tⁿ (< 0: approaching)
  const solid::Obstacle* obstacle = nullptr;
};

/// Contacts as velocity constraints of the coupled solve: a node whose predicted position
/// xⁿ + h uⁿ + ½ h² g is below an axis-aligned plane gets the normal velocity that puts it on
/// the plane by Eq. (5), u_n = −2 gapⁿ/h − uⁿ_n. Its position stays exact — the enclosed
/// volume then sees exactly what the solve saw, where projecting nodes out after the step
/// would change it by the penetration — and its velocity is stopped after (step()).
std::vector<Contact> floor_contacts(const solid::SolidBody& body,
                                    const std::vector<solid::Obstacle>& obstacles,
                                    const Vec3& gravity, double h, VecX& prescribed,
                                    std::vector<std::uint8_t>& fixed) {
  std::vector<Contact> out;
  const MatX3 x = body.positions();
  for (Index i = 0; i < body.num_nodes(); ++i) {
    for (const solid::Obstacle& o : obstacles) {
      if (o.kind != solid::Obstacle::Kind::Plane) continue;
      int axis = -1;
      for (int a = 0; a < 3; ++a)
        if (std::abs(std::abs(o.normal[a]) - 1.0) < 1e-12) axis = a;
      if (axis < 0) continue;
      const double sign = o.normal[axis] > 0 ? 1.0 : -1.0;
      const Index dof = 3 * i + axis;
      if (fixed[dof]) continue;
      const double gap = sign * (x(i, axis) - o.point[axis]);
      const double un = sign * body.velocity(i, axis);
      const double pred = gap + h * un + 0.5 * h * h * sign * gravity[axis];
      if (pred >= 0.0) continue;
      Contact c;
      c.node = i;
      c.axis = axis;
      c.sign = sign;
      c.incoming = un;
      c.obstacle = &o;
      fixed[dof] = 1;
      prescribed[dof] = sign * (-2.0 * gap / h - un);  // lands on the plane by Eq. (5)
      out.push_back(c);
      break;
    }
  }
  return out;
}

/// Eliminate DOF `dof` from the symmetric A u = b with the value v (row and column zeroed,
/// the column moved into b, diagonal `diag`).
void eliminate(SparseMatrix& A, VecX& b, Index dof, double v, double diag) {
  std::vector<Index> rows;
  for (SparseMatrix::InnerIterator it(A, dof); it; ++it) {
    if (it.row() != dof) {
      b[it.row()] -= it.value() * v;
      rows.push_back(it.row());
    }
    it.valueRef() = it.row() == dof ? diag : 0.0;
  }
  for (const Index r : rows) A.coeffRef(dof, r) = 0.0;  // the symmetric entries of row dof
  b[dof] = diag * v;
}

void check_finite(const solid::SolidBody& body, double h) {
  TETFSI_REQUIRE(SolverError, body.displacement.allFinite() && body.velocity.allFinite(),
                 "body '{}': state became non-finite at a step with h = {}; reduce time.dt or "
                 "raise rayleigh damping",
                 body.name(), h);
}

/// The fluid-only solution is affine in the bodies' face velocities (a linear solve with them
/// in its right-hand side): once points x₀ … x_k have been solved, any x in their affine span
/// gets p, the face velocities and the nodal forces by the same combination, exactly up to the
/// solves' tolerance. The line search's points x + β Δx are on the line through two solved
/// points, so each BFGS iteration costs one fluid solve, not one per trial β.
struct AffineFluidCache {
  std::vector<VecX> x;
  std::vector<CoupledSolution> s;

  bool combine(const VecX& xq, CoupledSolution& out) const {
    const Index k = static_cast<Index>(x.size()) - 1;
    if (k < 1) return false;
    Eigen::MatrixXd D(xq.size(), k);
    for (Index j = 0; j < k; ++j) D.col(j) = x[j + 1] - x[0];
    const VecX r = xq - x[0];
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(D);
    if (qr.rank() < k) return false;
    const VecX c = qr.solve(r);
    // in the span to round-off, and not a large extrapolation (that would amplify the solves'
    // errors)
    if (!((D * c - r).norm() <= 1e-11 * std::max(r.norm(), xq.norm())) ||
        !(c.cwiseAbs().maxCoeff() <= 1e3))
      return false;
    out = s[0];
    for (Index j = 0; j < k; ++j) {
      const CoupledSolution& sj = s[j + 1];
      out.p += c[j] * (sj.p - s[0].p);
      out.u_face += c[j] * (sj.u_face - s[0].u_face);
      for (size_t b = 0; b < out.fluid_force.size(); ++b)
        out.fluid_force[b] += c[j] * (sj.fluid_force[b] - s[0].fluid_force[b]);
    }
    return true;
  }
  void add(const VecX& xq, const CoupledSolution& sol) {
    if (x.size() >= 40) return;  // enough for any step; keeps the QR small
    x.push_back(xq);
    s.push_back(sol);
  }
};

}  // namespace

CoupledStepReport CoupledStepper::step(solid::SolidWorld& world, fluid::FluidSimulation& fluid,
                                       const MeshBuilder& build, double h, PhaseTimes& phases) {
  TETFSI_REQUIRE(InputError, std::isfinite(h) && h > 0, "coupled step: dt must be > 0, got {}", h);
  const Index nb = static_cast<Index>(world.bodies.size());
  TETFSI_CHECK(static_cast<Index>(m_surfaces.size()) == nb,
               "coupled step: the world has {} bodies, the stepper was made for {}", nb,
               m_surfaces.size());
  const Snapshot snap(world);
  const double t1 = world.time + h;
  const Vec3 g_fluid = fluid.params().gravity;
  CoupledStepReport rep;
  rep.scheme = m_params.scheme;

  std::vector<BodyInterface> ifaces(nb);
  for (Index b = 0; b < nb; ++b) {
    ifaces[b].triangles = m_surfaces[b].triangles;
    ifaces[b].surface_node = m_surfaces[b].nodes;
    ifaces[b].num_nodes = world.bodies[b].num_nodes();
  }
  auto positions = [&](auto&& disp) {
    std::vector<MatX3> x(nb);
    for (Index b = 0; b < nb; ++b) x[b] = world.bodies[b].rest_positions() + disp(b);
    return x;
  };
  auto motion = [&] {
    std::vector<fluid::SolidSurfaceMotion> s(nb);
    for (Index b = 0; b < nb; ++b) {
      s[b].triangles = m_surfaces[b].triangles;
      s[b].velocity.resize(m_surfaces[b].nodes.size(), 3);
      for (Index k = 0; k < m_surfaces[b].nodes.size(); ++k)
        s[b].velocity.row(k) = world.bodies[b].velocity.row(m_surfaces[b].nodes[k]);
    }
    return s;
  };
  auto solve_phases = [&](const CoupledReport& r) {
    phases.add("coupled_assembly", r.assembly_s);
    phases.add("coupled_solve", r.setup_s + r.solve_s);
  };
  // The mesh around x* = X + dⁿ + h uⁿ (kinematic bodies at tⁿ⁺¹), or around xⁿ if that fails
  // (a body predicted out of the box).
  auto build_predicted = [&]() -> mesh::TetMesh {
    try {
      return build(positions([&](Index b) -> MatX3 {
        const auto& body = world.bodies[b];
        return body.is_kinematic() ? body.displacement
                                   : MatX3(body.displacement + h * body.velocity);
      }));
    } catch (const MeshError& e) {
      logger().debug(
          "coupled step: remesh around the predicted surfaces failed ({}); "
          "building around the surfaces at t = {:.6g} s",
          e.what(), world.time);
      rep.predicted_mesh = false;
      return build(positions([&](Index b) -> MatX3 { return world.bodies[b].displacement; }));
    }
  };

  try {
    fluid::FluidPrediction pred;
    CoupledSolution sol;
    if (m_params.scheme == Scheme::Simultaneous) {
      // 1. each deformable body's Eq. (4) at dⁿ; kinematic bodies to tⁿ⁺¹
      std::vector<CoupledBody> cb(nb);
      std::vector<std::vector<Contact>> contacts(nb);
      {
        ScopedTimer timer(phases, "coupled_assembly");
        for (Index b = 0; b < nb; ++b) {
          solid::SolidBody& body = world.bodies[b];
          cb[b].interface = ifaces[b];
          if (body.is_kinematic()) {
            body.set_kinematic_state(t1);
            continue;
          }
          solid::TrapezoidalSystem sys = solid::assemble_trapezoidal(
              body, h, body.external_forces(world.gravity), world.trapezoid);
          cb[b].free = true;
          cb[b].A = std::move(sys.A);
          cb[b].b = std::move(sys.b);
          cb[b].fixed = body.fixed_dofs();
          cb[b].prescribed = VecX::Zero(body.num_dofs());
          contacts[b] = floor_contacts(body, world.obstacles, world.gravity, h, cb[b].prescribed,
                                       cb[b].fixed);
          for (const Contact& c : contacts[b]) {
            const Index dof = 3 * c.node + c.axis;
            eliminate(cb[b].A, cb[b].b, dof, cb[b].prescribed[dof], body.lumped_mass()[c.node] / h);
          }
          cb[b].x = body.positions();
          cb[b].u = flat(body.velocity);
        }
      }
      // 2. the mesh around x* = X + dⁿ + h uⁿ (or xⁿ), 3. transfer, forces: v*
      pred = fluid.predict(build_predicted(), h, motion(), phases);
      // 4. [Chentanez06, Eq. (7)]
      sol = solve_coupled(make_input(pred, fluid.params(), cb, &m_targets), m_params.solve);
      solve_phases(sol.report);
      // 5. Eq. (5), collisions
      ScopedTimer timer(phases, "update");
      for (Index b = 0; b < nb; ++b) {
        solid::SolidBody& body = world.bodies[b];
        if (!cb[b].free) continue;
        solid::advance_trapezoidal(body, sol.u[b], h);
        // The nodes the solve put on a floor stop there (normal velocity 0) and lose
        // tangential speed by Coulomb friction. No per-node restitution: a node sent back up
        // while its neighbours still come down crushes the elements between them (measured:
        // a liquid-filled shell inverted elements within 3 steps of touching the floor at
        // e = 0.3); the body rebounds by its own elasticity.
        for (const Contact& c : contacts[b]) {
          const double mu = c.obstacle->friction;
          Vec3 u = body.velocity.row(c.node).transpose();
          // the normal speed the floor takes away this step: the approach, and what gravity
          // would have added (a resting node's weight, for Coulomb friction)
          const double dun = std::abs(c.sign * u[c.axis]) + std::max(0.0, -c.incoming) +
                             h * std::max(0.0, -c.sign * world.gravity[c.axis]);
          u[c.axis] = 0.0;
          const double tn = u.norm();
          if (tn > 0) u *= std::max(0.0, 1.0 - mu * dun / tn);
          body.velocity.row(c.node) = u.transpose();
        }
        rep.contacts += static_cast<Index>(contacts[b].size());
        rep.contacts += solid::resolve_collisions(body, world.obstacles);
        check_finite(body, h);
      }
    } else if (is_iterated(m_params.scheme)) {
      for (solid::SolidBody& body : world.bodies)
        if (body.is_kinematic()) body.set_kinematic_state(t1);
      pred = fluid.predict(build_predicted(), h, motion(), phases);
      sol = step_iterated(world, pred, fluid.params(), ifaces, h, phases, rep);
    } else {
      // 1. the bodies with the fluid's last nodal forces held
      if (!m_have_force) {
        const mesh::TetMesh& m0 = fluid.mesh();
        const VecX rho = fluid::cell_fluid_density(m0, fluid.params());
        VecX p_dyn = fluid.state().p;
        for (Index t = 0; t < m0.num_tets(); ++t)
          p_dyn[t] -=
              fluid::hydrostatic_pressure(rho[t], g_fluid, fluid.params().hydrostatic_origin,
                                          m0.circumcentres.row(t).transpose());
        m_held_force =
            fluid_forces(m0, ifaces, p_dyn, rho, g_fluid, fluid.params().hydrostatic_origin);
      }
      {
        ScopedTimer timer(phases, "solid");
        for (Index b = 0; b < nb; ++b) {
          solid::SolidBody& body = world.bodies[b];
          if (body.is_kinematic()) {
            body.set_kinematic_state(t1);
            continue;
          }
          VecX fe = body.external_forces(world.gravity) + m_held_force[b];
          for (Index l = 0; l < fe.size(); ++l)
            if (body.is_fixed(l)) fe[l] = 0.0;
          const solid::TrapezoidalSystem sys =
              solid::assemble_trapezoidal(body, h, fe, world.trapezoid);
          const std::unique_ptr<LinearSolver> s = factor_symmetric(sys.A);
          VecX u = flat(body.velocity);
          const SolveReport sr = s->solve(sys.b, u);
          rep.solid_iterations += sr.iterations;
          solid::advance_trapezoidal(body, u, h);
          rep.contacts += solid::resolve_collisions(body, world.obstacles);
          check_finite(body, h);
        }
      }
      // 2. the mesh around the bodies at tⁿ⁺¹, the fluid with their velocities held
      mesh::TetMesh m =
          build(positions([&](Index b) -> MatX3 { return world.bodies[b].displacement; }));
      pred = fluid.predict(std::move(m), h, motion(), phases);
      std::vector<CoupledBody> cb(nb);
      for (Index b = 0; b < nb; ++b) cb[b].interface = ifaces[b];  // all prescribed
      sol = solve_coupled(make_input(pred, fluid.params(), cb), m_params.solve);
      solve_phases(sol.report);
      m_held_force = sol.fluid_force;
      m_have_force = true;
    }
    rep.solve = sol.report;
    rep.fluid = fluid.commit(std::move(pred), std::move(sol.u_face), std::move(sol.p));
  } catch (...) {
    snap.restore(world);
    throw;
  }
  rep.fluid.converged = rep.solve.converged;
  rep.fluid.iterations = rep.solve.iterations;
  rep.fluid.residual = rep.solve.residual;
  rep.fluid.divergence_before = rep.solve.divergence_before;
  rep.fluid.divergence_after = rep.solve.divergence_after;
  world.time = t1;
  rep.solid_kinetic_energy = world.kinetic_energy();
  rep.elastic_energy = world.elastic_energy();
  return rep;
}


CoupledSolution CoupledStepper::step_iterated(solid::SolidWorld& world,
                                              fluid::FluidPrediction& pred,
                                              const fluid::FluidParams& params,
                                              const std::vector<BodyInterface>& ifaces, double h,
                                              PhaseTimes& phases, CoupledStepReport& rep) {
  const Index nb = static_cast<Index>(world.bodies.size());
  const mesh::TetMesh& m = pred.mesh;
  const char* scheme = to_string(m_params.scheme);
  // A region with no Open face bounded by a deformable body: the fluid-only projection of a
  // residual evaluation would have to remove the body's net flux (fluid::project), so the
  // iteration could not see the region's incompressibility.
  {
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
  // Stacked unknowns: uⁿ⁺¹ of every deformable body.
  std::vector<Index> off(nb + 1, 0);
  std::vector<std::unique_ptr<solid::TrapezoidalEquilibrium>> eq(nb);
  for (Index b = 0; b < nb; ++b) {
    solid::SolidBody& body = world.bodies[b];
    if (!body.is_kinematic())
      eq[b] = std::make_unique<solid::TrapezoidalEquilibrium>(body, h,
                                                              body.external_forces(world.gravity));
    off[b + 1] = off[b] + (eq[b] ? body.num_dofs() : 0);
  }
  const Index n = off[nb];
  auto part = [&](const VecX& x, Index b) { return x.segment(off[b], off[b + 1] - off[b]); };
  const std::vector<InterfaceFace> iface = interface_faces(m, ifaces);
  const std::vector<Index> noff = node_offsets(ifaces);
  std::vector<CoupledBody> held(nb);  // every body prescribed: the fluid-only solve
  for (Index b = 0; b < nb; ++b) held[b].interface = ifaces[b];

  // g(u) = the bodies' trapezoidal out-of-balance force + the fluid's forces of the
  // projection with the Solid faces at n·(H u)   [BatheSonnad80, Eq. (6)]
  VecX last_x;
  CoupledSolution last;
  AffineFluidCache cache;
  SolveCache amg_cache;  // every fluid-only solve of this step has the same P = C
  auto fluid_at = [&](const VecX& x) {
    CoupledSolution s;
    if (cache.combine(x, s)) return s;
    VecX ustar = pred.u_star;
    for (const InterfaceFace& i : iface) {
      const Index b = m.face_body[i.face];
      if (!eq[b]) continue;
      Vec3 v = Vec3::Zero();
      for (int k = 0; k < 3; ++k) v += i.weight[k] * x.segment<3>(off[b] + 3 * (i.node[k] - noff[b]));
      ustar[i.face] = m.face_normals.row(i.face).dot(v.transpose());
    }
    CoupledInput in = make_input(pred, params, held);
    in.u_star = &ustar;
    // The forces need not be more accurate than RTOL resolves: the fluid solve stops at
    // 1e-2 RTOL relative (at most 1e-8; the scene's coupling.rel_tol if that is looser).
    CoupledOptions o = m_params.solve;
    o.rel_tol = std::max(o.rel_tol, std::min(1e-8, 1e-2 * world.equilibrium.rtol));
    o.reuse = &amg_cache;
    s = solve_coupled(in, o);
    phases.add("coupled_assembly", s.report.assembly_s);
    phases.add("coupled_solve", s.report.setup_s + s.report.solve_s);
    ++rep.fluid_solves;
    TETFSI_REQUIRE(SolverError, s.report.converged,
                   "coupling.scheme {}: a fluid solve did not converge ({} iterations, residual "
                   "{:.3g}); raise coupling.max_iterations or reduce time.dt",
                   scheme, s.report.iterations, s.report.residual);
    cache.add(x, s);
    return s;
  };
  EquilibriumProblem problem;
  problem.residual = [&](const VecX& x) {
    CoupledSolution s = fluid_at(x);
    ScopedTimer timer(phases, "solid");
    VecX g(n);
    for (Index b = 0; b < nb; ++b) {
      if (!eq[b]) continue;
      VecX gb = eq[b]->residual(part(x, b)) + s.fluid_force[b];
      for (Index l = 0; l < gb.size(); ++l)
        if (world.bodies[b].is_fixed(l)) gb[l] = 0.0;
      g.segment(off[b], gb.size()) = gb;
    }
    last_x = x;
    last = std::move(s);
    return g;
  };
  if (m_params.scheme == Scheme::Newton) {
    // The increment with the fluid in the matrix: the coupled system on homogeneous fluid data
    // (v* = 0, no open pressure, no gravity), A the bodies' tangents, b the residual.
    problem.factor = [&](const VecX& x) -> InverseOperator {
      auto bodies = std::make_shared<std::vector<CoupledBody>>(nb);
      {
        ScopedTimer timer(phases, "solid");
        for (Index b = 0; b < nb; ++b) {
          CoupledBody& cb = (*bodies)[b];
          cb.interface = ifaces[b];
          if (!eq[b]) continue;
          const solid::SolidBody& body = world.bodies[b];
          cb.free = true;
          cb.A = eq[b]->tangent(part(x, b));
          cb.fixed = body.fixed_dofs();
          cb.x = body.positions();
          cb.u = flat(body.velocity);
        }
      }
      return [&, bodies](const VecX& r) -> VecX {
        for (Index b = 0; b < nb; ++b)
          if (eq[b]) (*bodies)[b].b = part(r, b);
        const VecX zero_f = VecX::Zero(m.num_faces());
        CoupledInput in = make_input(pred, params, *bodies);
        in.u_star = &zero_f;
        in.p_open = &zero_f;
        in.gravity = Vec3::Zero();
        CoupledOptions o = m_params.solve;
        o.conserve_volume = false;
        // An increment only has to be a good direction: at 1e-10 the CG stalled just above
        // the tolerance on the small right-hand sides of late iterations (measured 1-4e-10).
        o.rel_tol = std::max(o.rel_tol, 1e-8);
        const CoupledSolution s = solve_coupled(in, o);
        phases.add("coupled_assembly", s.report.assembly_s);
        phases.add("coupled_solve", s.report.setup_s + s.report.solve_s);
        ++rep.fluid_solves;
        VecX dx(n);
        for (Index b = 0; b < nb; ++b)
          if (eq[b]) dx.segment(off[b], off[b + 1] - off[b]) = s.u[b];
        return dx;
      };
    };
  } else {
    // [BatheSonnad80, Eq. (15)]: the bodies' own (h/4) K̂, block diagonal, no fluid.
    problem.factor = [&](const VecX& x) -> InverseOperator {
      ScopedTimer timer(phases, "solid");
      std::vector<InverseOperator> inv(nb);
      for (Index b = 0; b < nb; ++b)
        if (eq[b]) inv[b] = solid::factor_inverse(eq[b]->tangent(part(x, b)));
      return [inv, off, nb](const VecX& r) -> VecX {
        VecX dx = VecX::Zero(r.size());
        for (Index b = 0; b < nb; ++b)
          if (inv[b]) dx.segment(off[b], off[b + 1] - off[b]) =
                          inv[b](r.segment(off[b], off[b + 1] - off[b]));
        return dx;
      };
    };
  }
  EquilibriumOptions opt = world.equilibrium;
  opt.method = m_params.scheme == Scheme::Newton           ? IterationMethod::Newton
               : m_params.scheme == Scheme::ModifiedNewton ? IterationMethod::ModifiedNewton
                                                           : IterationMethod::Bfgs;
  VecX x(n);
  for (Index b = 0; b < nb; ++b)
    if (eq[b]) x.segment(off[b], off[b + 1] - off[b]) = eq[b]->start();
  rep.equilibrium = solve_equilibrium(problem, x, opt, m_history);
  TETFSI_REQUIRE(SolverError, rep.equilibrium.converged,
                 "coupling.scheme {}: the iteration {} at t = {:.6g} s (h = {:.3g} s); raise "
                 "solid.max_iterations, reduce time.dt, or use coupling.scheme bfgs, newton or "
                 "simultaneous",
                 scheme, rep.equilibrium.failure, world.time, h);
  logger().debug(
      "coupling.scheme {}: {} iterations, {} residual evaluations, {} fluid solves, {} "
      "factorizations, {} updates ({} skipped), {} line searches; force ratio {:.3g}, energy "
      "ratio {:.3g}",
      scheme, rep.equilibrium.iterations, rep.equilibrium.evaluations, rep.fluid_solves,
      rep.equilibrium.factorizations, rep.equilibrium.updates, rep.equilibrium.skipped_updates,
      rep.equilibrium.line_searches, rep.equilibrium.force_ratio, rep.equilibrium.energy_ratio);
  if (!(last_x.size() == x.size() && last_x == x)) problem.residual(x);
  // Eq. (3): dⁿ⁺¹ = dⁿ + h/2 (uⁿ + uⁿ⁺¹); collisions
  ScopedTimer timer(phases, "update");
  for (Index b = 0; b < nb; ++b) {
    if (!eq[b]) continue;
    solid::SolidBody& body = world.bodies[b];
    const VecX ub = part(x, b);
    solid::advance_trapezoidal(body, ub, h);
    last.u[b] = ub;
    rep.contacts += solid::resolve_collisions(body, world.obstacles);
    check_finite(body, h);
  }
  return last;
}

}  // namespace tetfsi::coupling
