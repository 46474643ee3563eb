/// @file coupled_solvers.cpp
/// The solvers of the assembled coupled system (coupled_system.hpp): the paper's form and the
/// symmetric form with a general sparse solver, and CG on the Schur complement with AMG.
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"

namespace tetfsi::coupling {

namespace {

void merge(const SolveReport& s, CoupledReport& rep) {
  rep.iterations += s.iterations;
  rep.residual = std::max(rep.residual, s.residual);
  rep.converged = rep.converged && s.converged;
  rep.solve_s += s.solve_s;
  rep.floor = std::max(rep.floor, s.floor);
  if (s.converged && s.floor > 0) ++rep.solves_at_floor;
  if (!s.converged && s.stagnated) rep.stagnated = true;
}

/// K = [A −J; −Jᵀ·s −C·s] with s the row scale of the second block (1/V_g: the paper's
/// form [Chentanez06, Eq. (7)]; 1: the symmetric form).
SparseMatrix assemble_K(const CoupledSystem& sys, const VecX& rowscale) {
  const Index ns = sys.ns, ng = sys.ng;
  const std::vector<CoupledBody>& bodies = *sys.bodies;
  Triplets kt;
  for (Index b = 0; b < sys.nb; ++b) {
    if (!bodies[b].free) continue;
    const SparseMatrix& A = sys.body_A(b);
    for (Index c = 0; c < A.outerSize(); ++c)
      for (SparseMatrix::InnerIterator it(A, c); it; ++it)
        kt.emplace_back(sys.dof0[b] + it.row(), sys.dof0[b] + it.col(), it.value());
  }
  for (Index c = 0; c < sys.Ac.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(sys.Ac, c); it; ++it)
      kt.emplace_back(it.row(), it.col(), it.value());
  for (Index c = 0; c < sys.J.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(sys.J, c); it; ++it) {
      kt.emplace_back(it.row(), ns + it.col(), -it.value());
      if (sys.symmetric) kt.emplace_back(ns + it.col(), it.row(), -it.value() * rowscale[it.col()]);
    }
  if (!sys.symmetric)
    for (Index c = 0; c < sys.Jt.outerSize(); ++c)
      for (SparseMatrix::InnerIterator it(sys.Jt, c); it; ++it)
        kt.emplace_back(ns + it.row(), it.col(), -it.value() * rowscale[it.row()]);
  for (Index c = 0; c < sys.C.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(sys.C, c); it; ++it)
      kt.emplace_back(ns + it.row(), ns + it.col(), -it.value() * rowscale[it.row()]);
  SparseMatrix K(ns + ng, ns + ng);
  K.setFromTriplets(kt.begin(), kt.end());
  return K;
}

/// The free bodies' blocks stacked, with the contact between them.
SparseMatrix stacked_A(const CoupledSystem& sys) {
  std::vector<SparseMatrix> blocks(sys.nb);
  for (Index b = 0; b < sys.nb; ++b)
    if ((*sys.bodies)[b].free) blocks[b] = sys.body_A(b);
  return solid::stack_blocks(blocks, sys.dof0) + sys.Ac;
}

/// Each free body's A factorized once: x = A⁻¹ rhs (block diagonal); with contact between
/// the bodies (sys.Ac), their stacked matrix factorized as one.
class BodySolve {
 public:
  explicit BodySolve(const CoupledSystem& sys) : m_sys(sys), m_fac(sys.nb) {
    const std::vector<CoupledBody>& bodies = *sys.bodies;
    if (sys.Ac.nonZeros() > 0) {
      m_stacked = stacked_A(sys);  // kept: the factorisation refers to it
      m_all = factor_symmetric(m_stacked);
      return;
    }
    for (Index b = 0; b < sys.nb; ++b)
      if (bodies[b].free) m_fac[b] = factor_symmetric(sys.body_A(b));
  }
  void operator()(const VecX& rhs, VecX& x) const {
    x.resize(m_sys.ns);
    if (m_all) {
      x.setZero();
      m_all->solve(rhs, x);
      return;
    }
    for (Index b = 0; b < m_sys.nb; ++b) {
      if (!m_fac[b]) continue;
      const Index n = m_sys.dof0[b + 1] - m_sys.dof0[b];
      VecX xb = VecX::Zero(n);
      m_fac[b]->solve(rhs.segment(m_sys.dof0[b], n), xb);
      x.segment(m_sys.dof0[b], n) = xb;
    }
  }

