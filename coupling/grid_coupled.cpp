/// @file grid_coupled.cpp
/// The simultaneous solve on the MAC grid and the grid fluid behind the schemes' seam
/// (grid_coupled.hpp).
#include "coupling/grid_coupled.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "fluid/grid/projection.hpp"

namespace tetfsi::coupling {

using fluid::GridCells;
using mesh::FaceKind;

namespace {

/// The pressure unknowns, and where each stacked DOF (3N, GridInterface numbering) goes.
struct GridDofs {
  fluid::GridNumbering cells;
  std::vector<Index> free_dof;  ///< 3N → free DOF of the system, −1 if fixed or held
  VecX prescribed;              ///< 3N: the prescribed velocity of fixed DOFs of free bodies
  std::vector<std::uint8_t> fixed_free;  ///< 3N: 1 for fixed DOFs of free bodies
};

GridDofs stack_dofs(const GridCoupledInput& in, CoupledSystem& sys) {
  const GridCells& gc = *in.cells;
  const std::vector<CoupledBody>& bodies = *in.bodies;
  const fluid::GridInterface& gi = *in.interface;
  const Index nf = gc.grid.num_faces(), nc = gc.grid.num_cells(), n3 = gi.num_dofs();
  TETFSI_REQUIRE(InputError, std::isfinite(in.h) && in.h > 0,
                 "coupled solve: dt must be > 0, got {}", in.h);
  TETFSI_REQUIRE(InputError,
                 in.u_star->size() == nf && in.p_open->size() == nf && in.J->rows() == n3 &&
                     in.J->cols() == nc && in.Jc->rows() == n3 && in.Jc->cols() == nc &&
                     gi.bodies().size() == bodies.size(),
                 "grid coupled solve: v* {} and p_open {} of {} faces, J {} x {} and Jc {} x {} "
                 "for {} DOFs x {} cells, {} bodies for {}",
                 in.u_star->size(), in.p_open->size(), nf, in.J->rows(), in.J->cols(),
                 in.Jc->rows(), in.Jc->cols(), n3, nc, gi.bodies().size(), bodies.size());
  GridDofs d;
  d.cells = fluid::number_fluid_cells(gc);
  d.free_dof.assign(n3, -1);
  d.prescribed = VecX::Zero(n3);
  d.fixed_free.assign(n3, 0);
  sys.nb = static_cast<Index>(bodies.size());
  sys.dof0.assign(sys.nb + 1, 0);
  for (Index b = 0; b < sys.nb; ++b) {
    const CoupledBody& cb = bodies[b];
    const Index off = 3 * gi.node_offsets()[b], nb3 = 3 * gi.bodies()[b].num_nodes;
    if (cb.free)
      TETFSI_REQUIRE(InputError,
                     cb.A.rows() == nb3 && cb.b.size() == nb3 &&
                         static_cast<Index>(cb.fixed.size()) == nb3 && cb.x.rows() == nb3 / 3 &&
                         cb.u.size() == nb3,
                     "grid coupled solve: body {} has {} DOFs but A is {} x {}, b {}, fixed {}", b,
                     nb3, cb.A.rows(), cb.A.cols(), cb.b.size(), cb.fixed.size());
    sys.dof0[b + 1] = sys.dof0[b] + (cb.free ? nb3 : 0);
    if (!cb.free) continue;
    for (Index l = 0; l < nb3; ++l) {
      if (cb.fixed[l]) {
        d.fixed_free[off + l] = 1;
        d.prescribed[off + l] = cb.prescribed.size() ? cb.prescribed[l] : 0.0;
      } else {
        d.free_dof[off + l] = sys.dof0[b] + l;
      }
    }
  }
  sys.ns = sys.dof0[sys.nb];
  return d;
}

/// Regions, per-group volume and density (a group is a fluid cell).
void group_cells(const GridCoupledInput& in, const GridDofs& d, CoupledSystem& sys) {
  const GridCells& gc = *in.cells;
  sys.regions = fluid::grid_regions(gc);
  sys.ng = static_cast<Index>(d.cells.cell.size());
  sys.nr = sys.regions.count();
  sys.groups.cell_group = d.cells.unknown;
  sys.groups.count = sys.ng;
  sys.gvol = VecX::Constant(sys.ng, gc.grid.cell_volume());
  sys.grho = VecX(sys.ng);
  sys.greg = VecXi(sys.ng);
  for (Index g = 0; g < sys.ng; ++g) {
    sys.greg[g] = sys.regions.cell_region[d.cells.cell[g]];
    sys.grho[g] = (*in.rho)[d.cells.cell[g]];
  }
  sys.rvol = VecX::Zero(sys.nr);
  for (Index g = 0; g < sys.ng; ++g) sys.rvol[sys.greg[g]] += sys.gvol[g];
}

/// J and the second row's V D1 H between free DOFs and cells, the hydrostatic nodal forces,
/// the flux of prescribed DOFs of free bodies, the lifted regions.
void assemble_interface(const GridCoupledInput& in, const GridDofs& d, CoupledSystem& sys,
                        VecX& hydro, VecX& r_prescribed) {
  const GridCells& gc = *in.cells;
  // A region is lifted (its level held by a free body) when the body feels its pressure
  // (J) and its flux sees the body's motion (V D1 H) — both, or the paper form is singular
  // on a pocket one of them misses.
  std::vector<bool> by_J(sys.nr, false), by_Jc(sys.nr, false);
  r_prescribed = VecX::Zero(sys.ng);
  Triplets jt, kt;
  auto scan = [&](const SparseMatrix& M, bool first_row) {
    for (Index c = 0; c < M.outerSize(); ++c) {
      const Index g = d.cells.unknown[c];
      if (g < 0) continue;
      for (SparseMatrix::InnerIterator it(M, c); it; ++it) {
        const Index dof = it.row();
        if (!first_row && d.fixed_free[dof]) r_prescribed[g] += it.value() * d.prescribed[dof];
        if (d.free_dof[dof] < 0 || it.value() == 0.0) continue;
        (first_row ? jt : kt).emplace_back(d.free_dof[dof], g, it.value());
        (first_row ? by_J : by_Jc)[sys.greg[g]] = true;
      }
    }
  };
  scan(*in.J, true);
  scan(*in.Jc, false);
  sys.lifted.assign(sys.nr, false);
  for (Index r = 0; r < sys.nr; ++r) sys.lifted[r] = by_J[r] && by_Jc[r];
  sys.J = SparseMatrix(sys.ns, sys.ng);
  sys.J.setFromTriplets(jt.begin(), jt.end());
  SparseMatrix Kc(sys.ns, sys.ng);
  Kc.setFromTriplets(kt.begin(), kt.end());
  sys.symmetric = in.J == in.Jc;
  sys.Jt = sys.symmetric ? SparseMatrix(sys.J.transpose()) : SparseMatrix(Kc.transpose());
  // the hydrostatic pressure ρ g·(x − origin) at the cell centres through J
  hydro = VecX::Zero(sys.ns);
  if (in.gravity.squaredNorm() == 0) return;
  TETFSI_CHECK(in.Jh, "grid coupled solve: gravity without the hydrostatic J");
  VecX ph(gc.grid.num_cells());
  for (Index c = 0; c < ph.size(); ++c)
    ph[c] = fluid::hydrostatic_pressure((*in.rho)[c], in.gravity, in.hydrostatic_origin,
                                        gc.grid.cell_centre(c));
  const VecX f = *in.Jh * ph;  // the paper's J: exact for the linear hydrostatic field
  for (Index dof = 0; dof < f.size(); ++dof)
    if (d.free_dof[dof] >= 0) hydro[d.free_dof[dof]] = f[dof];
}

/// Whether face f's velocity is the unknown H u (a Solid face crossing a free body).
bool free_face(const GridCoupledInput& in, Index f) {
  const Index b = in.cells->face_solid[f].body;
  return in.cells->face_kind[f] == FaceKind::Solid && b >= 0 && (*in.bodies)[b].free;
}

/// The second block row r = V D v0 + (prescribed DOFs' flux) − Σ_open (A/d) (h/ρ) p_open, v0
/// = v* without the free bodies' faces; the net flux of pinned regions removed.
VecX second_row(const GridCoupledInput& in, const GridDofs& d, CoupledSystem& sys,
                const VecX& r_prescribed, CoupledReport& rep) {
  const GridCells& gc = *in.cells;
  const fluid::GridSpec& g = gc.grid;
  const Index nf = g.num_faces();
  VecX v0 = *in.u_star;
  for (Index f = 0; f < nf; ++f)
    if (free_face(in, f)) v0[f] = 0.0;
  const VecX flux = fluid::grid_flux_excess(gc, v0);
  rep.divergence_before =
      fluid::grid_net_flux(gc, *in.u_star).cwiseAbs().maxCoeff() / g.cell_volume();
  std::vector<OpenFaceTerm> open;
  for (Index f = 0; f < nf; ++f)
    if (gc.face_kind[f] == FaceKind::Open) {
      const Index c = fluid::grid_inner_cell(gc, f);
      if (c < 0) continue;
      open.push_back({d.cells.unknown[c], g.face_area(g.face_axis(f)), fluid::grid_face_dual(gc, f),
                      (*in.p_open)[f]});
    }
  return second_row_rhs(sys, r_prescribed, flux, d.cells.unknown, open, rep);
}

/// Triangles of each body's surface component (connected through shared vertices).
std::vector<std::vector<Index>> surface_components(const BodyInterface& b, VecXi& component) {
  const Index nt = b.triangles.rows();
  std::vector<Index> parent(b.surface_node.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](Index v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (Index t = 0; t < nt; ++t)
    for (int k = 1; k < 3; ++k) parent[find(b.triangles(t, k))] = find(b.triangles(t, 0));
  std::vector<Index> id(parent.size(), -1);
  std::vector<std::vector<Index>> comps;
  component.resize(nt);
  for (Index t = 0; t < nt; ++t) {
    const Index root = find(b.triangles(t, 0));
    if (id[root] < 0) {
      id[root] = static_cast<Index>(comps.size());
      comps.emplace_back();
    }
    component[t] = id[root];
    comps[id[root]].push_back(t);
  }
  return comps;
}

/// Enclosed regions (only Solid faces of free bodies around them, lifted, no Open face) and
/// their cavities: the surface components their Solid faces cross, whole.
void find_enclosed(const GridCoupledInput& in, const CoupledOptions& opt, CoupledSystem& sys) {
  if (!(opt.conserve_volume && in.volume_targets)) return;
  const GridCells& gc = *in.cells;
  const Index nf = gc.grid.num_faces();
  std::vector<bool> enclosed(sys.nr, true);
  for (Index f = 0; f < nf; ++f) {
    if (gc.interior(f)) continue;
    for (Index c : gc.grid.face_cells(f))
      if (gc.fluid(c) && !free_face(in, f)) enclosed[sys.regions.cell_region[c]] = false;
  }
  std::vector<Index> slot(sys.nr, -1);
  for (Index k = 0; k < sys.nr; ++k)
    if (enclosed[k] && sys.lifted[k] && !sys.regions.has_open[k]) {
      slot[k] = static_cast<Index>(sys.enclosed.size());
      sys.enclosed.push_back(k);
    }
  if (sys.enclosed.empty()) return;
  const std::vector<BodyInterface>& bi = in.interface->bodies();
  std::vector<VecXi> comp(bi.size());
  std::vector<std::vector<std::vector<Index>>> comps(bi.size());
  for (size_t b = 0; b < bi.size(); ++b) comps[b] = surface_components(bi[b], comp[b]);
  std::vector<std::vector<std::pair<Index, Index>>> hit(sys.enclosed.size());
  // the triangle each Solid face's segment meets first from the region's side (a thin shell's
  // segment crosses both of its surfaces; the cavity is bounded by the near one)
  const fluid::GridSpec& g = gc.grid;
  for (Index f = 0; f < nf; ++f) {
    if (!free_face(in, f)) continue;
    const auto cells = g.face_cells(f);
    for (int side = 0; side < 2; ++side) {
      const Index c = cells[side], o = cells[1 - side];
      if (!gc.fluid(c) || slot[sys.regions.cell_region[c]] < 0) continue;
      const Vec3 a = g.cell_centre(c), b = o >= 0 ? g.cell_centre(o) : g.face_centre(f);
      fluid::SurfacePoint sp;
      if (!gc.solids.first_crossing(a, b, &sp) || sp.body < 0) sp = gc.face_solid[f];
      hit[slot[sys.regions.cell_region[c]]].emplace_back(sp.body, comp[sp.body][sp.triangle]);
    }
  }
  sys.cavities.resize(sys.enclosed.size());
  for (size_t k = 0; k < hit.size(); ++k) {
    std::sort(hit[k].begin(), hit[k].end());
    hit[k].erase(std::unique(hit[k].begin(), hit[k].end()), hit[k].end());
    for (const auto& [b, cid] : hit[k])
      for (Index t : comps[b][cid]) sys.cavities[k].triangles.emplace_back(b, t);
  }
}

CoupledSystem assemble_grid_coupled(const GridCoupledInput& in, const CoupledOptions& opt,
                                    GridDofs& d, CoupledReport& rep) {
  const double t0 = now_seconds();
  CoupledSystem sys;
  sys.bodies = in.bodies;
  sys.interfaces = &in.interface->bodies();
  sys.h = in.h;
  d = stack_dofs(in, sys);
  rep.solid_unknowns = sys.ns;
  group_cells(in, d, sys);
  rep.pressure_unknowns = sys.ng;
  VecX hydro, r_prescribed;
  assemble_interface(in, d, sys, hydro, r_prescribed);
  // see [Chentanez06, Eq. (7)] on the grid: C = diag(h/ρ) L, pins where nothing fixes the level
  sys.pin_regions = sys.regions;
  for (Index r = 0; r < sys.nr; ++r)
    sys.pin_regions.has_open[r] = sys.regions.has_open[r] || sys.lifted[r];
  sys.gs = VecX::Constant(sys.ng, in.h).cwiseQuotient(sys.grho);  // h/ρ per cell
  sys.C = sys.gs.asDiagonal() * fluid::grid_pressure_matrix(*in.cells, d.cells, sys.pin_regions);
  const fluid::GridSpec& g = in.cells->grid;
  sys.grid = GridLayout{{g.n[0], g.n[1], g.n[2]}, d.cells.cell};
  VecX r = second_row(in, d, sys, r_prescribed, rep);
  find_enclosed(in, opt, sys);
  stack_right_hand_sides(sys, std::move(r), hydro);
  add_contact(sys, opt);
  rep.assembly_s = now_seconds() - t0;
  return sys;
}

/// Eq. (8) on the grid and the figures of the solution.
void finish_grid_coupled(const GridCoupledInput& in, const CoupledSystem& sys, const GridDofs& d,
                         const CoupledSolves& x, const VecX& c, CoupledSolution& sol) {
  const double t0 = now_seconds();
  const GridCells& gc = *in.cells;
  const fluid::GridSpec& g = gc.grid;
  const Index nc = g.num_cells(), ne = c.size();
  CoupledReport& rep = sol.report;
  const auto [u, pg] = combine_solves(x, c);
  sol.p = VecX::Zero(nc);
  for (Index k = 0; k < sys.ng; ++k) sol.p[d.cells.cell[k]] = pg[k];
  sol.u = body_velocities(sys, u);
  if (sys.ns > 0) {
    rep.interface_power = (sys.J * pg).dot(u);
    rep.interface_imbalance = rep.interface_power - pg.dot(sys.Jt * u);
  }
  // see [Chentanez06, Eq. (8)]: v* − (h/ρ) G p on Interior and Open faces, (H u)_f on the
  // faces of free bodies
  sol.u_face = *in.u_star;
  in.interface->apply_H(sol.u, sol.u_face);
  const VecX s = VecX::Constant(nc, in.h).cwiseQuotient(*in.rho);  // q = (h/ρ) p
  VecX q_open = *in.p_open;
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] == FaceKind::Open && fluid::grid_inner_cell(gc, f) >= 0)
      q_open[f] *= s[fluid::grid_inner_cell(gc, f)];
  fluid::grid_apply_gradient(gc, s.cwiseProduct(sol.p), q_open, sol.u_face);
  VecX source = VecX::Zero(nc);
  for (Index k = 0; k < ne; ++k)
    for (Index q = 0; q < sys.ng; ++q)
      if (sys.greg[q] == sys.enclosed[k])
        source[d.cells.cell[q]] = c[k] * sys.gvol[q] / sys.rvol[sys.enclosed[k]];
  rep.divergence_after =
      (fluid::grid_flux_excess(gc, sol.u_face) - source).cwiseAbs().maxCoeff() / g.cell_volume();
  const bool liquid = in.gravity.squaredNorm() > 0;
  VecX ph = VecX::Zero(nc);
  for (Index q = 0; q < nc && liquid; ++q)
    ph[q] = fluid::hydrostatic_pressure((*in.rho)[q], in.gravity, in.hydrostatic_origin,
                                        g.cell_centre(q));
  sol.fluid_force = grid_fluid_forces(*in.interface, *in.J, sol.p, liquid ? in.Jh : nullptr, &ph);
  rep.assembly_s += now_seconds() - t0;
}

}  // namespace

