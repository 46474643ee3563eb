// Tests of core/equilibrium.cpp: the BFGS algebra of [BatheSonnad80, Eq. (11)] (Matthies &
// Strang's product form), the line search of Eqs. (9)–(10), and the iteration with its
// convergence tests, Eqs. (12)–(13), on small dense problems.
#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <cmath>

#include "core/equilibrium.hpp"
#include "core/error.hpp"

using namespace tetfsi;
using Dense = Eigen::MatrixXd;

namespace {

/// A deterministic SPD matrix: a 1D spring chain (tridiagonal) plus a diagonal shift.
Dense spd(Index n, double shift = 0.5) {
  Dense K = Dense::Zero(n, n);
  for (Index i = 0; i < n; ++i) {
    K(i, i) = 2.0 + shift + 0.1 * i;
    if (i + 1 < n) K(i, i + 1) = K(i + 1, i) = -1.0;
  }
  return K;
}

VecX pattern(Index n, double a) {
  VecX v(n);
  for (Index i = 0; i < n; ++i) v[i] = std::sin(a * (i + 1)) + 0.3 * std::cos(2.1 * a * i);
  return v;
}

/// g(x) = b − K x − c x³: a chain of hardening springs (K ≈ −∂g/∂x at x = 0).
struct Cubic {
  Dense K;
  VecX b;
  double c = 0.5;
  VecX g(const VecX& x) const { return b - K * x - c * x.array().cube().matrix(); }
  Dense tangent(const VecX& x) const {
    Dense T = K;
    for (Index i = 0; i < x.size(); ++i) T(i, i) += 3.0 * c * x[i] * x[i];
    return T;
  }
};

InverseOperator dense_inverse(const Dense& K) {
  auto lu = std::make_shared<Eigen::PartialPivLU<Dense>>(K);
  return [lu](const VecX& r) -> VecX { return lu->solve(r); };
}

double rel(const VecX& a, const VecX& b) {
  return (a - b).norm() / b.norm();
}

}  // namespace

TEST_CASE("rank_one_condition is the exact 2-norm condition number of I + v w^T") {
  for (int k = 0; k < 5; ++k) {
    const Index n = 7;
    const VecX v = pattern(n, 0.7 + 0.3 * k) * (k + 1), w = pattern(n, 1.9 - 0.2 * k) / (k + 1);
    const Dense A = Dense::Identity(n, n) + v * w.transpose();
    Eigen::JacobiSVD<Dense> svd(A);
    const double exact = svd.singularValues()(0) / svd.singularValues()(n - 1);
    CHECK(rank_one_condition(v, w) == doctest::Approx(exact).epsilon(1e-9));
  }
  // v ∥ w: A symmetric with one eigenvalue 1 + wᵀv
  const VecX v = pattern(5, 0.4);
  CHECK(rank_one_condition(v, 3.0 * v) == doctest::Approx(1.0 + 3.0 * v.squaredNorm()));
  // singular: w = −v / |v|² gives 1 + wᵀv = 0
  CHECK(rank_one_condition(v, -v / v.squaredNorm()) > 1e12);
}

TEST_CASE("BFGS product form: secant condition, the explicit update A^T H A, and classic BFGS") {
  const Index n = 8;
  Cubic p{spd(n), pattern(n, 0.8)};
  const Dense K0 = p.K;
  BfgsInverse H(dense_inverse(K0));
  Dense Hd = K0.inverse();  // explicitly updated product form
  Dense Hc = K0.inverse();  // classic BFGS inverse update
  VecX x = VecX::Zero(n), g = p.g(x);
  int made = 0;
  for (int it = 0; it < 6; ++it) {
    const VecX dx = H.apply(g);
    const double beta = it % 2 ? 0.7 : 1.0;  // also steps that are not the full increment
    const VecX xn = x + beta * dx, gn = p.g(xn);
    const VecX delta = xn - x, gamma = g - gn;
    REQUIRE(H.update(delta, gamma, beta * g, 1e5));
    ++made;
    const auto& [v, w] = H.factors().back();
    const Dense A = Dense::Identity(n, n) + v * w.transpose();
    Hd = A.transpose() * Hd * A;
    const double rho = 1.0 / gamma.dot(delta);
    const Dense E = Dense::Identity(n, n) - rho * gamma * delta.transpose();
    Hc = E.transpose() * Hc * E + rho * delta * delta.transpose();
    // secant condition (K̂⁻¹)⁽ⁱ⁾ γ = δ
    CHECK(rel(H.apply(gamma), delta) < 1e-11);
    for (int k = 0; k < 3; ++k) {
      const VecX r = pattern(n, 0.3 + k);
      CHECK(rel(H.apply(r), Hd * r) < 1e-11);
      CHECK(rel(Hd * r, Hc * r) < 1e-10);
    }
    CHECK(H.last_condition() == doctest::Approx(rank_one_condition(v, w)));
    x = xn;
    g = gn;
  }
  CHECK(H.updates() == made);
  // symmetric positive definite after the updates
  const Dense Hs = 0.5 * (Hd + Hd.transpose());
  CHECK((Hd - Hs).norm() < 1e-10 * Hd.norm());
  CHECK(Eigen::SelfAdjointEigenSolver<Dense>(Hs).eigenvalues().minCoeff() > 0.0);
}

