/// @file coupled_assembly.cpp
/// assemble_coupled: the simultaneous system of one step on the tet fluid
/// [Chentanez06, Eq. (7)] in its symmetric form (coupled_system.hpp).
#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/timer.hpp"
#include "coupling/coupled_system.hpp"
#include "fluid/tet/operators.hpp"

namespace tetfsi::coupling {

using mesh::FaceKind;
using mesh::TetMesh;

namespace {

/// Sizes of the input; the free bodies' DOFs stacked (sys.dof0, ns).
void stack_free_dofs(const CoupledInput& in, CoupledSystem& sys) {
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  const Index nt = m.num_tets(), nf = m.num_faces();
  TETFSI_REQUIRE(InputError, std::isfinite(in.h) && in.h > 0,
                 "coupled solve: dt must be > 0, got {}", in.h);
  TETFSI_REQUIRE(InputError,
                 in.u_star->size() == nf && in.rho->size() == nt && in.p_open->size() == nf,
                 "coupled solve: v* has {} of {} faces, rho {} of {} cells, p_open {} of {} faces",
                 in.u_star->size(), nf, in.rho->size(), nt, in.p_open->size(), nf);
  TETFSI_REQUIRE(InputError,
                 &in.interface->mesh() == in.mesh && in.interface->bodies().size() == bodies.size(),
                 "coupled solve: the interface operators have {} bodies for {} (or another mesh)",
                 in.interface->bodies().size(), bodies.size());
  sys.nb = static_cast<Index>(bodies.size());
  sys.dof0.assign(sys.nb + 1, 0);
  for (Index b = 0; b < sys.nb; ++b) {
    const CoupledBody& cb = bodies[b];
    const Index n3 = 3 * in.interface->bodies()[b].num_nodes;
    if (cb.free) {
      TETFSI_REQUIRE(
          InputError,
          cb.A.rows() == n3 && cb.A.cols() == n3 && cb.b.size() == n3 &&
              static_cast<Index>(cb.fixed.size()) == n3 && cb.x.rows() == n3 / 3 &&
              cb.u.size() == n3,
          "coupled solve: body {} has {} DOFs but A is {} x {}, b {}, fixed {}, x {}, u {}", b, n3,
          cb.A.rows(), cb.A.cols(), cb.b.size(), cb.fixed.size(), cb.x.rows(), cb.u.size());
    }
    sys.dof0[b + 1] = sys.dof0[b] + (cb.free ? n3 : 0);
  }
  sys.ns = sys.dof0[sys.nb];
}

/// Pressure groups, regions, their volumes and densities.
void group_cells(const CoupledInput& in, const CoupledOptions& opt, CoupledSystem& sys) {
  const TetMesh& m = *in.mesh;
  sys.d_eff = fluid::effective_dual_lengths(m, opt.min_dual_fraction);
  sys.groups = fluid::pressure_groups(m, opt.min_dual_fraction);
  sys.regions = fluid::fluid_regions(m);
  sys.ng = sys.groups.count;
  sys.nr = sys.regions.count();
  sys.gvol = VecX::Zero(sys.ng);
  sys.grho = VecX::Zero(sys.ng);
  sys.greg = VecXi::Zero(sys.ng);
  for (Index t = 0; t < m.num_tets(); ++t) {
    const Index g = sys.groups.cell_group[t];
    sys.gvol[g] += m.volumes[t];
    sys.grho[g] = (*in.rho)[t];
    sys.greg[g] = sys.regions.cell_region[t];
  }
  sys.rvol = VecX::Zero(sys.nr);
  for (Index g = 0; g < sys.ng; ++g) sys.rvol[sys.greg[g]] += sys.gvol[g];
}

/// J between free DOFs and groups (J's entries of fluid::InterfaceOperators, columns summed
/// per group), the hydrostatic nodal forces, the flux of prescribed nonzero velocities, and
/// which regions a free body lifts.
void assemble_J(const CoupledInput& in, CoupledSystem& sys, VecX& hydro, VecX& r_prescribed) {
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  sys.lifted.assign(sys.nr, false);
  hydro = VecX::Zero(sys.ns);
  r_prescribed = VecX::Zero(sys.ng);
  const bool liquid = in.gravity.squaredNorm() > 0;
  Triplets jt;
  Index last_face = -1;
  double ph = 0.0;  // the hydrostatic pressure at the face centroid
  in.interface->for_each_J_entry([&](Index f, Index t, Index b, Index l, Index, double w) {
    const CoupledBody& cb = bodies[b];
    if (!cb.free) return;
    const Index g = sys.groups.cell_group[t];
    if (f != last_face) {
      last_face = f;
      ph = liquid ? fluid::hydrostatic_pressure((*in.rho)[t], in.gravity, in.hydrostatic_origin,
                                                m.face_centroids.row(f).transpose())
                  : 0.0;
    }
    if (cb.fixed[l]) {
      r_prescribed[g] += w * (cb.prescribed.size() ? cb.prescribed[l] : 0.0);  // Jᵀ u, known
      return;
    }
    if (w == 0.0) return;
    const Index dof = sys.dof0[b] + l;
    jt.emplace_back(dof, g, w);
    hydro[dof] += w * ph;
    sys.lifted[sys.regions.cell_region[t]] = true;
  });
  sys.J = SparseMatrix(sys.ns, sys.ng);
  sys.J.setFromTriplets(jt.begin(), jt.end());
  sys.Jt = sys.J.transpose();
}

/// The interface half cells' mass (coupled_system.hpp): sys.half_mass, sys.A per free body
/// with M_I/h added, and M_I u⁰/h (u⁰ = in.u_ref on the Solid faces) added to `forces`; the
/// DOFs a body fixes keep their eliminated rows and move their columns into `forces`.
void add_interface_mass(const CoupledInput& in, CoupledSystem& sys, VecX& forces) {
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  const VecX& u_ref = in.half_cell_u0();
  const VecX* delta = in.half_cell_lengths;
  TETFSI_REQUIRE(InputError, !delta || delta->size() == m.num_faces(),
                 "coupled solve: half-cell lengths for {} of {} faces", delta ? delta->size() : 0,
                 m.num_faces());
  sys.half_mass = VecX::Zero(m.num_faces());
  for (Index f = 0; f < m.num_faces(); ++f)  // (a face of zero area has no half cell)
    if (m.face_kind[f] == FaceKind::Solid && m.face_areas[f] > 0)
      sys.half_mass[f] = (*in.rho)[m.face_tets(f, 0)] *
                         (delta ? (*delta)[f] : std::max(m.dual_lengths[f], 0.0)) / m.face_areas[f];
  std::vector<Triplets> added(sys.nb);
  struct Entry {
    Index body, l;
    double w;
  };
  std::vector<Entry> face;  // the J entries of one face: 3 nodes × 3 components
  Index last = -1;
  const auto flush = [&] {
    if (face.empty()) return;
    const double c = sys.half_mass[last] / in.h;
    for (const Entry& i : face) {
      const CoupledBody& cb = bodies[i.body];
      if (!cb.free || cb.fixed[i.l]) continue;
      const Index dof = sys.dof0[i.body] + i.l;
      forces[dof] += c * i.w * m.face_areas[last] * u_ref[last];
      for (const Entry& j : face) {
        const double a = c * i.w * j.w;
        if (!cb.fixed[j.l])
          added[i.body].emplace_back(i.l, j.l, a);
        else if (cb.prescribed.size())
          forces[dof] -= a * cb.prescribed[j.l];
      }
    }
    face.clear();
  };
  in.interface->for_each_J_entry([&](Index f, Index, Index b, Index l, Index, double w) {
    if (f != last) flush();
    last = f;
    if (w != 0.0) face.push_back({b, l, w});
  });
  flush();
  sys.A.assign(sys.nb, SparseMatrix());
  for (Index b = 0; b < sys.nb; ++b) {
    if (!bodies[b].free) continue;
    SparseMatrix MI(bodies[b].A.rows(), bodies[b].A.cols());
    MI.setFromTriplets(added[b].begin(), added[b].end());
    sys.A[b] = bodies[b].A + MI;
  }
}

/// The step's second block row r = V D2 v* − (h/ρ) Σ_open (A/d̃) p_open (v* without the
/// faces of free bodies: their velocity is H u, the unknown), the net flux of pinned regions
/// removed (fluid::project).
VecX second_row(const CoupledInput& in, CoupledSystem& sys, const VecX& r_prescribed,
                CoupledReport& rep) {
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  const Index nt = m.num_tets(), nf = m.num_faces();
  VecX v0 = *in.u_star;
  for (Index f = 0; f < nf; ++f)
    if (m.face_kind[f] == FaceKind::Solid && bodies[m.face_body[f]].free) v0[f] = 0.0;
  const VecX flux = fluid::net_flux(m, v0);
  rep.divergence_before =
      nt ? fluid::net_flux(m, *in.u_star).cwiseQuotient(m.volumes).cwiseAbs().maxCoeff() : 0.0;
  std::vector<OpenFaceTerm> open;
  for (Index f = 0; f < nf; ++f)
    if (m.is_boundary(f) && m.face_kind[f] == FaceKind::Open)
      open.push_back({sys.groups.cell_group[m.face_tets(f, 0)], m.face_areas[f], sys.d_eff[f],
                      (*in.p_open)[f]});
  return second_row_rhs(sys, r_prescribed, flux, sys.groups.cell_group, open, rep);
}

/// Enclosed regions (only Solid faces of free bodies, lifted, no Open face) and their
/// cavities, when the volume correction is on.
void find_enclosed(const CoupledInput& in, const CoupledOptions& opt, CoupledSystem& sys) {
  const TetMesh& m = *in.mesh;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  if (!(opt.conserve_volume && in.volume_targets)) return;
  std::vector<bool> enclosed(sys.nr, true);
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (!m.is_boundary(f)) continue;
    const bool free_solid = m.face_kind[f] == FaceKind::Solid && bodies[m.face_body[f]].free;
    if (!free_solid) enclosed[sys.regions.cell_region[m.face_tets(f, 0)]] = false;
  }
  std::vector<Index> slot(sys.nr, -1);
  for (Index k = 0; k < sys.nr; ++k)
    if (enclosed[k] && sys.lifted[k] && !sys.regions.has_open[k]) {
      slot[k] = static_cast<Index>(sys.enclosed.size());
      sys.enclosed.push_back(k);
    }
  sys.cavities.resize(sys.enclosed.size());
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.face_kind[f] != FaceKind::Solid) continue;
    const Index k = slot[sys.regions.cell_region[m.face_tets(f, 0)]];
    if (k < 0) continue;
    sys.cavities[k].triangles.emplace_back(m.face_body[f], m.face_triangle[f]);
  }
  for (Cavity& c : sys.cavities) {  // a body triangle is split into several faces: once each
    std::sort(c.triangles.begin(), c.triangles.end());
    c.triangles.erase(std::unique(c.triangles.begin(), c.triangles.end()), c.triangles.end());
  }
}

}  // namespace