VecX grid_hydrostatic_pressure(const fluid::GridCells& gc, const VecX& rho,
                               const fluid::FluidParams& params) {
  VecX ph(gc.grid.num_cells());
  for (Index c = 0; c < ph.size(); ++c)
    ph[c] = fluid::hydrostatic_pressure(rho[c], params.gravity, params.hydrostatic_origin,
                                        gc.grid.cell_centre(c));
  return ph;
}

std::vector<VecX> grid_fluid_forces(const fluid::GridInterface& iface, const SparseMatrix& J,
                                    const VecX& p_dyn, const SparseMatrix* Jh,
                                    const VecX* p_hydro) {
  VecX f = J * p_dyn;
  if (Jh && p_hydro) f += *Jh * *p_hydro;
  const std::vector<Index>& off = iface.node_offsets();
  std::vector<VecX> F(iface.bodies().size());
  for (size_t b = 0; b < F.size(); ++b) F[b] = f.segment(3 * off[b], 3 * (off[b + 1] - off[b]));
  return F;
}

CoupledSolution solve_grid_coupled(const GridCoupledInput& in, const CoupledOptions& opt) {
  TETFSI_CHECK(in.cells && in.u_star && in.p_open && in.interface && in.J && in.Jc && in.bodies,
               "solve_grid_coupled: missing input");
  CoupledSolution sol;
  CoupledReport& rep = sol.report;
  rep.backend = to_string(opt.solver);
  rep.converged = true;
  GridDofs d;
  const CoupledSystem sys = assemble_grid_coupled(in, opt, d, rep);
  const auto [x, c] = solve_system(sys, opt, in.volume_targets, rep, "grid coupled solve");
  finish_grid_coupled(in, sys, d, x, c, sol);
  return sol;
}

