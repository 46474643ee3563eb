/// @file scheme_iterated.cpp
/// The iterated schemes bfgs, modified_newton and newton [BatheSonnad80] (scheme.hpp): the
/// fully nonlinear trapezoidal rule of every deformable body (solid/nonlinear_trapezoid.hpp)
/// with the fluid's nodal forces in its out-of-balance force, iterated to equilibrium
/// (core/equilibrium.hpp, tolerances from SolidWorld::equilibrium). The mesh is built around
/// x* as for simultaneous; each residual evaluation projects the fluid on it with the bodies'
/// Solid faces moving at the iterate's velocities (a fluid-only solve) and returns the
/// pressure forces. bfgs and modified_newton start from the seed's Eq. (15): the bodies' own
/// (h/4) K̂ = M/h + C/2 + (h/4) K', no fluid in it — the fluid's added mass is learnt by the
/// BFGS updates (modified Newton never learns it: with more added mass than body mass it
/// cannot converge); solid.starting_matrix adds it, lumped per node or whole (newton's
/// increment system formed at the step's first iterate and kept). newton re-forms the bodies'
/// tangent every iteration and solves for the increment with the fluid in the matrix (the coupled
/// system on the increment), so it is the simultaneous scheme iterated on the solid's nonlinearity.
/// The fluid-only solution is affine in the face velocities: a point in the affine span of solved
/// points (every line-search trial) is combined from them instead of solved, so BFGS costs one
/// fluid solve per iteration. Fluid regions sealed by a deformable body (no Open face) are
/// rejected: a fluid-only projection cannot give them a volume.
#include <algorithm>
#include <memory>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include "core/error.hpp"
#include "core/log.hpp"
#include "coupling/scheme.hpp"
#include "solid/integrator.hpp"
#include "solid/nonlinear_trapezoid.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::coupling {

namespace {

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

/// One iterated step: the unknowns x = uⁿ⁺¹ of every deformable body, stacked.
class IteratedStep {
 public:
  IteratedStep(StepContext& ctx, const PredictedFluid& pred, const CouplingParams& params,
               CoupledStepReport& rep)
      : m_ctx(ctx), m_pred(pred), m_params(params), m_rep(rep) {
    const solid::SolidWorld& world = ctx.world;
    m_nb = static_cast<Index>(world.bodies.size());
    m_off.assign(m_nb + 1, 0);
    m_eq.resize(m_nb);
    for (Index b = 0; b < m_nb; ++b) {
      const solid::SolidBody& body = world.bodies[b];
      if (!body.is_kinematic())
        m_eq[b] = std::make_unique<solid::TrapezoidalEquilibrium>(
            body, ctx.h, body.external_forces(world.gravity));
      m_off[b + 1] = m_off[b] + (m_eq[b] ? body.num_dofs() : 0);
    }
    m_held.resize(m_nb);  // every body prescribed: the fluid-only solve
  }

