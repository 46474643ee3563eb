/// @file enclosed_volume.cpp
/// Enclosed liquids keep their volume exactly (coupled_system.hpp, "Enclosed regions"): the
/// net flux c of every enclosed region is chosen by Newton on the exact volume of its cavity's
/// triangles after Eq. (5).
#include <algorithm>
#include <cmath>

#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"
#include "solid/integrator.hpp"

namespace tetfsi::coupling {

double cavity_volume(const Cavity& cav, const std::vector<BodyInterface>& bodies,
                     const std::vector<MatX3>& x) {
  // V = −(1/6) Σ (x0 − c)·((x1 − c) × (x2 − c)) over triangles oriented out of the cavity's
  // solid, i.e. into the cavity
  if (cav.triangles.empty()) return 0.0;
  const auto& [b0, t0] = cav.triangles.front();
  const BodyInterface& i0 = bodies[b0];
  const Vec3 c = x[b0].row(i0.surface_node[i0.triangles(t0, 0)]).transpose();
  double v = 0.0;
  for (const auto& [b, t] : cav.triangles) {
    const BodyInterface& bi = bodies[b];
    Vec3 p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = x[b].row(bi.surface_node[bi.triangles(t, k)]).transpose() - c;
    v -= p[0].dot(p[1].cross(p[2]));
  }
  return v / 6.0;
}

std::vector<MatX3> positions_after_step(const CoupledSystem& sys, const VecX& u) {
  const std::vector<CoupledBody>& bodies = *sys.bodies;
  std::vector<MatX3> x(sys.nb);
  for (Index b = 0; b < sys.nb; ++b) {
    const CoupledBody& cb = bodies[b];
    if (!cb.free) continue;
    VecX un1 = u.segment(sys.dof0[b], sys.dof0[b + 1] - sys.dof0[b]);
    for (Index l = 0; l < un1.size(); ++l)
      if (cb.fixed[l]) un1[l] = cb.prescribed.size() ? cb.prescribed[l] : 0.0;
    x[b] = cb.x;
    solid::trapezoidal_displace(flat(x[b]), cb.u, un1, sys.h);
  }
  return x;
}

VecX solve_enclosed_volumes(const CoupledSystem& sys, const CoupledSolves& s,
                            VolumeTargets& targets, CoupledReport& rep) {
  const double t0 = now_seconds();
  const Index ne = static_cast<Index>(sys.enclosed.size());
  const std::vector<BodyInterface>& ops = *sys.interfaces;
  const double h = sys.h;
  VecX c = VecX::Zero(ne);
  if (ne == 0) return c;
  auto positions = [&](const VecX& cc) {  // node positions after Eq. (5) for the fluxes c
    VecX u = s.U[0];
    for (Index k = 0; k < ne; ++k) u += cc[k] * s.U[1 + k];
    return positions_after_step(sys, u);
  };
  std::vector<MatX3> xn(sys.nb);
  for (Index b = 0; b < sys.nb; ++b)
    if ((*sys.bodies)[b].free) xn[b] = (*sys.bodies)[b].x;
  std::vector<double> target(ne);
  for (Index k = 0; k < ne; ++k) {
    EnclosedRegion er;
    er.key = std::int64_t(sys.cavities[k].triangles.front().first) << 32 |
             std::int64_t(sys.cavities[k].triangles.front().second);
    er.volume = cavity_volume(sys.cavities[k], ops, xn);
    auto [it, inserted] = targets.emplace(er.key, er.volume);
    er.target = it->second;
    for (Index t = 0; t < sys.regions.cell_region.size(); ++t)
      if (sys.regions.cell_region[t] == sys.enclosed[k]) ++er.cells;
    target[k] = er.target;
    rep.enclosed.push_back(er);
  }
  for (int sweep = 0; sweep < 8; ++sweep) {
    double worst = 0.0;
    for (Index k = 0; k < ne; ++k) {
      for (int it = 0; it < 6; ++it) {
        const double v = cavity_volume(sys.cavities[k], ops, positions(c)) - target[k];
        const double eps = std::max(1e-12, 1e-6 * std::abs(target[k]) / h);
        VecX cp = c, cm = c;
        cp[k] += eps;
        cm[k] -= eps;
        const double dv = (cavity_volume(sys.cavities[k], ops, positions(cp)) -
                           cavity_volume(sys.cavities[k], ops, positions(cm))) /
                          (2 * eps);
        if (!(std::abs(dv) > 0)) break;
        c[k] -= v / dv;
        worst = std::max(worst, std::abs(v) / std::max(target[k], 1e-300));
        if (std::abs(v) <= 1e-14 * target[k]) break;
      }
    }
    if (worst <= 1e-14) break;
  }
  const std::vector<MatX3> x1 = positions(c);
  for (Index k = 0; k < ne; ++k) {
    rep.enclosed[k].after = cavity_volume(sys.cavities[k], ops, x1);
    rep.enclosed[k].flux = c[k];
  }
  rep.assembly_s += now_seconds() - t0;
  return c;
}

}  // namespace tetfsi::coupling