 private:
  const CoupledSystem& m_sys;
  std::vector<std::unique_ptr<LinearSolver>> m_fac;
  SparseMatrix m_stacked;
  std::unique_ptr<LinearSolver> m_all;
};

/// The AMG V-cycle on P = C + Jᵀ diag(A)⁻¹ J, or the cache's (the caller vouches that P is
/// the same). diag(A)⁻¹ in P: measured 37 CG iterations per step on a water-filled shell,
/// 55 with h M⁻¹ (the rigid-body response) instead.
AmgPreconditioner* amg_for(const CoupledSystem& sys, const CoupledOptions& opt,
                           std::unique_ptr<AmgPreconditioner>& own) {
  const std::vector<CoupledBody>& bodies = *sys.bodies;
  if (opt.reuse && opt.reuse->amg && opt.reuse->size == sys.ng) {
    ++opt.reuse->reused;
    return opt.reuse->amg.get();
  }
  // diag(A)⁻¹ per body, or of the stacked block when contact couples the bodies
  VecX dinv;
  if (sys.Ac.nonZeros() > 0) {
    dinv = stacked_A(sys).diagonal().cwiseInverse();
  } else {
    dinv = VecX::Zero(sys.ns);
    for (Index b = 0; b < sys.nb; ++b)
      if (bodies[b].free)
        dinv.segment(sys.dof0[b], sys.dof0[b + 1] - sys.dof0[b]) =
            sys.body_A(b).diagonal().cwiseInverse();
  }
  // (the grid's paper form: P from the second row's operator on both sides, symmetric)
  const SparseMatrix Pm =
      sys.symmetric ? SparseMatrix(sys.C + SparseMatrix(sys.Jt * dinv.asDiagonal() * sys.J))
                    : SparseMatrix(sys.C + SparseMatrix(sys.Jt * dinv.asDiagonal() *
                                                        SparseMatrix(sys.Jt.transpose())));
  own = sys.grid.dims[0] > 0 && opt.grid_multigrid ? make_pfmg_preconditioner(sys.grid)
                                                   : make_amg_preconditioner();
  own->setup(Pm);
  AmgPreconditioner* amg = own.get();
  if (opt.reuse) {
    opt.reuse->amg = std::move(own);
    opt.reuse->size = sys.ng;
  }
  return amg;
}

/// S = C + Jᵀ A⁻¹ J applied as a product, with the balancing coarse space of the region
/// constants only the bodies' elasticity holds (no Open face). S is nearly singular there (a
/// stiff body barely lifts it), which stalls a plain preconditioned CG; the balancing
/// preconditioner
///   B = (I − Z E⁻¹ (SZ)ᵀ) M (I − SZ E⁻¹ Zᵀ) + Z E⁻¹ Zᵀ,  E = Zᵀ S Z, M the AMG V-cycle,
/// solves that space exactly and stays SPD. Iterates are kept as x = Z a + y: the region
/// constants a can exceed y by many orders (1/λ_min), and S Z = Jᵀ A⁻¹ J Z exactly (C Z = 0
/// in theory, rounding noise times a in practice).
struct SchurOperator {
  const CoupledSystem& sys;
  const BodySolve& solve_A;
  AmgPreconditioner* amg = nullptr;
  Index nz = 0;
  Eigen::MatrixXd Z, SZ, JZ;
  Eigen::LDLT<Eigen::MatrixXd> Einv;
  Eigen::PartialPivLU<Eigen::MatrixXd> Elu;  ///< E of the non-symmetric S (the grid's paper J)
  mutable VecX tmp_u, tmp_f;

