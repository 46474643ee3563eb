#include "solid/integrator.hpp"

#include <cmath>

#include "core/dof_elimination.hpp"
#include "core/error.hpp"

namespace tetfsi::solid {

Trapezoid parse_trapezoid(const std::string& name) {
  return k_trapezoid_names.parse(name);
}

const char* to_string(Trapezoid t) {
  return k_trapezoid_names.name(t);
}

TrapezoidalSystem assemble_trapezoidal(const SolidBody& body, double h, const VecX& f_e,
                                       Trapezoid variant) {
  TETFSI_REQUIRE(InputError, h > 0.0 && std::isfinite(h), "body '{}': time step h = {} must be > 0",
                 body.name(), h);
  const Index ndof = body.num_dofs();
  TETFSI_CHECK(f_e.size() == ndof, "f_e has size {}, expected {}", f_e.size(), ndof);
  const Material& mat = body.material();
  const VecX& mass = body.lumped_mass();

  TrapezoidalSystem sys;
  VecX K;  // K(dⁿ), internal elastic force
  body.elasticity().forces_and_jacobian(body.positions(), K, sys.A);  // sys.A holds K' for now
  const VecX u = flat(body.velocity);

  // Weight w of K' uⁿ and K' uⁿ⁺¹: h/2 for K(dⁿ⁺¹) [Chentanez06, Eq. (16)], h/4 for the
  // midpoint K((dⁿ + dⁿ⁺¹)/2), since dⁿ⁺¹ − dⁿ = h/2 (uⁿ + uⁿ⁺¹) by Eq. (5).
  const double w = variant == Trapezoid::Paper ? 0.5 * h : 0.25 * h;

  // b = M uⁿ/h − w K' uⁿ − K(dⁿ) + f_e   [Chentanez06, Eq. (4)]
  VecX Mu(ndof);
  for (Index i = 0; i < ndof; ++i) Mu[i] = mass[i / 3] * u[i];
  sys.b = Mu / h - w * (sys.A * u) - K + f_e;

  // A = M/h + C + w K',  C = αM + βK'   [Chentanez06, Eq. (4), §3.2]
  const double k_coef = mat.rayleigh_beta + w;
  const double m_coef = 1.0 / h + mat.rayleigh_alpha;
  sys.A *= k_coef;
  const auto& fixed = body.fixed_dofs();
  for (Index col = 0; col < ndof; ++col)
    for (SparseMatrix::InnerIterator it(sys.A, col); it; ++it)
      if (it.row() == col && !fixed[col]) it.valueRef() += m_coef * mass[col / 3];
  // fixed DOFs: zero rows and columns, diagonal m/h, b = 0
  eliminate_dofs(
      sys.A, fixed, [&](Index i) { return mass[i / 3] / h; }, &sys.b);
  return sys;
}

void trapezoidal_displace(Eigen::Ref<VecX> x, const VecX& u_old, const VecX& u_new, double h) {
  TETFSI_CHECK(x.size() == u_old.size() && x.size() == u_new.size(),
               "trapezoidal_displace: x {}, u_old {}, u_new {}", x.size(), u_old.size(),
               u_new.size());
  x += (0.5 * h) * (u_old + u_new);  // [Chentanez06, Eq. (5)]
}

void advance_trapezoidal(SolidBody& body, const VecX& u_new, double h) {
  TETFSI_CHECK(u_new.size() == body.num_dofs(), "u_new has size {}, expected {}", u_new.size(),
               body.num_dofs());
  auto d = flat(body.displacement);
  auto u = flat(body.velocity);
  VecX un = u_new;
  for (Index i = 0; i < body.num_dofs(); ++i)
    if (body.is_fixed(i)) un[i] = 0.0;
  trapezoidal_displace(d, u, un, h);  // dⁿ⁺¹ = dⁿ + h/2 (uⁿ + uⁿ⁺¹)
  u = un;
}

}  // namespace tetfsi::solid