// ---- the grid fluid behind the seam ------------------------------------------------------

namespace {

/// The J matrices a step keeps: (V D1 H)ᵀ always; the paper's J when the step needs it — for
/// its forces, or for the hydrostatic pressure's — else empty.
void force_matrices(const fluid::GridInterface& iface, GridPressureForces forces,
                    const fluid::FluidParams& params, SparseMatrix& Jc, SparseMatrix& Jp) {
  Jc = iface.J_consistent();
  const bool paper = forces == GridPressureForces::Paper || params.gravity.squaredNorm() > 0;
  Jp = paper ? iface.J_paper() : SparseMatrix();
}

}  // namespace

GridPredicted::GridPredicted(fluid::GridPrediction pred, const fluid::FluidParams& params,
                             const std::vector<BodyInterface>& bodies, GridPressureForces forces)
    : m_pred(std::move(pred)), m_params(params), m_iface(m_pred.cells, bodies), m_forces(forces) {
  force_matrices(m_iface, forces, params, m_Jc, m_Jp);
}

void fill_grid_force_cache(const fluid::GridCells& gc, const std::vector<BodyInterface>& bodies,
                           GridPressureForces forces, const fluid::FluidParams& params, double time,
                           GridForceCache& cache) {
  cache.valid = false;
  force_matrices(fluid::GridInterface(gc, bodies), forces, params, cache.Jc, cache.Jp);
  cache.time = time;
  cache.valid = true;
}