  SchurOperator(const CoupledSystem& s, const BodySolve& a, AmgPreconditioner* m)
      : sys(s), solve_A(a), amg(m) {
    std::vector<Index> zreg;
    for (Index k = 0; k < sys.nr; ++k)
      if (sys.lifted[k] && !sys.regions.has_open[k]) zreg.push_back(k);
    nz = static_cast<Index>(zreg.size());
    Z = Eigen::MatrixXd::Zero(sys.ng, nz);
    SZ.resize(sys.ng, nz);
    JZ.resize(sys.ns, nz);
    for (Index j = 0; j < nz; ++j)
      for (Index g = 0; g < sys.ng; ++g)
        if (sys.greg[g] == zreg[j]) Z(g, j) = 1.0;
    for (Index j = 0; j < nz; ++j) {
      JZ.col(j) = sys.J * Z.col(j);
      VecX au;
      solve_A(JZ.col(j), au);
      SZ.col(j) = sys.Jt * au;
    }
    const Eigen::MatrixXd E = Z.transpose() * SZ;
    if (sys.symmetric)
      Einv.compute(E);
    else
      Elu.compute(E);
  }
  void S(const VecX& x, VecX& y) const {
    y = sys.C * x;
    if (sys.ns > 0) {
      tmp_f = sys.J * x;
      solve_A(tmp_f, tmp_u);
      y += sys.Jt * tmp_u;
    }
  }
  void S2(const VecX& a, const VecX& y, VecX& out) const {  // S (Z a + y)
    S(y, out);
    if (nz) out += SZ * a;
  }
  void precondition(const VecX& r, VecX& za, VecX& zy) const {  // z = Z za + zy = B r
    if (nz == 0) {
      amg->apply(r, zy);
      za = VecX();
      return;
    }
    const VecX r1 = r - SZ * Einv.solve(Z.transpose() * r);
    amg->apply(r1, zy);
    za = Einv.solve(Z.transpose() * r - SZ.transpose() * zy);
  }
  /// The non-symmetric S: z = Z za + zy = Q r + M (r − S Q r), Q = Z E⁻¹ Zᵀ (deflation of
  /// the region constants, a fixed linear preconditioner, as right preconditioning needs).
  void precondition_nonsymmetric(const VecX& r, VecX& za, VecX& zy) const {
    if (nz == 0) {
      amg->apply(r, zy);
      za = VecX();
      return;
    }
    za = Elu.solve(Z.transpose() * r);
    amg->apply(r - SZ * za, zy);
  }
  double dot_z(const VecX& v, const VecX& a, const VecX& y) const {
    return v.dot(y) + (nz ? (Z.transpose() * v).dot(a) : 0.0);
  }
  /// The round-off noise of evaluating S at x = Z a + y, given Sx = S2(a, y): split x into
  /// x₁ = 0.3 x and x₂ = x − x₁, equal in exact arithmetic to x₁ + x₂ = x, so that
  /// ‖S x₁ + S x₂ − S x‖ measures what the products (C, J, Jᵀ, the bodies' A⁻¹ solves, S Z a)
  /// add to any computed residual: the floor no iteration can go below.
  double noise(const VecX& a, const VecX& y, const VecX& Sx) const {
    const VecX a1 = 0.3 * a, y1 = 0.3 * y;
    VecX s1, s2;
    S2(a1, y1, s1);
    S2(a - a1, y - y1, s2);
    return (s1 + s2 - Sx).norm();
  }
};

/// The rule the Schur iterations stop by: converged if the true relative residual reached
/// rel_tol, or, when the iteration stagnated above it, if it lies within k_floor_factor of
/// the round-off floor measured for this system (SchurOperator::noise): a tolerance below
/// what round-off allows is then met as well as it can be, not "not converged".
constexpr double k_floor_factor = 10.0;

void judge_convergence(const SchurOperator& op, const CoupledOptions& opt, const VecX& a,
                       const VecX& y, const VecX& Sx, double bn, SolveReport& sr) {
  sr.converged = sr.residual <= opt.rel_tol;
  if (sr.converged) return;
  sr.floor = op.noise(a, y, Sx) / bn;
  if (sr.stagnated && sr.residual <= k_floor_factor * sr.floor) sr.converged = true;
  logger().debug(
      "coupled solve: stopped at residual {:.3g} after {} iterations ({}), round-off "
      "floor {:.3g}",
      sr.residual, sr.iterations, sr.stagnated ? "stagnated" : "iteration limit", sr.floor);
}

/// Preconditioned CG on S x = rhs, x = Z xa + xy, stopped on the true residual (up to 4
/// restarts). Sets `breakdown` if dᵀ S d ≤ 0 (S not positive definite along d).
SolveReport schur_pcg(const SchurOperator& op, const CoupledOptions& opt, const VecX& rhs, VecX& xa,
                      VecX& xy, bool& breakdown) {
  const Index nz = op.nz;
  SolveReport sr{"schur_amg", false, 0, 0.0, 0.0, 0.0};
  const double t1 = now_seconds();
  const double bn = rhs.norm();
  xy = VecX::Zero(op.sys.ng);
  xa = nz ? VecX(op.Einv.solve(op.Z.transpose() * rhs)) : VecX();
  if (bn == 0.0) {
    if (nz) xa.setZero();
    sr.converged = true;
    return sr;
  }
  VecX r, q, za, zy, da, dy;
  op.S2(xa, xy, q);
  r = rhs - q;
  double last_true = std::numeric_limits<double>::infinity();
  for (int restart = 0; restart < 4; ++restart) {
    op.precondition(r, za, zy);
    da = za;
    dy = zy;
    double rz = op.dot_z(r, za, zy);
    while (sr.iterations < opt.max_iterations && r.norm() > opt.rel_tol * bn) {
      op.S2(da, dy, q);
      const double dq = op.dot_z(q, da, dy);
      if (!(dq > 0)) {
        breakdown = true;
        logger().debug("coupled solve: CG breakdown after {} iterations (d^T S d = {:.3g})",
                       sr.iterations, dq);
        break;
      }
      const double alpha = rz / dq;
      xy += alpha * dy;
      if (nz) xa += alpha * da;
      r -= alpha * q;
      ++sr.iterations;
      op.precondition(r, za, zy);
      const double rz1 = op.dot_z(r, za, zy);
      dy = zy + (rz1 / rz) * dy;
      if (nz) da = za + (rz1 / rz) * da;
      rz = rz1;
    }
    op.S2(xa, xy, q);
    r = rhs - q;  // the true residual
    sr.residual = r.norm() / bn;
    if (sr.residual <= opt.rel_tol || sr.iterations >= opt.max_iterations || breakdown) break;
    // A restart that does not halve the true residual: round-off, not the iteration, bounds it.
    sr.stagnated = sr.residual > 0.5 * last_true;
    if (sr.stagnated) break;
    last_true = sr.residual;
  }
  judge_convergence(op, opt, xa, xy, q, bn, sr);
  sr.solve_s = now_seconds() - t1;
  return sr;
}

/// Right-preconditioned BiCGSTAB on S x = rhs for the non-symmetric S = C + Jt A⁻¹ J of the
/// grid's paper form, preconditioned by the AMG V-cycle with the region constants deflated
/// (SchurOperator::precondition_nonsymmetric), stopped on the true residual. The iterates are
/// kept as x = Z a + y, as in schur_pcg.
SolveReport schur_bicgstab(const SchurOperator& op, const CoupledOptions& opt, const VecX& rhs,
                           VecX& x) {
  SolveReport sr{"schur_amg (bicgstab)", false, 0, 0.0, 0.0, 0.0};
  const double t1 = now_seconds();
  const double bn = rhs.norm();
  x = VecX::Zero(op.sys.ng);
  if (bn == 0.0) {
    sr.converged = true;
    return sr;
  }
  const Index nz = op.nz;
  VecX r = rhs, rh = rhs, p = VecX::Zero(rhs.size()), v = p, t;
  VecX xa = VecX::Zero(nz), xy = x, pha, phy, sha, shy;
  double rho = 1, alpha = 1, omega = 1;
  while (sr.iterations < opt.max_iterations && r.norm() > opt.rel_tol * bn) {
    const double rho1 = rh.dot(r);
    if (rho1 == 0.0) break;
    p = r + (rho1 / rho) * (alpha / omega) * (p - omega * v);
    op.precondition_nonsymmetric(p, pha, phy);
    op.S2(pha, phy, v);
    alpha = rho1 / rh.dot(v);
    const VecX sv = r - alpha * v;
    ++sr.iterations;
    if (sv.norm() <= opt.rel_tol * bn) {
      xy += alpha * phy;
      if (nz) xa += alpha * pha;
      r = sv;
      break;
    }
    op.precondition_nonsymmetric(sv, sha, shy);
    op.S2(sha, shy, t);
    omega = t.dot(sv) / t.dot(t);
    xy += alpha * phy + omega * shy;
    if (nz) xa += alpha * pha + omega * sha;
    r = sv - omega * t;
    rho = rho1;
    if (!std::isfinite(omega) || omega == 0.0) break;
  }
  op.S2(xa, xy, t);
  sr.residual = (rhs - t).norm() / bn;  // the true residual
  sr.converged = sr.residual <= opt.rel_tol;
  x = nz ? VecX(op.Z * xa + xy) : xy;
  sr.solve_s = now_seconds() - t1;
  return sr;
}

}  // namespace

CoupledSolves solve_assembled(const CoupledSystem& sys, CoupledSolverKind which,
                              const CoupledOptions& opt, CoupledReport& rep) {
  const double t0 = now_seconds();
  const Index ns = sys.ns, ng = sys.ng, nrhs = static_cast<Index>(sys.R2.size());
  const bool paper = which != CoupledSolverKind::SymmetricUmfpack;
  // Rows of the second block: −Jᵀ u − C p (symmetric), scaled by 1/V_g (paper form).
  const VecX rowscale = paper ? VecX(sys.gvol.cwiseInverse()) : VecX(VecX::Ones(ng));
  const SparseMatrix K = assemble_K(sys, rowscale);
  SolverOptions so;
  so.rel_tol = opt.rel_tol;
  so.max_iterations = opt.max_iterations;
  so.symmetric = !paper;
  const SolverKind kind =
      which == CoupledSolverKind::BiCgStabIlut ? SolverKind::BiCgStabIlut : SolverKind::Umfpack;
  auto solver = make_linear_solver(kind, so);
  solver->setup(K);
  rep.setup_s = now_seconds() - t0;
  CoupledSolves x;
  x.U.resize(nrhs);
  x.P.resize(nrhs);
  x.Pa.resize(nrhs);
  for (Index k = 0; k < nrhs; ++k) {
    VecX rhs(ns + ng);
    rhs.head(ns) = k == 0 ? sys.bs : VecX(VecX::Zero(ns));
    rhs.tail(ng) = sys.R2[k].cwiseProduct(rowscale);
    VecX xk = VecX::Zero(ns + ng);
    merge(solver->solve(rhs, xk), rep);
    x.U[k] = xk.head(ns);
    x.P[k] = xk.tail(ng);
  }
  return x;
}

namespace {

/// The grid's paper form: BiCGSTAB on S per right-hand side, u = A⁻¹ (b + J p); LU (the
/// paper's umfpack) if the iteration fails.
CoupledSolves solve_schur_nonsymmetric(const CoupledSystem& sys, const SchurOperator& op,
                                       const CoupledOptions& opt, CoupledReport& rep) {
  const Index ns = sys.ns, nrhs = static_cast<Index>(sys.R2.size());
  CoupledSolves x;
  x.U.resize(nrhs);
  x.P.resize(nrhs);
  x.Pa.assign(nrhs, VecX());
  bool ok = true;
  VecX Ab;
  op.solve_A(sys.bs, Ab);
  CoupledReport it = rep;
  for (Index k = 0; k < nrhs && ok; ++k) {
    VecX rhs = -sys.R2[k];
    if (k == 0) rhs -= sys.Jt * Ab;
    VecX p;
    const SolveReport sr = schur_bicgstab(op, opt, rhs, p);
    merge(sr, it);
    ok = sr.converged;
    VecX u;
    op.solve_A((k == 0 ? sys.bs : VecX(VecX::Zero(ns))) + sys.J * p, u);
    x.U[k] = u;
    x.P[k] = p;
  }
  if (ok) {
    rep = it;
    rep.backend = "schur_amg (bicgstab)";
    return x;
  }
  logger().debug(
      "coupled solve: BiCGSTAB on the non-symmetric Schur complement did not converge ({} "
      "iterations, residual {:.3g}); solving by LU (umfpack)",
      it.iterations, it.residual);
  rep.backend = "schur_amg+umfpack";
  CoupledSolves lu = solve_assembled(sys, CoupledSolverKind::Umfpack, opt, rep);
  lu.Pa.assign(nrhs, VecX());
  return lu;
}

}  // namespace

CoupledSolves solve_schur_amg(const CoupledSystem& sys, const CoupledOptions& opt,
                              CoupledReport& rep) {
  const double t0 = now_seconds();
  const Index ns = sys.ns, nrhs = static_cast<Index>(sys.R2.size());
  const BodySolve solve_A(sys);
  std::unique_ptr<AmgPreconditioner> own_amg;
  const SchurOperator op(sys, solve_A, amg_for(sys, opt, own_amg));
  rep.setup_s = now_seconds() - t0;
  if (!sys.symmetric && ns > 0) return solve_schur_nonsymmetric(sys, op, opt, rep);
  bool breakdown = false;
  CoupledSolves x;
  x.U.resize(nrhs);
  x.P.resize(nrhs);
  x.Pa.resize(nrhs);
  VecX Ab;
  if (ns > 0) solve_A(sys.bs, Ab);
  for (Index k = 0; k < nrhs; ++k) {
    // S p = −R2 − Jᵀ A⁻¹ b (b only for the step's column), u = A⁻¹ (b + J p)
    VecX rhs = -sys.R2[k];
    if (k == 0 && ns > 0) rhs -= sys.Jt * Ab;
    VecX pa, py;
    merge(schur_pcg(op, opt, rhs, pa, py, breakdown), rep);
    VecX u;
    if (ns > 0) {
      VecX f = (k == 0 ? sys.bs : VecX(VecX::Zero(ns))) + sys.J * py;
      if (op.nz) f += op.JZ * pa;
      solve_A(f, u);
    }
    x.U[k] = u;
    x.P[k] = py;
    x.Pa[k] = pa;
  }
  x.Z = op.Z;
  if (!breakdown) return x;
  // S is not positive definite: a body's A = M/h + C + (h/2) K' is indefinite (StVK under
  // strong compression, or a soft body under a large pressure whose follower stiffness the
  // linearisation leaves out). LU of the symmetric form still solves the step.
  logger().warn(
      "coupled solve: the Schur complement is not positive definite (a body's "
      "stiffness is indefinite); this step is solved by LU (symmetric_umfpack)");
  rep.backend = "schur_amg+symmetric_umfpack";
  rep.iterations = 0;
  rep.residual = 0.0;
  rep.floor = 0.0;
  rep.solves_at_floor = 0;
  rep.stagnated = false;
  rep.converged = true;
  CoupledSolves lu = solve_assembled(sys, CoupledSolverKind::SymmetricUmfpack, opt, rep);
  lu.Pa.assign(nrhs, VecX());
  lu.Z = x.Z;
  return lu;
}

}  // namespace tetfsi::coupling