CoupledSystem assemble_coupled(const CoupledInput& in, const CoupledOptions& opt,
                               CoupledReport& rep) {
  TETFSI_CHECK(in.mesh && in.u_star && in.rho && in.p_open && in.bodies && in.interface,
               "solve_coupled: missing input");
  const double t0 = now_seconds();
  CoupledSystem sys;
  sys.in = &in;
  sys.bodies = in.bodies;
  sys.interfaces = &in.interface->bodies();
  sys.h = in.h;
  stack_free_dofs(in, sys);
  rep.solid_unknowns = sys.ns;
  group_cells(in, opt, sys);
  rep.pressure_unknowns = sys.ng;
  VecX hydro, r_prescribed;
  assemble_J(in, sys, hydro, r_prescribed);
  if (opt.interface_mass) add_interface_mass(in, sys, hydro);

  // [Chentanez06, Eq. (7)] in the symmetric form: A per body, J (above), and the pressure
  // block C = diag(h/ρ_g) L, pins only where nothing fixes the level
  sys.pin_regions = sys.regions;
  for (Index r = 0; r < sys.nr; ++r)
    sys.pin_regions.has_open[r] = sys.regions.has_open[r] || sys.lifted[r];
  sys.C = fluid::pressure_matrix(*in.mesh, sys.d_eff, sys.groups, sys.pin_regions);
  sys.gs = VecX::Constant(sys.ng, in.h).cwiseQuotient(sys.grho);  // h/ρ per group
  sys.C = sys.gs.asDiagonal() * sys.C;

  // the second block row's right-hand side, see [Chentanez06, Eq. (6)]
  VecX r = second_row(in, sys, r_prescribed, rep);
  find_enclosed(in, opt, sys);
  stack_right_hand_sides(sys, std::move(r), hydro);
  add_contact(sys, opt);
  rep.assembly_s = now_seconds() - t0;
  return sys;
}

