#pragma once
/// @file forces.hpp
/// The body force every discretisation of the fluid shares: buoyancy [Fedkiw01, Eq. (8)],
/// evaluated per cell (each discretisation applies it to its faces; vorticity confinement is
/// each one's own: tet/confinement.hpp, the grid's in grid/simulation.cpp).
#include "core/types.hpp"
#include "fluid/params.hpp"

namespace tetfsi::fluid {

/// Per-cell buoyancy acceleration (#T × 3, m/s²): (−α ρ_smoke + β (T − T_amb)) up.
MatX3 buoyancy(const FluidParams& p, const VecX& density, const VecX& temperature);

}  // namespace tetfsi::fluid