CoupledSolution GridPredicted::solve(const std::vector<CoupledBody>& bodies,
                                     const CoupledOptions& opt, const SolveVariant& v) const {
  GridCoupledInput in;
  in.cells = &m_pred.cells;
  in.u_star = v.u_star ? v.u_star : &m_pred.u_star;
  in.p_open = &m_pred.p_open;
  in.rho = &m_pred.rho;
  in.h = m_pred.h;
  in.gravity = m_params.gravity;
  in.hydrostatic_origin = m_params.hydrostatic_origin;
  in.interface = &m_iface;
  in.Jc = &m_Jc;
  in.J = m_forces == GridPressureForces::Paper ? &m_Jp : &m_Jc;
  in.Jh = m_Jp.size() ? &m_Jp : nullptr;
  in.bodies = &bodies;
  in.volume_targets = v.targets;
  VecX zero_f;
  if (v.homogeneous) {
    zero_f = VecX::Zero(m_pred.cells.grid.num_faces());
    in.u_star = &zero_f;
    in.p_open = &zero_f;
    in.gravity = Vec3::Zero();
  }
  return solve_grid_coupled(in, opt);
}

void GridPredicted::refuse_sealed_regions(const solid::SolidWorld& world,
                                          const char* scheme) const {
  const GridCells& gc = m_pred.cells;
  const fluid::Regions regions = fluid::grid_regions(gc);
  for (Index f = 0; f < gc.grid.num_faces(); ++f) {
    const Index b = gc.face_solid[f].body;
    if (gc.face_kind[f] != FaceKind::Solid || b < 0 || world.bodies[b].is_kinematic()) continue;
    for (Index c : gc.grid.face_cells(f))
      TETFSI_REQUIRE(InputError, !gc.fluid(c) || regions.has_open[regions.cell_region[c]],
                     "coupling.scheme {}: a fluid region of the grid has no open face and is "
                     "bounded by body '{}': a fluid-only projection cannot keep its volume; use "
                     "coupling.scheme simultaneous, or give the region an open patch",
                     scheme, world.bodies[b].name());
  }
}

