#include "fluid/forces.hpp"

namespace tetfsi::fluid {

MatX3 buoyancy(const FluidParams& p, const VecX& density, const VecX& temperature) {
  const Index nt = static_cast<Index>(density.size());
  MatX3 a(nt, 3);
  for (Index t = 0; t < nt; ++t) {
    // [Fedkiw01, Eq. (8)] f_buoy = −α ρ z + β (T − T_amb) z
    const double s =
        -p.buoyancy_alpha * density[t] + p.buoyancy_beta * (temperature[t] - p.ambient_temperature);
    a.row(t) = s * p.up.transpose();
  }
  return a;
}

}  // namespace tetfsi::fluid