  /// Iterate to equilibrium from the seed's U⁽⁰⁾; returns the converged velocities.
  VecX solve(EquilibriumHistory& history) {
    EquilibriumProblem problem;
    problem.residual = [this](const VecX& x) { return residual(x); };
    EquilibriumOptions opt = m_ctx.world.equilibrium;
    if (m_params.scheme == Scheme::Newton) {
      problem.factor = [this](const VecX& x) { return newton_inverse(x, nullptr); };
    } else if (opt.starting_matrix == StartingMatrix::Coupled) {
      TETFSI_REQUIRE(InputError, !opt.keep_matrix,
                     "solid.starting_matrix 'coupled' is formed on each step's fluid mesh: set "
                     "solid.reform to 'step'");
      // the matrix is fixed until BFGS re-forms it: its solves share one AMG set-up
      problem.factor = [this](const VecX& x) {
        m_coupled_amg = SolveCache{};
        return newton_inverse(x, &m_coupled_amg);
      };
    } else {
      problem.factor = [this](const VecX& x) { return body_inverse(x); };
    }
    opt.method = m_params.scheme == Scheme::Newton           ? IterationMethod::Newton
                 : m_params.scheme == Scheme::ModifiedNewton ? IterationMethod::ModifiedNewton
                                                             : IterationMethod::Bfgs;
    VecX x(m_off[m_nb]);
    for (Index b = 0; b < m_nb; ++b)
      if (m_eq[b]) x.segment(m_off[b], m_off[b + 1] - m_off[b]) = m_eq[b]->start();
    m_rep.equilibrium = solve_equilibrium(problem, x, opt, history);
    const char* scheme = to_string(m_params.scheme);
    TETFSI_REQUIRE(SolverError, m_rep.equilibrium.converged,
                   "coupling.scheme {}: the iteration {} at t = {:.6g} s (h = {:.3g} s); raise "
                   "solid.max_iterations, reduce time.dt, or use coupling.scheme bfgs, newton or "
                   "simultaneous",
                   scheme, m_rep.equilibrium.failure, m_ctx.world.time, m_ctx.h);
    const EquilibriumReport& e = m_rep.equilibrium;
    logger().debug(
        "coupling.scheme {}: {} iterations, {} residual evaluations, {} fluid solves, {} "
        "factorizations, {} updates ({} skipped), {} line searches; force ratio {:.3g}, energy "
        "ratio {:.3g}",
        scheme, e.iterations, e.evaluations, m_rep.fluid_solves, e.factorizations, e.updates,
        e.skipped_updates, e.line_searches, e.force_ratio, e.energy_ratio);
    if (!is_last(x)) residual(x);
    return x;
  }

  /// Eq. (3): dⁿ⁺¹ = dⁿ + h/2 (uⁿ + uⁿ⁺¹), collisions; the fluid solution at x.
  CoupledSolution finish(const VecX& x) {
    ScopedTimer timer(m_ctx.phases, "update");
    solid::SolidWorld& world = m_ctx.world;
    for (Index b = 0; b < m_nb; ++b) {
      if (!m_eq[b]) continue;
      solid::SolidBody& body = world.bodies[b];
      const VecX ub = part(x, b);
      solid::advance_trapezoidal(body, ub, m_ctx.h);
      m_last.u[b] = ub;
      m_rep.contacts += solid::resolve_collisions(body, world.obstacles);
      check_finite(body, m_ctx.h);
    }
    return std::move(m_last);
  }

 private:
  VecX part(const VecX& x, Index b) const { return x.segment(m_off[b], m_off[b + 1] - m_off[b]); }

  /// x split per body (empty for kinematic bodies).
  std::vector<VecX> per_body(const VecX& x) const {
    std::vector<VecX> u(m_nb);
    for (Index b = 0; b < m_nb; ++b)
      if (m_eq[b]) u[b] = part(x, b);
    return u;
  }

  void add_phases(const CoupledSolution& s) {
    add_solve_phases(m_ctx.phases, s.report);
    ++m_rep.fluid_solves;
  }

  /// The fluid-only solve with the Solid faces of deformable bodies at n·(H x).
  CoupledSolution fluid_at(const VecX& x) {
    CoupledSolution s;
    if (m_cache.combine(x, s)) return s;
    VecX ustar = m_pred.u_star();
    m_pred.apply_H(per_body(x), ustar);
    SolveVariant variant;
    variant.u_star = &ustar;
    // The forces need not be more accurate than RTOL resolves: the fluid solve stops at
    // 1e-2 RTOL relative (at most 1e-8; the scene's coupling.rel_tol if that is looser).
    CoupledOptions o = m_params.solve;
    o.rel_tol = std::max(o.rel_tol, std::min(1e-8, 1e-2 * m_ctx.world.equilibrium.rtol));
    o.reuse = &m_amg;  // every fluid-only solve of this step has the same P = C
    s = m_pred.solve(m_held, o, variant);
    add_phases(s);
    TETFSI_REQUIRE(SolverError, s.report.converged,
                   "coupling.scheme {}: a fluid solve did not converge ({} iterations, residual "
                   "{:.3g}); raise coupling.max_iterations or reduce time.dt",
                   to_string(m_params.scheme), s.report.iterations, s.report.residual);
    m_cache.add(x, s);
    return s;
  }