GridCoupledFluid::GridCoupledFluid(fluid::GridFluid& fluid, const mesh::FluidDomain& domain,
                                   const std::vector<BodySurface>& surfaces,
                                   const std::vector<std::string>& names,
                                   std::vector<BodyInterface> bodies, GridPressureForces forces,
                                   GridForceCache* cache)
    : m_fluid(fluid),
      m_domain(domain),
      m_surfaces(surfaces),
      m_names(names),
      m_bodies(std::move(bodies)),
      m_forces(forces),
      m_cache(cache) {}

std::unique_ptr<PredictedFluid> GridCoupledFluid::predict(
    const std::vector<MatX3>& positions, const std::vector<fluid::SolidSurfaceMotion>& motions,
    double h, PhaseTimes& phases) {
  fluid::GridPrediction pred =
      m_fluid.predict(place_surfaces(m_domain, m_surfaces, m_names, positions), motions, h, phases);
  ScopedTimer timer(phases, "coupled_assembly");  // H, D1 and J of the step's grid
  return std::make_unique<GridPredicted>(std::move(pred), m_fluid.params(), m_bodies, m_forces);
}

fluid::FluidStepReport GridCoupledFluid::commit(std::unique_ptr<PredictedFluid> pred,
                                                CoupledSolution& sol) {
  auto* gp = dynamic_cast<GridPredicted*>(pred.get());
  TETFSI_CHECK(gp, "GridCoupledFluid::commit: a prediction of another fluid");
  if (m_cache) {
    m_cache->valid = false;
    gp->release_forces(m_cache->Jc, m_cache->Jp);
  }
  fluid::FluidStepReport r =
      m_fluid.commit(std::move(gp->prediction()), std::move(sol.u_face), std::move(sol.p));
  if (m_cache) {
    m_cache->valid = true;
    m_cache->time = m_fluid.time();
  }
  return r;
}