TEST_CASE("BFGS skips updates with delta^T gamma <= 0 or an ill-conditioned A") {
  const Index n = 5;
  const Dense K0 = spd(n);
  BfgsInverse H(dense_inverse(K0));
  const VecX r = pattern(n, 0.5), before = H.apply(r);
  const VecX delta = pattern(n, 1.1);
  CHECK_FALSE(H.update(delta, -K0 * delta, K0 * delta, 1e5));  // δᵀγ < 0
  CHECK(std::isinf(H.last_condition()));
  // γ almost orthogonal to δ: c = (δᵀγ/δᵀKδ)^½ tiny, cond(A) ≈ 1/c huge
  VecX gamma = K0 * delta;
  gamma -= (gamma.dot(delta) / delta.squaredNorm() - 1e-14) * delta;
  CHECK_FALSE(H.update(delta, gamma, K0 * delta, 1e5));
  CHECK(H.last_condition() > 1e5);
  CHECK(H.updates() == 0);
  CHECK(rel(H.apply(r), before) == 0.0);
  // a well-conditioned one is made
  CHECK(H.update(delta, 1.3 * K0 * delta, K0 * delta, 1e5));
  CHECK(H.updates() == 1);
}

TEST_CASE("line search accepts beta = 1 within STOL and finds beta where the step is off") {
  const Index n = 6;
  const Dense K = spd(n);
  const VecX b = pattern(n, 0.9), x = VecX::Zero(n), g = b;  // g(x) = b − K x, linear
  auto residual = [&](const VecX& y) -> VecX { return b - K * y; };
  EquilibriumOptions opt;
  opt.stol = 0.4;
  SUBCASE("exact increment: beta = 1, one evaluation") {
    const VecX dx = K.partialPivLu().solve(g);
    const LineSearchResult ls = line_search(residual, x, dx, g, opt);
    CHECK(ls.beta == 1.0);
    CHECK(ls.evaluations == 1);
    CHECK(ls.satisfied);
  }
  SUBCASE("a step 1/1.5 too short is within STOL: accepted at beta = 1") {
    const VecX dx = (1.5 * K).partialPivLu().solve(g);  // φ(1) = φ₀ / 3
    const LineSearchResult ls = line_search(residual, x, dx, g, opt);
    CHECK(ls.beta == 1.0);
    CHECK(ls.evaluations == 1);
  }
  SUBCASE("4x too short: beta = 1 and 2 rejected, beta = 4 lands on the minimum") {
    const VecX dx = (4.0 * K).partialPivLu().solve(g);  // φ(β) = φ₀ (1 − β/4)
    const LineSearchResult ls = line_search(residual, x, dx, g, opt);
    CHECK(ls.beta == doctest::Approx(4.0));
    CHECK(ls.evaluations == 3);
    CHECK(ls.satisfied);
    CHECK(rel(ls.x, K.partialPivLu().solve(b)) < 1e-12);
  }
  SUBCASE("4x overshoot: beta = 1 rejected (Delta^T g = -3 phi0), regula falsi gives 1/4") {
    const VecX dx = (0.25 * K).partialPivLu().solve(g);
    const LineSearchResult ls = line_search(residual, x, dx, g, opt);
    CHECK(ls.beta == doctest::Approx(0.25));
    CHECK(ls.evaluations == 2);
    CHECK(ls.satisfied);
  }
  SUBCASE("a nonlinear residual: the accepted beta satisfies Eq. (10)") {
    Cubic p{K, 4.0 * b, 2.0};
    auto res = [&](const VecX& y) -> VecX { return p.g(y); };
    const VecX g0 = p.g(x);
    const VecX dx = (0.2 * K).partialPivLu().solve(g0);  // far too long
    const LineSearchResult ls = line_search(res, x, dx, g0, opt);
    CHECK(ls.satisfied);
    CHECK(std::abs(dx.dot(p.g(ls.x))) <= opt.stol * dx.dot(g0));
    CHECK(ls.beta < 1.0);
  }
}

