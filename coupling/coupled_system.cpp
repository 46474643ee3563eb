#include "coupling/coupled_system.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "fluid/operators.hpp"
#include "fluid/simulation.hpp"

namespace tetfsi::coupling {

using mesh::FaceKind;
using mesh::TetMesh;

const std::vector<std::string>& coupled_solver_names() {
  static const std::vector<std::string> n = {"schur_amg", "umfpack", "bicgstab_ilut",
                                             "symmetric_umfpack"};
  return n;
}

CoupledSolverKind parse_coupled_solver(const std::string& name) {
  if (name == "schur_amg") return CoupledSolverKind::SchurAmg;
  if (name == "umfpack") return CoupledSolverKind::Umfpack;
  if (name == "bicgstab_ilut") return CoupledSolverKind::BiCgStabIlut;
  if (name == "symmetric_umfpack") return CoupledSolverKind::SymmetricUmfpack;
  throw InputError(
      fmt::format("unknown coupled solver '{}': use schur_amg, umfpack, "
                  "bicgstab_ilut or symmetric_umfpack",
                  name));
}

const char* to_string(CoupledSolverKind k) {
  switch (k) {
    case CoupledSolverKind::SchurAmg:
      return "schur_amg";
    case CoupledSolverKind::Umfpack:
      return "umfpack";
    case CoupledSolverKind::BiCgStabIlut:
      return "bicgstab_ilut";
    case CoupledSolverKind::SymmetricUmfpack:
      return "symmetric_umfpack";
  }
  return "?";
}

CoupledInput make_input(const fluid::FluidPrediction& pred, const fluid::FluidParams& params,
                        const std::vector<CoupledBody>& bodies, VolumeTargets* targets) {
  CoupledInput in;
  in.mesh = &pred.mesh;
  in.u_star = &pred.u_star;
  in.rho = &pred.rho;
  in.p_open = &pred.p_open;
  in.h = pred.h;
  in.gravity = params.gravity;
  in.hydrostatic_origin = params.hydrostatic_origin;
  in.bodies = &bodies;
  in.volume_targets = targets;
  return in;
}

std::vector<VecX> fluid_forces(const TetMesh& m, const std::vector<BodyInterface>& bodies,
                               const VecX& p, const VecX& rho, const Vec3& gravity,
                               const Vec3& origin) {
  const std::vector<Index> off = node_offsets(bodies);
  std::vector<VecX> F(bodies.size());
  for (size_t b = 0; b < bodies.size(); ++b) F[b] = VecX::Zero(3 * bodies[b].num_nodes);
  for (const InterfaceFace& i : interface_faces(m, bodies)) {
    const Index f = i.face, t = m.face_tets(f, 0), b = m.face_body[f];
    const Vec3 x = m.face_centroids.row(f).transpose();
    const double pf = p[t] + fluid::hydrostatic_pressure(rho[t], gravity, origin, x);
    const Vec3 an = m.face_areas[f] * pf * m.face_normals.row(f).transpose();
    for (int k = 0; k < 3; ++k) F[b].segment<3>(3 * (i.node[k] - off[b])) += i.weight[k] * an;
  }
  return F;
}

namespace {

/// The signed volume enclosed by triangles (x0, x1, x2) oriented out of the cavity's solid,
/// i.e. into the cavity: V = −(1/6) Σ (x0 − c)·((x1 − c) × (x2 − c)).
struct Cavity {
  std::vector<std::pair<Index, Index>> triangles;  ///< (body, triangle)
};

double cavity_volume(const Cavity& cav, const std::vector<CoupledBody>& bodies,
                     const std::vector<MatX3>& x) {
  if (cav.triangles.empty()) return 0.0;
  const auto& [b0, t0] = cav.triangles.front();
  const BodyInterface& i0 = bodies[b0].interface;
  const Vec3 c = x[b0].row(i0.surface_node[i0.triangles(t0, 0)]).transpose();
  double v = 0.0;
  for (const auto& [b, t] : cav.triangles) {
    const BodyInterface& bi = bodies[b].interface;
    Vec3 p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = x[b].row(bi.surface_node[bi.triangles(t, k)]).transpose() - c;
    v -= p[0].dot(p[1].cross(p[2]));
  }
  return v / 6.0;
}

}  // namespace

CoupledSolution solve_coupled(const CoupledInput& in, const CoupledOptions& opt) {
  TETFSI_CHECK(in.mesh && in.u_star && in.rho && in.p_open && in.bodies,
               "solve_coupled: missing input");
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  const Index nt = m.num_tets(), nf = m.num_faces();
  const double h = in.h;
  TETFSI_REQUIRE(InputError, std::isfinite(h) && h > 0, "coupled solve: dt must be > 0, got {}", h);
  TETFSI_REQUIRE(InputError,
                 in.u_star->size() == nf && in.rho->size() == nt && in.p_open->size() == nf,
                 "coupled solve: v* has {} of {} faces, rho {} of {} cells, p_open {} of {} faces",
                 in.u_star->size(), nf, in.rho->size(), nt, in.p_open->size(), nf);
  CoupledSolution sol;
  CoupledReport& rep = sol.report;
  rep.backend = to_string(opt.solver);
  double t0 = now_seconds();

  // ---- solid DOFs: the free bodies stacked --------------------------------------------------
  const Index nb = static_cast<Index>(bodies.size());
  std::vector<Index> dof0(nb + 1, 0);
  std::vector<BodyInterface> ifaces;
  for (Index b = 0; b < nb; ++b) {
    const CoupledBody& cb = bodies[b];
    ifaces.push_back(cb.interface);
    const Index n3 = 3 * cb.interface.num_nodes;
    if (cb.free) {
      TETFSI_REQUIRE(
          InputError,
          cb.A.rows() == n3 && cb.A.cols() == n3 && cb.b.size() == n3 &&
              static_cast<Index>(cb.fixed.size()) == n3 && cb.x.rows() == n3 / 3 &&
              cb.u.size() == n3,
          "coupled solve: body {} has {} DOFs but A is {} x {}, b {}, fixed {}, x {}, u {}", b, n3,
          cb.A.rows(), cb.A.cols(), cb.b.size(), cb.fixed.size(), cb.x.rows(), cb.u.size());
    }
    dof0[b + 1] = dof0[b] + (cb.free ? n3 : 0);
  }
  const Index ns = dof0[nb];
  rep.solid_unknowns = ns;

  // ---- fluid: groups, regions ----------------------------------------------------------------
  const VecX d_eff = fluid::effective_dual_lengths(m, opt.min_dual_fraction);
  const fluid::PressureGroups groups = fluid::pressure_groups(m, opt.min_dual_fraction);
  fluid::Regions regions = fluid::fluid_regions(m);
  const Index ng = groups.count, nr = regions.count();
  rep.pressure_unknowns = ng;
  VecX gvol = VecX::Zero(ng), grho = VecX::Zero(ng);
  VecXi greg = VecXi::Zero(ng);
  for (Index t = 0; t < nt; ++t) {
    const Index g = groups.cell_group[t];
    gvol[g] += m.volumes[t];
    grho[g] = (*in.rho)[t];
    greg[g] = regions.cell_region[t];
  }
  VecX rvol = VecX::Zero(nr);
  for (Index g = 0; g < ng; ++g) rvol[greg[g]] += gvol[g];

  // J between free DOFs and groups; H rows for the faces of free bodies; which regions a free
  // body lifts; which regions are enclosed (only Solid faces of free bodies).
  const std::vector<InterfaceFace> iface = interface_faces(m, ifaces);
  const std::vector<Index> noff = node_offsets(ifaces);
  std::vector<bool> lifted(nr, false), enclosed(nr, true);
  for (Index f = 0; f < nf; ++f) {
    if (!m.is_boundary(f)) continue;
    const bool free_solid = m.face_kind[f] == FaceKind::Solid && bodies[m.face_body[f]].free;
    if (!free_solid) enclosed[regions.cell_region[m.face_tets(f, 0)]] = false;
  }
  Triplets jt;
  // Free DOF of stacked node `node`, component d, or −1 (fixed / not free).
  auto free_dof = [&](Index node, int d) -> Index {
    const Index b =
        static_cast<Index>(std::upper_bound(noff.begin(), noff.end(), node) - noff.begin()) - 1;
    if (!bodies[b].free) return -1;
    const Index local = 3 * (node - noff[b]) + d;
    if (bodies[b].fixed[local]) return -1;
    return dof0[b] + local;
  };
  VecX hydro = VecX::Zero(ns);                   // the hydrostatic pressure's nodal forces
  VecX r_prescribed = VecX::Zero(groups.count);  // flux of prescribed nonzero velocities
  auto prescribed = [&](Index node, int d) -> double {
    const Index b =
        static_cast<Index>(std::upper_bound(noff.begin(), noff.end(), node) - noff.begin()) - 1;
    const CoupledBody& cb = bodies[b];
    const Index local = 3 * (node - noff[b]) + d;
    return cb.free && cb.fixed[local] && cb.prescribed.size() ? cb.prescribed[local] : 0.0;
  };
  const bool liquid = in.gravity.squaredNorm() > 0;
  for (const InterfaceFace& i : iface) {
    const Index f = i.face, t = m.face_tets(f, 0);
    if (!bodies[m.face_body[f]].free) continue;
    const Index g = groups.cell_group[t];
    const Vec3 n = m.face_normals.row(f).transpose();
    const double ph =
        liquid ? fluid::hydrostatic_pressure((*in.rho)[t], in.gravity, in.hydrostatic_origin,
                                             m.face_centroids.row(f).transpose())
               : 0.0;
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) {
        const Index dof = free_dof(i.node[k], d);
        const double w = i.weight[k] * m.face_areas[f] * n[d];
        if (dof < 0) {
          r_prescribed[g] += w * prescribed(i.node[k], d);  // Jᵀ u of the known part
          continue;
        }
        if (w == 0.0) continue;
        jt.emplace_back(dof, g, w);  // force on node a: w_a A_f p n_f [DESIGN.md §3]
        hydro[dof] += w * ph;
        lifted[regions.cell_region[t]] = true;
      }
  }
  SparseMatrix J(ns, ng);
  J.setFromTriplets(jt.begin(), jt.end());
  const SparseMatrix Jt = J.transpose();