std::vector<VecX> GridCoupledFluid::current_forces(const std::vector<BodyInterface>& bodies) const {
  return grid_current_forces(m_fluid, bodies, m_forces, m_cache);
}

std::vector<VecX> grid_current_forces(const fluid::GridFluid& fluid,
                                      const std::vector<BodyInterface>& bodies,
                                      GridPressureForces forces, const GridForceCache* cache) {
  const fluid::GridCells& gc = fluid.cells();
  const fluid::GridInterface iface(gc, bodies);
  const bool cached = cache && cache->valid && cache->time == fluid.time() &&
                      cache->Jc.rows() == iface.num_dofs() &&
                      cache->Jc.cols() == gc.grid.num_cells();
  const bool need_paper =
      forces == GridPressureForces::Paper || fluid.params().gravity.squaredNorm() > 0;
  SparseMatrix Jc, Jp;
  if (!cached || (need_paper && cache->Jp.size() == 0)) Jp = iface.J_paper();
  if (!cached && forces == GridPressureForces::Consistent) Jc = iface.J_consistent();
  const SparseMatrix& jp = Jp.size() || !cached ? Jp : cache->Jp;
  const SparseMatrix& jc = Jc.size() || !cached ? Jc : cache->Jc;
  const VecX ph =
      grid_hydrostatic_pressure(gc, fluid::grid_cell_density(gc, fluid.params()), fluid.params());
  const VecX p_dyn = fluid.state().p - ph;  // J reads fluid cells only
  const bool hydro = fluid.params().gravity.squaredNorm() > 0;
  return grid_fluid_forces(iface, forces == GridPressureForces::Paper ? jp : jc, p_dyn,
                           hydro ? &jp : nullptr, hydro ? &ph : nullptr);
}

}  // namespace tetfsi::coupling
