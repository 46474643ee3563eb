#include "solid/nonlinear_trapezoid.hpp"

#include <cmath>
#include <memory>

#include "core/dof_elimination.hpp"
#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "solid/integrator.hpp"

namespace tetfsi::solid {

Integrator parse_integrator(const std::string& name) {
  return k_integrator_names.parse(name);
}

const char* to_string(Integrator i) {
  return k_integrator_names.name(i);
}

IterationMethod iteration_method(Integrator i) {
  TETFSI_CHECK(i != Integrator::Linearized, "the linearized integrator does not iterate");
  return i == Integrator::Newton           ? IterationMethod::Newton
         : i == Integrator::ModifiedNewton ? IterationMethod::ModifiedNewton
                                           : IterationMethod::Bfgs;
}

TrapezoidalEquilibrium::TrapezoidalEquilibrium(const SolidBody& body, double h, const VecX& f_e)
    : m_body(body), m_h(h), m_mass(body.lumped_mass()), m_fe(f_e) {
  TETFSI_REQUIRE(InputError, h > 0.0 && std::isfinite(h), "body '{}': time step h = {} must be > 0",
                 body.name(), h);
  TETFSI_CHECK(f_e.size() == body.num_dofs(), "f_e has size {}, expected {}", f_e.size(),
               body.num_dofs());
  m_d0 = flat(body.displacement);
  m_u0 = flat(body.velocity);
  VecX K0;
  SparseMatrix Kp;
  const double beta = body.material().rayleigh_beta;
  if (beta != 0.0) {
    body.elasticity().forces_and_jacobian(body.positions(), K0, Kp);
    m_C = beta * Kp;
  } else {
    K0 = body.elasticity().forces(body.positions());
  }
  m_fs0 = f_e - K0;
  const double alpha = body.material().rayleigh_alpha;
  for (Index i = 0; i < m_u0.size(); ++i) m_fs0[i] -= alpha * m_mass[i / 3] * m_u0[i];
  if (m_C.size()) m_fs0 -= m_C * m_u0;
}

VecX TrapezoidalEquilibrium::displacement(const VecX& u1) const {
  VecX d = m_d0;
  trapezoidal_displace(d, m_u0, u1, m_h);  // [BatheSonnad80, Eq. (3)]
  return d;
}

MatX3 TrapezoidalEquilibrium::positions(const VecX& u1) const {
  MatX3 x = m_body.rest_positions();
  flat(x) += displacement(u1);
  return x;
}

VecX TrapezoidalEquilibrium::residual(const VecX& u1) const {
  const VecX K1 = m_body.elasticity().forces(positions(u1));
  const double alpha = m_body.material().rayleigh_alpha;
  // g = ½ (f_s⁰ + f_s¹) − M (u¹ − uⁿ)/h, f_s¹ = f_e − C u¹ − K(d¹)   [BatheSonnad80, Eq. (6)] / 2
  VecX g = 0.5 * (m_fs0 + m_fe - K1);
  if (m_C.size()) g -= 0.5 * (m_C * u1);
  const auto& fixed = m_body.fixed_dofs();
  for (Index i = 0; i < g.size(); ++i) {
    const double m = m_mass[i / 3];
    g[i] -= 0.5 * alpha * m * u1[i] + m * (u1[i] - m_u0[i]) / m_h;
    if (fixed[i]) g[i] = 0.0;
  }
  return g;
}

SparseMatrix TrapezoidalEquilibrium::tangent(const VecX& u1) const {
  SparseMatrix A = m_body.elasticity().jacobian(positions(u1));
  // (h/4) K̂ = M/h + C/2 + (h/4) K'(d¹)   [BatheSonnad80, Eq. (7)]
  A *= 0.25 * m_h;
  if (m_C.size()) A += 0.5 * m_C;
  const double alpha = m_body.material().rayleigh_alpha;
  const auto& fixed = m_body.fixed_dofs();
  for (Index col = 0; col < A.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(A, col); it; ++it)
      if (it.row() == col && !fixed[col]) {
        const double m = m_mass[col / 3];
        it.valueRef() += m / m_h + 0.5 * alpha * m;
      }
  eliminate_dofs(A, fixed, [&](Index i) { return m_mass[i / 3] / m_h; });  // diagonal m/h
  return A;
}

VecX TrapezoidalEquilibrium::start() const {
  VecX u = -m_u0;
  const auto& fixed = m_body.fixed_dofs();
  for (Index i = 0; i < u.size(); ++i)
    if (fixed[i]) u[i] = 0.0;
  return u;
}

FactoredMatrix factor_inverse(const SparseMatrix& A) {
  return factor_blocks({std::make_shared<const SparseMatrix>(A)},
                       {0, static_cast<Index>(A.rows())});
}

EquilibriumReport step_nonlinear(SolidBody& body, double h, const VecX& f_e,
                                 const EquilibriumOptions& opt, EquilibriumHistory& history) {
  const TrapezoidalEquilibrium eq(body, h, f_e);
  EquilibriumProblem problem;
  problem.residual = [&](const VecX& u) { return eq.residual(u); };
  problem.factor = [&](const VecX& u) { return factor_inverse(eq.tangent(u)); };
  VecX u = eq.start();
  const EquilibriumReport rep = solve_equilibrium(problem, u, opt, history);
  if (rep.converged) advance_trapezoidal(body, u, h);  // see [BatheSonnad80, Eq. (3)]
  return rep;
}

}  // namespace tetfsi::solid