TEST_CASE("Newton, modified Newton and BFGS solve the same nonlinear problem") {
  const Index n = 10;
  Cubic p{spd(n, 0.2), 3.0 * pattern(n, 0.6), 1.0};
  EquilibriumProblem prob;
  prob.residual = [&](const VecX& x) { return p.g(x); };
  prob.factor = [&](const VecX& x) { return dense_inverse(p.tangent(x)); };
  EquilibriumOptions opt;
  opt.rtol = 1e-10;
  opt.etol = 1e-18;
  opt.max_iterations = 60;
  opt.line_search_newton = true;  // from x = 0 plain modified Newton overshoots here
  VecX sol[3];
  int its[3];
  const IterationMethod methods[3] = {IterationMethod::Newton, IterationMethod::ModifiedNewton,
                                      IterationMethod::Bfgs};
  for (int k = 0; k < 3; ++k) {
    opt.method = methods[k];
    EquilibriumHistory hist;
    sol[k] = VecX::Zero(n);
    const EquilibriumReport rep = solve_equilibrium(prob, sol[k], opt, hist);
    INFO(std::string(to_string(methods[k])), ": ", rep.failure);
    REQUIRE(rep.converged);
    CHECK(p.g(sol[k]).norm() <= 1e-10 * p.g(VecX::Zero(n)).norm());
    its[k] = rep.iterations;
    MESSAGE(std::string(to_string(methods[k])), ": ", rep.iterations, " iterations, ",
            rep.evaluations, " evaluations, ", rep.factorizations, " factorizations, ", rep.updates,
            " updates");
    if (methods[k] == IterationMethod::Newton) CHECK(rep.factorizations == rep.iterations);
    if (methods[k] != IterationMethod::Newton) CHECK(rep.factorizations == 1);
  }
  CHECK(sol[0].norm() > 1.0);  // far from linear: |x| ~ 1, c x³ ~ K x
  CHECK(rel(sol[1], sol[0]) < 1e-9);
  CHECK(rel(sol[2], sol[0]) < 1e-9);
  CHECK(its[0] < its[2]);
  CHECK(its[2] < its[1]);
}

TEST_CASE("a linear problem with the exact matrix converges in 2 iterations (Table I's 2)") {
  const Index n = 6;
  const Dense K = spd(n);
  const VecX b = pattern(n, 1.3);
  EquilibriumProblem prob;
  prob.residual = [&](const VecX& x) -> VecX { return b - K * x; };
  prob.factor = [&](const VecX&) { return dense_inverse(K); };
  for (IterationMethod m :
       {IterationMethod::Newton, IterationMethod::ModifiedNewton, IterationMethod::Bfgs}) {
    EquilibriumOptions opt;
    opt.method = m;
    EquilibriumHistory hist;
    VecX x = VecX::Zero(n);
    const EquilibriumReport rep = solve_equilibrium(prob, x, opt, hist);
    CHECK(rep.converged);
    CHECK(rep.iterations == 2);
    CHECK(rep.evaluations == 2);
    CHECK(rel(x, K.partialPivLu().solve(b)) < 1e-12);
    CHECK(hist.max_force == doctest::Approx(b.norm()));
  }
}

TEST_CASE("modified Newton with a poor matrix fails and says so - BFGS recovers") {
  const Index n = 8;
  const Dense K = spd(n);
  const VecX b = pattern(n, 0.7);
  EquilibriumProblem prob;
  prob.residual = [&](const VecX& x) -> VecX { return b - K * x; };
  // the starting matrix leaves out most of K (like the fluid left out of Eq. (15))
  const Dense K0 = 0.1 * Dense::Identity(n, n) + 0.05 * K;
  prob.factor = [&](const VecX&) { return dense_inverse(K0); };
  EquilibriumOptions opt;
  opt.line_search = false;
  opt.method = IterationMethod::ModifiedNewton;
  EquilibriumHistory hist;
  VecX x = VecX::Zero(n);
  const EquilibriumReport mn = solve_equilibrium(prob, x, opt, hist);
  CHECK_FALSE(mn.converged);
  CHECK(mn.failure.find("diverged") != std::string::npos);
  opt.method = IterationMethod::Bfgs;
  opt.line_search = true;
  EquilibriumHistory hist2;
  x = VecX::Zero(n);
  const EquilibriumReport bf = solve_equilibrium(prob, x, opt, hist2);
  INFO(bf.failure);
  CHECK(bf.converged);
  CHECK(bf.iterations <= n + 2);  // BFGS with line search on a quadratic: ~conjugate gradients
  CHECK((b - K * x).norm() <= opt.rtol * b.norm());
}

TEST_CASE("keep_matrix forms the starting matrix once per run - max_force spans solves") {
  const Index n = 5;
  const Dense K = spd(n);
  int formed = 0;
  VecX b = pattern(n, 0.3);
  EquilibriumProblem prob;
  prob.residual = [&](const VecX& x) -> VecX { return b - K * x; };
  prob.factor = [&](const VecX&) {
    ++formed;
    return dense_inverse(K);
  };
  EquilibriumOptions opt;
  opt.method = IterationMethod::ModifiedNewton;
  opt.keep_matrix = true;
  EquilibriumHistory hist;
  VecX x = VecX::Zero(n);
  CHECK(solve_equilibrium(prob, x, opt, hist).converged);
  const double first = hist.max_force;
  b *= 0.5;  // a smaller load: the reference force stays the first one's
  x.setZero();
  CHECK(solve_equilibrium(prob, x, opt, hist).converged);
  CHECK(formed == 1);
  CHECK(hist.max_force == first);
  EquilibriumOptions bad;
  bad.stol = 1.5;
  CHECK_THROWS_AS(solve_equilibrium(prob, x, bad, hist), InputError);
}