void add_contact(CoupledSystem& sys, const CoupledOptions& opt) {
  if (!opt.contact || opt.contact->empty()) return;
  TETFSI_REQUIRE(InputError, opt.contact->A.rows() == sys.ns && opt.contact->b.size() == sys.ns,
                 "coupled solve: the contact system has {} DOFs for {} free DOFs",
                 opt.contact->A.rows(), sys.ns);
  sys.Ac = opt.contact->A;
  sys.bs += opt.contact->b;
}

VecX second_row_rhs(const CoupledSystem& sys, VecX r_prescribed, const VecX& cell_flux,
                    const VecXi& cell_group, const std::vector<OpenFaceTerm>& open,
                    CoupledReport& rep) {
  // [Chentanez06, Eq. (6)] times V: −J_freeᵀ u − C p = V D v* + J_prescribedᵀ v − ...
  VecX r = std::move(r_prescribed);
  for (Index c = 0; c < cell_flux.size(); ++c)
    if (cell_group[c] >= 0) r[cell_group[c]] += cell_flux[c];
  for (const OpenFaceTerm& o : open) r[o.group] -= sys.gs[o.group] * o.area / o.dual * o.p_open;
  remove_pinned_flux(sys, r, rep);
  return r;
}

void remove_pinned_flux(const CoupledSystem& sys, VecX& r, CoupledReport& rep) {
  const Index nr = sys.nr, ng = sys.ng;
  std::vector<double> sum(nr, 0.0), abs_sum(nr, 0.0);
  for (Index g = 0; g < ng; ++g) {
    sum[sys.greg[g]] += r[g];
    abs_sum[sys.greg[g]] += std::abs(r[g]);
  }
  for (Index k = 0; k < nr; ++k) {
    if (sys.pin_regions.has_open[k]) continue;
    ++rep.pinned_regions;
    if (abs_sum[k] > 0)
      rep.incompatibility = std::max(rep.incompatibility, std::abs(sum[k]) / abs_sum[k]);
  }
  for (Index g = 0; g < ng; ++g)
    if (!sys.pin_regions.has_open[sys.greg[g]])
      r[g] -= sum[sys.greg[g]] * sys.gvol[g] / sys.rvol[sys.greg[g]];
}

void stack_right_hand_sides(CoupledSystem& sys, VecX r, const VecX& hydro) {
  sys.bs = VecX(sys.ns);
  for (Index b = 0; b < sys.nb; ++b)
    if ((*sys.bodies)[b].free)
      sys.bs.segment(sys.dof0[b], sys.dof0[b + 1] - sys.dof0[b]) = (*sys.bodies)[b].b;
  sys.bs += hydro;
  // Right-hand sides of the second block row: column 0 the step's, column 1 + k region k's
  // unit net flux (K's second block row reads −Jᵀu − C p = R2, R2 = r − s).
  const Index ne = static_cast<Index>(sys.enclosed.size());
  sys.R2.assign(1 + ne, VecX());
  sys.R2[0] = std::move(r);
  for (Index k = 0; k < ne; ++k) {
    sys.R2[1 + k] = VecX::Zero(sys.ng);
    for (Index g = 0; g < sys.ng; ++g)
      if (sys.greg[g] == sys.enclosed[k])
        sys.R2[1 + k][g] = -sys.gvol[g] / sys.rvol[sys.enclosed[k]];
  }
}

}  // namespace tetfsi::coupling
