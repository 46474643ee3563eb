#pragma once
/// @file material.hpp
/// Isotropic St. Venant–Kirchhoff material with Rayleigh damping.
#include <string>

namespace tetfsi::solid {

struct Material {
  double density = 1000.0;        ///< ρ (kg/m³), > 0
  double youngs_modulus = 1.0e5;  ///< E (Pa), > 0
  double poisson_ratio = 0.3;     ///< ν, in (−1, 0.5)
  double rayleigh_alpha = 0.0;    ///< α (1/s): C = αM + βK'  [Chentanez06, §3.2]
  double rayleigh_beta = 0.0;     ///< β (s)
};

struct LameParameters {
  double lambda;  ///< λ = Eν / ((1 + ν)(1 − 2ν))  (Pa)
  double mu;      ///< μ = E / (2(1 + ν))          (Pa)
};

LameParameters lame_parameters(const Material& m);

/// @throws InputError naming `where` (e.g. "scene.json: bodies[0].material") and the bad field.
void validate_material(const Material& m, const std::string& where);

}  // namespace tetfsi::solid
