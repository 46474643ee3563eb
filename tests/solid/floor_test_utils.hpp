#pragma once
/// @file floor_test_utils.hpp
/// Bodies on floors for the floor-contact tests (solid/floor_contact.hpp), solid-only and
/// coupled: a soft ball, a block, and a log of a body's contacts with the floor.
#include <algorithm>
#include <string>
#include <vector>

#include "solid/static_solve.hpp"
#include "solid/world.hpp"
#include "solid_test_utils.hpp"

namespace tetfsi::solid::testing {

/// The bouncy ball of the floor tests: R = 5 cm (make_ball, 1 subdivision: 42 surface nodes,
/// 2 layers), rubber-like but soft, ρ = 1000 kg/m³, E = 1e5 Pa, ν = 0.3, no Rayleigh damping:
/// its lowest modes have ω ≈ c/R = sqrt(E/ρ)/R ≈ 200 rad/s, so a contact lasts ~15 ms and
/// h = 1 ms resolves it (ωh ≈ 0.2: the paper trapezoid's numerical damping ratio ≈ ωh/4).
/// Its lowest point starts `drop` above the floor point `below` (z up).
inline SolidBody bouncy_ball(double drop, const Vec3& below = Vec3::Zero(), double E = 1e5) {
  const double R = 0.05;
  return SolidBody("ball", mesh::make_ball(below + Vec3(0, 0, R + drop), R, 1),
                   make_material(1000.0, E, 0.3));
}

/// A block [0, 0.1] × [0, 0.1] × [0, 0.05] m (4 × 4 × 2 cells) on the floor z = 0, ρ = 1000,
/// E = 1e6 Pa, ν = 0.3, Rayleigh β = `beta`. Its own weight sags it by ~ρ g H²/(2E) ≈ 1e-5 m.
inline SolidBody floor_block(const Vec3& lo = Vec3(0, 0, 0), double beta = 1e-3) {
  return make_box_body("block", lo, lo + Vec3(0.1, 0.1, 0.05), Vec3i(4, 4, 2),
                       make_material(1000.0, 1e6, 0.3, 0.0, beta));
}

/// The block at its static equilibrium on the frictionless floor z = floor_z, at rest: solve_static
/// with its bottom nodes held at the floor (z pinned, sliding freely along it; the in-plane rigid
/// motion held at the bottom's middle node and the middle of its +x edge). The floor's forces
/// there are then the bottom's reactions, all normal. (The bottom clamped instead gives tangential
/// reactions at its rim of more than μ = 0.5 times the normal ones: started there the block slips
/// once by 2.3e-6 m, measured.) Started undeformed, it would sag ~1e-5 m and ring.
inline void settle_on_floor(SolidBody& block, double floor_z, const Vec3& gravity) {
  SolidBody held = block;
  const std::vector<Index> bottom = nodes_at(held, 2, floor_z, 1.0);
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (Index i : bottom) {
    held.fix_dof(i, 2);
    lo = lo.cwiseMin(held.rest_positions().row(i).transpose());
    hi = hi.cwiseMax(held.rest_positions().row(i).transpose());
  }
  const Index mid = closest_node(held, 0.5 * (lo + hi));
  held.fix_dof(mid, 0);
  held.fix_dof(mid, 1);
  held.fix_dof(closest_node(held, Vec3(hi.x(), 0.5 * (lo.y() + hi.y()), floor_z)), 1);
  StaticSolveOptions opt;
  opt.rel_tol = 1e-12;
  solve_static(held, held.external_forces(gravity), opt);  // throws if it does not converge
  block.displacement = held.displacement;
  block.velocity.setZero();
}

/// The least-squares slope of y(t).
inline double fit_slope(const std::vector<double>& t, const std::vector<double>& y) {
  const double n = static_cast<double>(t.size());
  double st = 0, sy = 0, stt = 0, sty = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    st += t[i];
    sy += y[i];
    stt += t[i] * t[i];
    sty += t[i] * y[i];
  }
  return (n * sty - st * sy) / (n * stt - st * st);
}

/// The body's lowest node height (m).
inline double lowest(const SolidBody& b) {
  return b.positions().col(2).minCoeff();
}

/// A body's contacts with the floor z = floor_z, one step at a time: it is on the floor while
/// its lowest node is within 1e-9 m of it, and has left it (a departure) once its lowest node
/// is `clear` above it. Apexes: the centre-of-mass heights where its vertical velocity turns
/// from up to down in flight.
struct BounceLog {
  double floor_z = 0.0;
  double clear = 1e-3;
  bool touching = false, rising = false;
  int landings = 0, departures = 0;
  std::vector<double> apexes;  ///< centre-of-mass heights at the tops of the flights (m)

  void record(const SolidBody& b) {
    const double low = lowest(b) - floor_z;
    if (low <= 1e-9) {
      if (!touching) ++landings;
      touching = true;
    } else if (touching && low >= clear) {
      touching = false;
      ++departures;
    }
    const double vz = com_velocity(b).z();
    if (!touching && departures > 0 && rising && vz <= 0.0) apexes.push_back(com(b).z());
    rising = vz > 0.0;
  }
};

}  // namespace tetfsi::solid::testing
