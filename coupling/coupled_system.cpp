#include "coupling/coupled_system.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "fluid/tet/operators.hpp"
#include "fluid/tet/simulation.hpp"

namespace tetfsi::coupling {

using mesh::FaceKind;
using mesh::TetMesh;

CoupledSolverKind parse_coupled_solver(const std::string& name) {
  return k_coupled_solver_names.parse(name);
}

const char* to_string(CoupledSolverKind k) {
  return k_coupled_solver_names.name(k);
}

CoupledInput make_input(const fluid::FluidPrediction& pred, const fluid::FluidParams& params,
                        const InterfaceOperators& ops, const std::vector<CoupledBody>& bodies,
                        VolumeTargets* targets) {
  CoupledInput in;
  in.mesh = &pred.mesh;
  in.u_star = &pred.u_star;
  in.u_ref = &pred.u_star;
  in.rho = &pred.rho;
  in.p_open = &pred.p_open;
  in.h = pred.h;
  in.gravity = params.gravity;
  in.hydrostatic_origin = params.hydrostatic_origin;
  in.interface = &ops;
  in.bodies = &bodies;
  in.volume_targets = targets;
  return in;
}

std::vector<VecX> fluid_forces(const InterfaceOperators& ops, const VecX& p, const VecX& rho,
                               const Vec3& gravity, const Vec3& origin) {
  const TetMesh& m = ops.mesh();
  return ops.apply_J([&](const fluid::InterfaceFace& i) {
    const Index t = m.face_tets(i.face, 0);
    const Vec3 x = m.face_centroids.row(i.face).transpose();
    return p[t] + fluid::hydrostatic_pressure(rho[t], gravity, origin, x);
  });
}

CoupledSolution solve_coupled(const CoupledInput& in, const CoupledOptions& opt) {
  CoupledSolution sol;
  CoupledReport& rep = sol.report;
  rep.backend = to_string(opt.solver);
  rep.converged = true;
  const CoupledSystem sys = assemble_coupled(in, opt, rep);
  const auto [x, c] = solve_system(sys, opt, in.volume_targets, rep, "coupled solve");
  finish_coupled(sys, x, c, sol);
  return sol;
}

std::pair<CoupledSolves, VecX> solve_system(const CoupledSystem& sys, const CoupledOptions& opt,
                                            VolumeTargets* targets, CoupledReport& rep,
                                            const char* what) {
  CoupledSolves x = opt.solver == CoupledSolverKind::SchurAmg
                        ? solve_schur_amg(sys, opt, rep)
                        : solve_assembled(sys, opt.solver, opt, rep);
  for (size_t k = 0; k < x.U.size(); ++k)
    TETFSI_REQUIRE(SolverError, x.U[k].allFinite() && x.P[k].allFinite(),
                   "{} ({}) returned non-finite values after {} iterations; reduce time.dt", what,
                   rep.backend, rep.iterations);
  if (!rep.converged)  // the run's recorder warns, with the time and the remedy
    logger().debug("{} ({}) did not converge: {} iterations, residual {:.3g}{}", what, rep.backend,
                   rep.iterations, rep.residual,
                   rep.stagnated ? fmt::format(" (stagnated; round-off floor {:.3g})", rep.floor)
                                 : std::string());
  VecX c = sys.enclosed.empty() ? VecX() : solve_enclosed_volumes(sys, x, *targets, rep);
  return {std::move(x), std::move(c)};
}

std::pair<VecX, VecX> combine_solves(const CoupledSolves& x, const VecX& c) {
  const Index ne = c.size();
  VecX u = x.U[0], pg = x.P[0];
  VecX pa = x.Pa[0];
  for (Index k = 0; k < ne; ++k) {
    u += c[k] * x.U[1 + k];
    pg += c[k] * x.P[1 + k];
    if (pa.size()) pa += c[k] * x.Pa[1 + k];
  }
  if (pa.size()) pg += x.Z * pa;
  return {std::move(u), std::move(pg)};
}

std::vector<VecX> body_velocities(const CoupledSystem& sys, const VecX& u) {
  const std::vector<CoupledBody>& bodies = *sys.bodies;
  std::vector<VecX> ub_all(sys.nb);
  for (Index b = 0; b < sys.nb; ++b) {
    if (!bodies[b].free) continue;
    VecX ub = u.segment(sys.dof0[b], sys.dof0[b + 1] - sys.dof0[b]);
    for (Index l = 0; l < ub.size(); ++l)
      if (bodies[b].fixed[l]) ub[l] = bodies[b].prescribed.size() ? bodies[b].prescribed[l] : 0.0;
    ub_all[b] = std::move(ub);
  }
  return ub_all;
}

void add_half_cell_forces(const CoupledSystem& sys, const VecX& u_face, std::vector<VecX>& force) {
  const CoupledInput& in = *sys.in;
  const TetMesh& m = *in.mesh;
  const VecX& u_ref = in.half_cell_u0();
  // −ρ_t A_f δ_f (u_f − u_f⁰)/h H_fᵀ, H_f = w_f / A_f (coupled_system.hpp, half cells)
  in.interface->for_each_J_entry([&](Index f, Index, Index b, Index l, Index, double w) {
    force[b][l] -= sys.half_mass[f] * m.face_areas[f] * (u_face[f] - u_ref[f]) / in.h * w;
  });
}

void finish_coupled(const CoupledSystem& sys, const CoupledSolves& x, const VecX& c,
                    CoupledSolution& sol) {
  const double t0 = now_seconds();
  const CoupledInput& in = *sys.in;
  const TetMesh& m = *in.mesh;
  const Index nt = m.num_tets(), nf = m.num_faces(), ne = c.size();
  CoupledReport& rep = sol.report;
  const auto [u, pg] = combine_solves(x, c);
  sol.p.resize(nt);
  for (Index t = 0; t < nt; ++t) sol.p[t] = pg[sys.groups.cell_group[t]];
  sol.u = body_velocities(sys, u);
  rep.interface_power = sys.ns > 0 ? (sys.J * pg).dot(u) : 0.0;
  // see [Chentanez06, Eq. (8)]: v* − (h/ρ) G p on interior and Open faces, (H u)_f on the
  // faces of free bodies.
  sol.u_face = *in.u_star;
  in.interface->apply_H(sol.u, sol.u_face);
  VecX q(nt), source = VecX::Zero(nt);
  for (Index t = 0; t < nt; ++t) q[t] = sol.p[t] * in.h / (*in.rho)[t];
  for (Index k = 0; k < ne; ++k)
    for (Index t = 0; t < nt; ++t)
      if (sys.regions.cell_region[t] == sys.enclosed[k])
        source[t] = c[k] * m.volumes[t] / sys.rvol[sys.enclosed[k]];
  VecX q_open = VecX::Zero(nf);
  for (Index f = 0; f < nf; ++f)
    if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open)
      q_open[f] = (*in.p_open)[f] * in.h / (*in.rho)[m.face_tets(f, 0)];
  fluid::apply_pressure_gradient(m, sys.d_eff, sys.groups, q, q_open, sol.u_face,
                                 ne ? &source : nullptr);
  rep.divergence_after =
      nt ? (fluid::net_flux(m, sol.u_face) - source).cwiseQuotient(m.volumes).cwiseAbs().maxCoeff()
         : 0.0;
  // The fluid's forces on every body (J p + hydrostatic), for reports and time splitting.
  sol.fluid_force = fluid_forces(*in.interface, sol.p, *in.rho, in.gravity, in.hydrostatic_origin);
  if (sys.half_mass.size()) add_half_cell_forces(sys, sol.u_face, sol.fluid_force);
  rep.assembly_s += now_seconds() - t0;
}

}  // namespace tetfsi::coupling
