#include "solid/material.hpp"

#include <cmath>

#include "core/error.hpp"

namespace tetfsi::solid {

LameParameters lame_parameters(const Material& m) {
  const double E = m.youngs_modulus;
  const double nu = m.poisson_ratio;
  // Standard isotropic relations (e.g. [OBrienHodgins99, §3]).
  return {E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))};
}

void validate_material(const Material& m, const std::string& where) {
  TETFSI_REQUIRE(InputError, std::isfinite(m.density) && m.density > 0.0,
                 "{}.density: {} is out of range; need a finite density > 0 (kg/m^3)", where,
                 m.density);
  TETFSI_REQUIRE(InputError, std::isfinite(m.youngs_modulus) && m.youngs_modulus > 0.0,
                 "{}.youngs_modulus: {} is out of range; need a finite Young's modulus > 0 (Pa)",
                 where, m.youngs_modulus);
  TETFSI_REQUIRE(InputError,
                 std::isfinite(m.poisson_ratio) && m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5,
                 "{}.poisson_ratio: {} is out of range; need -1 < poisson_ratio < 0.5 (0.5 is "
                 "incompressible and locks linear tets)",
                 where, m.poisson_ratio);
  TETFSI_REQUIRE(InputError, std::isfinite(m.rayleigh_alpha) && m.rayleigh_alpha >= 0.0,
                 "{}.rayleigh_alpha: {} is out of range; need a finite alpha >= 0 (1/s)", where,
                 m.rayleigh_alpha);
  TETFSI_REQUIRE(InputError, std::isfinite(m.rayleigh_beta) && m.rayleigh_beta >= 0.0,
                 "{}.rayleigh_beta: {} is out of range; need a finite beta >= 0 (s)", where,
                 m.rayleigh_beta);
}

}  // namespace tetfsi::solid