  /// g(u) = the bodies' trapezoidal out-of-balance force + the fluid's forces of the
  /// projection with the Solid faces at n·(H u)   [BatheSonnad80, Eq. (6)]
  /// x is the point of the last residual evaluation (m_last holds its fluid solution).
  bool is_last(const VecX& x) const { return m_last_x.size() == x.size() && m_last_x == x; }

  VecX residual(const VecX& x) {
    CoupledSolution s = fluid_at(x);
    ScopedTimer timer(m_ctx.phases, "solid");
    VecX g(m_off[m_nb]);
    for (Index b = 0; b < m_nb; ++b) {
      if (!m_eq[b]) continue;
      VecX gb = m_eq[b]->residual(part(x, b)) + s.fluid_force[b];
      for (Index l = 0; l < gb.size(); ++l)
        if (m_ctx.world.bodies[b].is_fixed(l)) gb[l] = 0.0;
      g.segment(m_off[b], gb.size()) = gb;
    }
    m_last_x = x;
    m_last = std::move(s);
    return g;
  }

  /// newton: the increment with the fluid in the matrix — the coupled system on homogeneous
  /// fluid data (v* = 0, no open pressure, no gravity), A the bodies' tangents, b the residual.
  /// Also solid.starting_matrix "coupled" (bfgs, modified_newton), the matrix formed at the
  /// step's first iterate and kept; its solves then share the AMG set-up in `reuse`.
  InverseOperator newton_inverse(const VecX& x, SolveCache* reuse) {
    auto bodies = std::make_shared<std::vector<CoupledBody>>(m_nb);
    {
      ScopedTimer timer(m_ctx.phases, "solid");
      for (Index b = 0; b < m_nb; ++b) {
        if (!m_eq[b]) continue;
        CoupledBody& cb = (*bodies)[b];
        const solid::SolidBody& body = m_ctx.world.bodies[b];
        cb.free = true;
        cb.A = m_eq[b]->tangent(part(x, b));
        cb.fixed = body.fixed_dofs();
        cb.x = body.positions();
        cb.u = flat(body.velocity);
      }
    }
    return [this, bodies, reuse](const VecX& r) -> VecX {
      for (Index b = 0; b < m_nb; ++b)
        if (m_eq[b]) (*bodies)[b].b = part(r, b);
      SolveVariant variant;
      variant.homogeneous = true;
      CoupledOptions o = m_params.solve;
      o.conserve_volume = false;
      // An increment only has to be a good direction: at 1e-10 the CG stalled just above
      // the tolerance on the small right-hand sides of late iterations (measured 1-4e-10).
      o.rel_tol = std::max(o.rel_tol, 1e-8);
      o.reuse = reuse;
      const CoupledSolution s = m_pred.solve(*bodies, o, variant);
      add_phases(s);
      VecX dx(m_off[m_nb]);
      for (Index b = 0; b < m_nb; ++b)
        if (m_eq[b]) dx.segment(m_off[b], m_off[b + 1] - m_off[b]) = s.u[b];
      return dx;
    };
  }

  /// The fluid's added mass lumped on each deformable body's nodes (3n × 3n, kg, one 3×3
  /// block per free node): the fluid-only solve's nodal forces F respond to the bodies' face
  /// velocities as −M_a/h (M_a = h J C⁻¹ Jᵀ, the Schur complement's fluid part, plus the half
  /// cells). Three more solves per body give M_a t_k for the body's unit translations t_k;
  /// node a's block is [M_a t_1, M_a t_2, M_a t_3]_a (row-sum lumping: exact on uniform
  /// translations, so the blocks sum to the body's translational added mass), symmetrised and
  /// clipped to be positive semi-definite.
  std::vector<SparseMatrix> lumped_added_mass(const VecX& x) {
    const CoupledSolution s0 = is_last(x) ? m_last : fluid_at(x);
    std::vector<SparseMatrix> out(m_nb);
    for (Index b = 0; b < m_nb; ++b) {
      if (!m_eq[b]) continue;
      const solid::SolidBody& body = m_ctx.world.bodies[b];
      const Index n = body.num_nodes();
      Eigen::MatrixXd Mt(3 * n, 3);  // M_a t_k
      for (int k = 0; k < 3; ++k) {
        VecX xk = x;
        for (Index a = 0; a < n; ++a) xk[m_off[b] + 3 * a + k] += 1.0;
        const CoupledSolution sk = fluid_at(xk);
        Mt.col(k) = -m_ctx.h * (sk.fluid_force[b] - s0.fluid_force[b]);
      }
      Triplets tr;
      for (Index a = 0; a < n; ++a) {
        const Eigen::Matrix3d B = Mt.middleRows<3>(3 * a);
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (B + B.transpose()));
        const Eigen::Matrix3d P = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                  es.eigenvectors().transpose();
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            if (!body.is_fixed(3 * a + r) && !body.is_fixed(3 * a + c) && P(r, c) != 0.0)
              tr.emplace_back(3 * a + r, 3 * a + c, P(r, c));
      }
      out[b] = SparseMatrix(3 * n, 3 * n);
      out[b].setFromTriplets(tr.begin(), tr.end());
    }
    return out;
  }