  // ---- the pressure block C = diag(h/ρ_g) L, pins only where nothing fixes the level --------
  fluid::Regions pin_regions = regions;
  for (Index r = 0; r < nr; ++r) pin_regions.has_open[r] = regions.has_open[r] || lifted[r];
  SparseMatrix C = fluid::pressure_matrix(m, d_eff, groups, pin_regions);
  const VecX gs = VecX::Constant(ng, h).cwiseQuotient(grho);  // h/ρ per group
  C = gs.asDiagonal() * C;

  // ---- right-hand sides ------------------------------------------------------------------------
  // Second block row: r = V D2 v* − (h/ρ) Σ_open (A/d̃) p_open, v* without the faces of free
  // bodies (their velocity is H u, the unknown).
  VecX v0 = *in.u_star;
  for (Index f = 0; f < nf; ++f)
    if (m.face_kind[f] == FaceKind::Solid && bodies[m.face_body[f]].free) v0[f] = 0.0;
  const VecX flux = fluid::net_flux(m, v0);
  rep.divergence_before =
      nt ? fluid::net_flux(m, *in.u_star).cwiseQuotient(m.volumes).cwiseAbs().maxCoeff() : 0.0;
  VecX r = r_prescribed;  // −J_freeᵀ u − C p = V D2 v* + J_prescribedᵀ v − ...
  for (Index t = 0; t < nt; ++t) r[groups.cell_group[t]] += flux[t];
  for (Index f = 0; f < nf; ++f)
    if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open) {
      const Index g = groups.cell_group[m.face_tets(f, 0)];
      r[g] -= gs[g] * m.face_areas[f] / d_eff[f] * (*in.p_open)[f];
    }
  {  // pinned regions: remove the net flux they cannot absorb (fluid::project)
    std::vector<double> sum(nr, 0.0), abs_sum(nr, 0.0);
    for (Index g = 0; g < ng; ++g) {
      sum[greg[g]] += r[g];
      abs_sum[greg[g]] += std::abs(r[g]);
    }
    for (Index k = 0; k < nr; ++k) {
      if (pin_regions.has_open[k]) continue;
      ++rep.pinned_regions;
      if (abs_sum[k] > 0)
        rep.incompatibility = std::max(rep.incompatibility, std::abs(sum[k]) / abs_sum[k]);
    }
    for (Index g = 0; g < ng; ++g)
      if (!pin_regions.has_open[greg[g]]) r[g] -= sum[greg[g]] * gvol[g] / rvol[greg[g]];
  }
  VecX bs(ns);
  for (Index b = 0; b < nb; ++b)
    if (bodies[b].free) bs.segment(dof0[b], dof0[b + 1] - dof0[b]) = bodies[b].b;
  bs += hydro;

  // Enclosed regions: unit-flux right-hand sides and their cavities.
  std::vector<Index> enc;  // region ids
  std::vector<Cavity> cavities;
  if (opt.conserve_volume && in.volume_targets) {
    std::vector<Index> slot(nr, -1);
    for (Index k = 0; k < nr; ++k)
      if (enclosed[k] && lifted[k] && !regions.has_open[k]) {
        slot[k] = static_cast<Index>(enc.size());
        enc.push_back(k);
      }
    cavities.resize(enc.size());
    for (Index f = 0; f < nf; ++f) {
      if (m.face_kind[f] != FaceKind::Solid) continue;
      const Index k = slot[regions.cell_region[m.face_tets(f, 0)]];
      if (k < 0) continue;
      cavities[k].triangles.emplace_back(m.face_body[f], m.face_triangle[f]);
    }
    for (Cavity& c : cavities) {  // a body triangle is split into several faces: once each
      std::sort(c.triangles.begin(), c.triangles.end());
      c.triangles.erase(std::unique(c.triangles.begin(), c.triangles.end()), c.triangles.end());
    }
  }
  const Index ne = static_cast<Index>(enc.size());
  rep.assembly_s = now_seconds() - t0;

  // ---- solve: K [u; p] = [b; R2] for R2 = r (and −s_unit per enclosed region) ------------------
  // Right-hand sides of the second block row: column 0 the step's, column 1 + k region k's.
  std::vector<VecX> R2(1 + ne);
  R2[0] = r;  // K's second block row reads −Jᵀu − C p = R2, R2 = r − s
  for (Index k = 0; k < ne; ++k) {
    R2[1 + k] = VecX::Zero(ng);
    for (Index g = 0; g < ng; ++g)
      if (greg[g] == enc[k]) R2[1 + k][g] = -gvol[g] / rvol[enc[k]];
  }
  // Solutions per right-hand side: u, and p = Z Pa + P (Z: the coarse space of the Schur
  // solver below, whose region constants can be far larger than the rest; empty otherwise).
  std::vector<VecX> U(1 + ne), P(1 + ne), Pa(1 + ne);
  Eigen::MatrixXd Z;
  auto merge = [&](const SolveReport& s) {
    rep.iterations += s.iterations;
    rep.residual = std::max(rep.residual, s.residual);
    rep.converged = rep.converged && s.converged;
    rep.solve_s += s.solve_s;
  };
  rep.converged = true;
  // The assembled system (paper or symmetric form) with a general sparse solver.
  auto solve_direct = [&](CoupledSolverKind which) {
    t0 = now_seconds();
    const bool paper = which != CoupledSolverKind::SymmetricUmfpack;
    // Rows of the second block: −Jᵀ u − C p (symmetric), scaled by 1/V_g (paper form).
    const VecX rowscale = paper ? VecX(gvol.cwiseInverse()) : VecX(VecX::Ones(ng));
    Triplets kt;
    for (Index b = 0; b < nb; ++b) {
      if (!bodies[b].free) continue;
      const SparseMatrix& A = bodies[b].A;
      for (Index c = 0; c < A.outerSize(); ++c)
        for (SparseMatrix::InnerIterator it(A, c); it; ++it)
          kt.emplace_back(dof0[b] + it.row(), dof0[b] + it.col(), it.value());
    }
    for (Index c = 0; c < J.outerSize(); ++c)
      for (SparseMatrix::InnerIterator it(J, c); it; ++it) {
        kt.emplace_back(it.row(), ns + it.col(), -it.value());
        kt.emplace_back(ns + it.col(), it.row(), -it.value() * rowscale[it.col()]);
      }
    for (Index c = 0; c < C.outerSize(); ++c)
      for (SparseMatrix::InnerIterator it(C, c); it; ++it)
        kt.emplace_back(ns + it.row(), ns + it.col(), -it.value() * rowscale[it.row()]);
    SparseMatrix K(ns + ng, ns + ng);
    K.setFromTriplets(kt.begin(), kt.end());
    SolverOptions so;
    so.rel_tol = opt.rel_tol;
    so.max_iterations = opt.max_iterations;
    so.symmetric = !paper;
    const SolverKind kind =
        which == CoupledSolverKind::BiCgStabIlut ? SolverKind::BiCgStabIlut : SolverKind::Umfpack;
    auto solver = make_linear_solver(kind, so);
    solver->setup(K);
    rep.setup_s = now_seconds() - t0;
    for (Index k = 0; k <= ne; ++k) {
      VecX rhs(ns + ng);
      rhs.head(ns) = k == 0 ? bs : VecX(VecX::Zero(ns));
      rhs.tail(ng) = R2[k].cwiseProduct(rowscale);
      VecX x = VecX::Zero(ns + ng);
      merge(solver->solve(rhs, x));
      U[k] = x.head(ns);
      P[k] = x.tail(ng);
    }
  };
  bool breakdown = false;  // the Schur CG met dᵀ S d ≤ 0 (a body's A is indefinite)
  if (opt.solver == CoupledSolverKind::SchurAmg) {
    t0 = now_seconds();
    std::vector<std::unique_ptr<LinearSolver>> fac(nb);
    VecX dinv = VecX::Zero(ns);
    for (Index b = 0; b < nb; ++b) {
      if (!bodies[b].free) continue;
      fac[b] = factor_symmetric(bodies[b].A);
      // diag(A)⁻¹ in P: measured 37 CG iterations per step on a water-filled shell, 55 with
      // h M⁻¹ (the rigid-body response) instead.
      dinv.segment(dof0[b], dof0[b + 1] - dof0[b]) = bodies[b].A.diagonal().cwiseInverse();
    }
    auto solve_A = [&](const VecX& rhs, VecX& x) {
      x.resize(ns);
      for (Index b = 0; b < nb; ++b) {
        if (!bodies[b].free) continue;
        const Index n = dof0[b + 1] - dof0[b];
        VecX xb = VecX::Zero(n);
        fac[b]->solve(rhs.segment(dof0[b], n), xb);
        x.segment(dof0[b], n) = xb;
      }
    };
    const SparseMatrix Pm = C + SparseMatrix(Jt * dinv.asDiagonal() * J);
    VecX tmp_u, tmp_f;
    auto S = [&](const VecX& x, VecX& y) {
      y = C * x;
      if (ns > 0) {
        tmp_f = J * x;
        solve_A(tmp_f, tmp_u);
        y += Jt * tmp_u;
      }
    };
    std::unique_ptr<AmgPreconditioner> own_amg;
    AmgPreconditioner* amg = nullptr;
    if (opt.reuse && opt.reuse->amg && opt.reuse->size == ng) {
      amg = opt.reuse->amg.get();  // the caller vouches that P is the same
      ++opt.reuse->reused;
    } else {
      own_amg = make_amg_preconditioner();
      own_amg->setup(Pm);
      amg = own_amg.get();
      if (opt.reuse) {
        opt.reuse->amg = std::move(own_amg);
        opt.reuse->size = ng;
      }
    }
    // Coarse space: the constant of every region that only the bodies' elasticity holds
    // (no Open face). S is nearly singular there (a stiff body barely lifts it), which stalls
    // a plain preconditioned CG; the balancing preconditioner
    //   B = (I − Z E⁻¹ (SZ)ᵀ) M (I − SZ E⁻¹ Zᵀ) + Z E⁻¹ Zᵀ,  E = Zᵀ S Z, M the AMG V-cycle,
    // solves that space exactly and stays SPD. Iterates are kept as x = Z a + y: the region
    // constants a can exceed y by many orders (1/λ_min), and S Z = Jᵀ A⁻¹ J Z exactly (C Z = 0
    // in theory, rounding noise times a in practice).
    std::vector<Index> zreg;
    for (Index k = 0; k < nr; ++k)
      if (lifted[k] && !regions.has_open[k]) zreg.push_back(k);
    const Index nz = static_cast<Index>(zreg.size());
    Z = Eigen::MatrixXd::Zero(ng, nz);
    Eigen::MatrixXd SZ(ng, nz), JZ(ns, nz);
    for (Index j = 0; j < nz; ++j)
      for (Index g = 0; g < ng; ++g)
        if (greg[g] == zreg[j]) Z(g, j) = 1.0;
    for (Index j = 0; j < nz; ++j) {
      JZ.col(j) = J * Z.col(j);
      VecX au;
      solve_A(JZ.col(j), au);
      SZ.col(j) = Jt * au;
    }
    const Eigen::MatrixXd E = Z.transpose() * SZ;
    const Eigen::LDLT<Eigen::MatrixXd> Einv(E);
    // z = Z za + zy = B r
    auto precondition = [&](const VecX& r, VecX& za, VecX& zy) {
      if (nz == 0) {
        amg->apply(r, zy);
        za = VecX();
        return;
      }
      const VecX r1 = r - SZ * Einv.solve(Z.transpose() * r);
      amg->apply(r1, zy);
      za = Einv.solve(Z.transpose() * r - SZ.transpose() * zy);
    };
    auto S2 = [&](const VecX& a, const VecX& y, VecX& out) {  // S (Z a + y)
      S(y, out);
      if (nz) out += SZ * a;
    };
    rep.setup_s = now_seconds() - t0;
    // Preconditioned CG on S x = rhs, stopped on the true residual.
    auto pcg = [&](const VecX& rhs, VecX& xa, VecX& xy) {
      SolveReport sr{"schur_amg", false, 0, 0.0, 0.0, 0.0};
      const double t1 = now_seconds();
      const double bn = rhs.norm();
      xy = VecX::Zero(ng);
      xa = nz ? VecX(Einv.solve(Z.transpose() * rhs)) : VecX();
      if (bn == 0.0) {
        if (nz) xa.setZero();
        sr.converged = true;
        return sr;
      }
      VecX r, q, za, zy, da, dy;
      S2(xa, xy, q);
      r = rhs - q;
      for (int restart = 0; restart < 4; ++restart) {
        precondition(r, za, zy);
        da = za;
        dy = zy;
        auto dot_z = [&](const VecX& v, const VecX& a, const VecX& y) {
          return v.dot(y) + (nz ? (Z.transpose() * v).dot(a) : 0.0);
        };
        double rz = dot_z(r, za, zy);
        while (sr.iterations < opt.max_iterations && r.norm() > opt.rel_tol * bn) {
          S2(da, dy, q);
          const double dq = dot_z(q, da, dy);
          if (!(dq > 0)) {  // breakdown: S not positive definite along d
            breakdown = true;
            logger().debug("coupled solve: CG breakdown after {} iterations (d^T S d = {:.3g})",
                           sr.iterations, dq);
            break;
          }
          const double alpha = rz / dq;
          xy += alpha * dy;
          if (nz) xa += alpha * da;
          r -= alpha * q;
          ++sr.iterations;
          precondition(r, za, zy);
          const double rz1 = dot_z(r, za, zy);
          dy = zy + (rz1 / rz) * dy;
          if (nz) da = za + (rz1 / rz) * da;
          rz = rz1;
        }
        S2(xa, xy, q);
        r = rhs - q;  // the true residual
        sr.residual = r.norm() / bn;
        if (sr.residual <= opt.rel_tol || sr.iterations >= opt.max_iterations) break;
      }
      sr.converged = sr.residual <= opt.rel_tol;
      sr.solve_s = now_seconds() - t1;
      return sr;
    };
    VecX Ab;
    if (ns > 0) solve_A(bs, Ab);
    for (Index k = 0; k <= ne; ++k) {
      // S p = −R2 − Jᵀ A⁻¹ b (b only for the step's column), u = A⁻¹ (b + J p)
      VecX rhs = -R2[k];
      if (k == 0 && ns > 0) rhs -= Jt * Ab;
      VecX pa, py;
      merge(pcg(rhs, pa, py));
      VecX u;
      if (ns > 0) {
        VecX f = (k == 0 ? bs : VecX(VecX::Zero(ns))) + J * py;
        if (nz) f += JZ * pa;
        solve_A(f, u);
      }
      U[k] = u;
      P[k] = py;
      Pa[k] = pa;
    }
    if (breakdown) {
      // S is not positive definite: a body's A = M/h + C + (h/2) K' is indefinite (StVK under
      // strong compression, or a soft body under a large pressure whose follower stiffness the
      // linearisation leaves out). LU of the symmetric form still solves the step.
      logger().warn(
          "coupled solve: the Schur complement is not positive definite (a body's "
          "stiffness is indefinite); this step is solved by LU (symmetric_umfpack)");
      rep.backend = "schur_amg+symmetric_umfpack";
      rep.iterations = 0;
      rep.residual = 0.0;
      rep.converged = true;
      for (auto& v : Pa) v = VecX();
      solve_direct(CoupledSolverKind::SymmetricUmfpack);
    }
  } else {
    solve_direct(opt.solver);
  }
  for (Index k = 0; k <= ne; ++k)
    TETFSI_REQUIRE(SolverError, U[k].allFinite() && P[k].allFinite(),
                   "coupled solve ({}) returned non-finite values after {} iterations; reduce "
                   "time.dt",
                   rep.backend, rep.iterations);
  if (!rep.converged)
    logger().warn("coupled solve ({}) did not converge: {} iterations, residual {:.3g}",
                  rep.backend, rep.iterations, rep.residual);

  // ---- enclosed volumes: Newton on c per region (Gauss–Seidel over regions) -----------------
  t0 = now_seconds();
  VecX c = VecX::Zero(ne);
  if (ne > 0) {
    std::vector<MatX3> xn(nb);
    for (Index b = 0; b < nb; ++b)
      if (bodies[b].free) xn[b] = bodies[b].x;
    // Node positions after Eq. (5) for the fluxes c.
    auto positions = [&](const VecX& cc) {
      std::vector<MatX3> x = xn;
      VecX u = U[0];
      for (Index k = 0; k < ne; ++k) u += cc[k] * U[1 + k];
      for (Index b = 0; b < nb; ++b) {
        if (!bodies[b].free) continue;
        const Index n = bodies[b].interface.num_nodes;
        for (Index i = 0; i < n; ++i)
          for (int d = 0; d < 3; ++d) {
            const Index l = 3 * i + d;
            const double un1 = bodies[b].fixed[l]
                                   ? (bodies[b].prescribed.size() ? bodies[b].prescribed[l] : 0.0)
                                   : u[dof0[b] + l];
            x[b](i, d) += 0.5 * h * (bodies[b].u[l] + un1);  // [Chentanez06, Eq. (5)]
          }
      }
      return x;
    };
    std::vector<double> target(ne);
    for (Index k = 0; k < ne; ++k) {
      EnclosedRegion er;
      er.key = std::int64_t(cavities[k].triangles.front().first) << 32 |
               std::int64_t(cavities[k].triangles.front().second);
      er.volume = cavity_volume(cavities[k], bodies, xn);
      auto [it, inserted] = in.volume_targets->emplace(er.key, er.volume);
      er.target = it->second;
      for (Index t = 0; t < nt; ++t)
        if (regions.cell_region[t] == enc[k]) ++er.cells;
      target[k] = er.target;
      rep.enclosed.push_back(er);
    }
    for (int sweep = 0; sweep < 8; ++sweep) {
      double worst = 0.0;
      for (Index k = 0; k < ne; ++k) {
        for (int it = 0; it < 6; ++it) {
          const double v = cavity_volume(cavities[k], bodies, positions(c)) - target[k];
          const double eps = std::max(1e-12, 1e-6 * std::abs(target[k]) / h);
          VecX cp = c, cm = c;
          cp[k] += eps;
          cm[k] -= eps;
          const double dv = (cavity_volume(cavities[k], bodies, positions(cp)) -
                             cavity_volume(cavities[k], bodies, positions(cm))) /
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
      rep.enclosed[k].after = cavity_volume(cavities[k], bodies, x1);
      rep.enclosed[k].flux = c[k];
    }
  }
  VecX u = U[0], pg = P[0];
  VecX pa = Pa[0];
  for (Index k = 0; k < ne; ++k) {
    u += c[k] * U[1 + k];
    pg += c[k] * P[1 + k];
    if (pa.size()) pa += c[k] * Pa[1 + k];
  }
  if (pa.size()) pg += Z * pa;

  // ---- results ----------------------------------------------------------------------------------
  sol.p.resize(nt);
  for (Index t = 0; t < nt; ++t) sol.p[t] = pg[groups.cell_group[t]];
  sol.u.assign(nb, VecX());
  for (Index b = 0; b < nb; ++b) {
    if (!bodies[b].free) continue;
    VecX ub = u.segment(dof0[b], dof0[b + 1] - dof0[b]);
    for (Index l = 0; l < ub.size(); ++l)
      if (bodies[b].fixed[l]) ub[l] = bodies[b].prescribed.size() ? bodies[b].prescribed[l] : 0.0;
    sol.u[b] = ub;
  }
  rep.interface_power = ns > 0 ? (J * pg).dot(u) : 0.0;
  // Eq. (8): v* − (h/ρ) G p on interior and Open faces, (H u)_f on the faces of free bodies.
  sol.u_face = *in.u_star;
  for (const InterfaceFace& i : iface) {
    const Index f = i.face, b = m.face_body[f];
    if (!bodies[b].free) continue;
    Vec3 v = Vec3::Zero();
    for (int k = 0; k < 3; ++k) v += i.weight[k] * sol.u[b].segment<3>(3 * (i.node[k] - noff[b]));
    sol.u_face[f] = m.face_normals.row(f).dot(v.transpose());
  }
  VecX q(nt), source = VecX::Zero(nt);
  for (Index t = 0; t < nt; ++t) q[t] = sol.p[t] * h / (*in.rho)[t];
  for (Index k = 0; k < ne; ++k)
    for (Index t = 0; t < nt; ++t)
      if (regions.cell_region[t] == enc[k]) source[t] = c[k] * m.volumes[t] / rvol[enc[k]];
  VecX q_open = VecX::Zero(nf);
  for (Index f = 0; f < nf; ++f)
    if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open)
      q_open[f] = (*in.p_open)[f] * h / (*in.rho)[m.face_tets(f, 0)];
  fluid::apply_pressure_gradient(m, d_eff, groups, q, q_open, sol.u_face, ne ? &source : nullptr);
  rep.divergence_after =
      nt ? (fluid::net_flux(m, sol.u_face) - source).cwiseQuotient(m.volumes).cwiseAbs().maxCoeff()
         : 0.0;
  // The fluid's forces on every body (J p + hydrostatic), for reports and time splitting.
  sol.fluid_force = fluid_forces(m, ifaces, sol.p, *in.rho, in.gravity, in.hydrostatic_origin);
  rep.assembly_s += now_seconds() - t0;
  return sol;
}

}  // namespace tetfsi::coupling