  /// bfgs, modified_newton: [BatheSonnad80, Eq. (15)], the bodies' own (h/4) K̂, block
  /// diagonal, no fluid (solid.starting_matrix "added_mass": plus lumped_added_mass / h).
  FactoredMatrix body_inverse(const VecX& x) {
    ScopedTimer timer(m_ctx.phases, "solid");
    // the bodies' own tangents, no fluid: [BatheSonnad80, Eq. (15)]; with
    // solid.starting_matrix "added_mass" plus the fluid's lumped added mass / h
    std::vector<SparseMatrix> added;
    if (m_ctx.world.equilibrium.starting_matrix == StartingMatrix::AddedMass)
      added = lumped_added_mass(x);
    std::vector<std::shared_ptr<const SparseMatrix>> blocks(m_nb);
    for (Index b = 0; b < m_nb; ++b) {
      if (!m_eq[b]) continue;
      SparseMatrix K = m_eq[b]->tangent(part(x, b));
      if (!added.empty()) K += added[b] / m_ctx.h;
      blocks[b] = std::make_shared<const SparseMatrix>(std::move(K));
    }
    return factor_blocks(std::move(blocks), m_off);
  }

  StepContext& m_ctx;
  const PredictedFluid& m_pred;
  const CouplingParams& m_params;
  CoupledStepReport& m_rep;
  Index m_nb = 0;
  std::vector<Index> m_off;  ///< first unknown of each body
  std::vector<std::unique_ptr<solid::TrapezoidalEquilibrium>> m_eq;
  std::vector<CoupledBody> m_held;
  VecX m_last_x;
  CoupledSolution m_last;
  AffineFluidCache m_cache;
  SolveCache m_amg;
  SolveCache m_coupled_amg;  ///< solid.starting_matrix "coupled": the kept matrix's AMG
};

class IteratedScheme final : public CouplingScheme {
 public:
  explicit IteratedScheme(CouplingParams p) : m_params(std::move(p)) {}
  Scheme kind() const override { return m_params.scheme; }

  CoupledSolution advance(StepContext& ctx, std::unique_ptr<PredictedFluid>& pred,
                          CoupledStepReport& rep) override {
    for (solid::SolidBody& body : ctx.world.bodies)
      if (body.is_kinematic()) body.set_kinematic_state(ctx.world.time + ctx.h);
    pred = predict_around_predicted(ctx, rep);
    pred->refuse_sealed_regions(ctx.world, to_string(m_params.scheme));
    IteratedStep step(ctx, *pred, m_params, rep);
    const VecX x = step.solve(m_history);
    return step.finish(x);
  }

  void save_state(CheckpointWriter& w, const std::string& prefix) const override {
    save_history(m_history, w, prefix + "history/");
  }
  void load_state(const CheckpointReader& r, const std::string& prefix) override {
    m_history = load_history(r, prefix + "history/");
  }

 private:
  CouplingParams m_params;
  EquilibriumHistory m_history;  ///< Eq. (12)'s largest force, the kept matrix
};

}  // namespace

std::unique_ptr<CouplingScheme> make_iterated_scheme(const CouplingParams& params) {
  TETFSI_CHECK(is_iterated(params.scheme), "make_iterated_scheme: {} is not iterated",
               to_string(params.scheme));
  return std::make_unique<IteratedScheme>(params);
}

}  // namespace tetfsi::coupling
