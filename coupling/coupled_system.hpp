#pragma once
/// @file coupled_system.hpp
/// The simultaneous fluid–solid solve of one step [Chentanez06, §3.3, Eqs. (6)–(8)]: the
/// solid velocities uⁿ⁺¹ of every free body and the fluid pressure pⁿ⁺¹ from one system.
///
/// Unknowns: the free bodies' node velocities (stacked, 3 per node) and one pressure per
/// group of co-spherical cells (fluid/tet/operators.hpp; a group's cells share the pressure, so
/// J's columns are summed per group). With C = diag(h/ρ_g) L, L = −V D2 G the pressure
/// matrix between groups (SPD up to its constants), the paper's system (7)
///
///     [ A            −J          ] [u]   [ b           ]
///     [ −D1 H        (h/ρ) D2 G  ] [p] = [ D2 v* − s/V ]
///
/// is, after multiplying its second block row by the group volumes V (J = (V D1 H)ᵀ), the
/// symmetric quasi-definite system (docs/method/coupling.md)
///
///     [ A     −J ] [u]   [ b            ]
///     [ −Jᵀ   −C ] [p] = [ V D2 v* − s  ]
///
/// with A = M/h + C_damp + (h/2)K' per body [Chentanez06, Eq. (4)] and s the net outward
/// flux allowed per group (zero except in enclosed regions, below). Solvers:
///  - `schur_amg` (default): eliminate u. S = C + Jᵀ A⁻¹ J is SPD; CG on S, applied as a
///    product (A⁻¹ by a Cholesky factorization of each body's A), preconditioned by
///    BoomerAMG on the sparse P = C + Jᵀ diag(A)⁻¹ J; then u = A⁻¹ (b + J p);
///  - `umfpack`, `bicgstab_ilut`: the paper's non-symmetric form, the paper's solvers (LU;
///    BiCGSTAB with incomplete LU) — the reference;
///  - `symmetric_umfpack`: LU of the symmetric form (a check of the equivalence).
/// Then the fluid face velocities by Eq. (8): v* − (h/ρ) G p inside and on Open faces,
/// (H u)_f on the Solid faces of free bodies.
///
/// Regions (connected fluid). A region with an Open face has its pressure level fixed by
/// it. A region that touches a free body has none to fix: Jᵀ A⁻¹ J lifts the constant (a
/// uniform pressure squeezes the body), so it is solved without a pin and without any flux
/// correction. Only a region bounded by walls and prescribed bodies alone is pinned and its
/// net boundary flux removed (fluid::project()).
///
/// Interface half cells. The projection's kinetic energy is ½ Σ_f ρ A_f d_f u_f² over the
/// faces' dual cells; a Solid face has only the half dual cell between the face and its cell's
/// circumcentre (A_f δ_f, δ_f = max(d_f, 0), not the clamped d̃_f), whose fluid moves with the
/// face's normal velocity (H u)_f. Left out (the paper's form), that fluid carries no kinetic
/// energy and the added mass is biased low at first order (−10 % of C_m at 0.025 m cells around a
/// 0.1 m sphere). Counted, it is the mass M_I = Σ_f ρ_t A_f δ_f H_fᵀ H_f on the body's DOFs, δ_f
/// lowered off a convex body (raised in a cavity) by the spreading of its normals
/// (half_cells.hpp, CoupledInput::half_cell_lengths): A +=
/// M_I/h, b += Σ_f ρ_t A_f δ_f u_f⁰ H_fᵀ / h (u_f⁰ the half cell's velocity at tⁿ,
/// CoupledInput::u_ref), and the fluid's force on the body gains −Σ_f ρ_t A_f δ_f (u_f − u_f⁰)/h
/// H_fᵀ, its pressure at the face rather than at the circumcentre. Every scheme sees the same
/// force, so the iterated schemes converge to the simultaneous solution; time splitting's fluid
/// solve has the faces at their held velocity (u_f = u_f⁰), so the term is 0 there.
///
/// Enclosed regions (bounded only by Solid faces of free bodies: a liquid in a closed toy or
/// balloon) keep their volume exactly. The linearised constraint conserves it only to
/// O(h² |∇u|²) per step (the solid moves by the trapezoidal rule, Eq. (5), not along uⁿ⁺¹),
/// so the solve allows the region a net flux c (spread over its cells in proportion to
/// volume): the solution is affine in c, one more solve gives its direction, and c is chosen
/// by Newton on the exact volume of the cavity's triangles after Eq. (5),
/// V(xⁿ + h/2 (uⁿ + uⁿ⁺¹(c))) = V_target. The target is the region's volume when first seen.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "core/linear_solver.hpp"
#include "core/types.hpp"
#include "fluid/tet/interface.hpp"
#include "fluid/tet/operators.hpp"
#include "fluid/tet/simulation.hpp"
#include "mesh/tet_mesh.hpp"
#include "solid/contact.hpp"

namespace tetfsi::coupling {

enum class CoupledSolverKind { SchurAmg, Umfpack, BiCgStabIlut, SymmetricUmfpack };
inline constexpr EnumNames<CoupledSolverKind, 4> k_coupled_solver_names{
    "coupled solver",
    {{{CoupledSolverKind::SchurAmg, "schur_amg"},
      {CoupledSolverKind::Umfpack, "umfpack"},
      {CoupledSolverKind::BiCgStabIlut, "bicgstab_ilut"},
      {CoupledSolverKind::SymmetricUmfpack, "symmetric_umfpack"}}}};
/// "schur_amg" | "umfpack" | "bicgstab_ilut" | "symmetric_umfpack" (k_coupled_solver_names).
/// @throws InputError naming the value and the valid ones.
CoupledSolverKind parse_coupled_solver(const std::string& name);
const char* to_string(CoupledSolverKind k);

using fluid::BodyInterface;
using fluid::InterfaceOperators;

/// One body as the coupled solve sees it (how the mesh's Solid faces refer to it is the
/// input's InterfaceOperators, body for body).
struct CoupledBody {
  /// true: its velocities are unknowns (a deformable body). false: prescribed (kinematic,
  /// or held by time splitting): its Solid faces keep the v* the caller set.
  bool free = false;
  SparseMatrix A;  ///< free: [Chentanez06, Eq. (4)], 3n × 3n, fixed DOFs eliminated
  VecX b;          ///< free: 3n, without fluid forces
  std::vector<std::uint8_t> fixed;  ///< free: per DOF, 1 if its velocity is prescribed
  /// free: the prescribed uⁿ⁺¹ of the fixed DOFs (3n; empty: 0, pins). A contact constraint
  /// puts a node on the floor this way; A and b must already have the DOF eliminated
  /// (A's row and column zero but the diagonal, b = A_ii v, the column moved into b).
  VecX prescribed;
  MatX3 x;  ///< free: node positions at tⁿ (#n × 3; enclosed volumes)
  VecX u;   ///< free: uⁿ (3n; enclosed volumes)
};

/// A preconditioner kept between solves whose P is the same: the fluid-only solves of one
/// iterated step (coupled_step.hpp) share the mesh, the densities, h and (no free body)
/// P = C, and differ only in their right-hand sides. The caller must drop it when P changes.
struct SolveCache {
  std::unique_ptr<AmgPreconditioner> amg;
  Index size = -1;  ///< pressure unknowns of the matrix it was set up for
  int reused = 0;   ///< solves that reused it
};

struct CoupledOptions {
  CoupledSolverKind solver = CoupledSolverKind::SchurAmg;
  /// Relative residual of the iterative solves. The right-hand side carries the bodies'
  /// momentum, so the fluid's per-cell divergence follows it more loosely than in a fluid-only
  /// projection: measured 1e-6, 6e-9, 3e-10 of the v* divergence at 1e-8, 1e-10, 1e-12 (12,
  /// 15, 17 CG iterations on 8k pressure unknowns).
  double rel_tol = 1e-10;
  int max_iterations = 500;
  double min_dual_fraction = 1e-6;  ///< as fluid::FluidParams
  bool conserve_volume = true;      ///< the enclosed-volume correction (file comment)
  /// The interface half cells' inertia (file comment): the fluid between a Solid face and its
  /// cell's circumcentre moves with the face. false: the paper's form, no kinetic energy there.
  bool interface_mass = true;
  /// schur_amg on the grid fluid: precondition with hypre's structured multigrid
  /// (make_pfmg_preconditioner: P's 7-point part, the bodies' couplings beyond it on the
  /// diagonal) instead of BoomerAMG on the whole P. Off by default: cheaper set-up and
  /// V-cycles, but 2–6× the iterations where stiff bodies couple many cells
  /// (docs/method/grid_fluid.md).
  bool grid_multigrid = false;
  /// schur_amg: if set, the AMG setup of the first solve is kept here and reused by later
  /// solves with this cache (see SolveCache: only for the same P).
  SolveCache* reuse = nullptr;
  /// Contact between the bodies (solid/contact.hpp): its matrix joins the solid block (the
  /// bodies it couples are then factorised together) and its right-hand side the bodies'.
  /// Over the stacked free DOFs; null or empty: none.
  const solid::ContactSystem* contact = nullptr;
};

/// Enclosed regions' targets, keyed by the region's first (body, triangle) pair, kept by
/// the caller across steps (remeshing renumbers cells, not the bodies' triangles).
using VolumeTargets = std::map<std::int64_t, double>;

struct CoupledInput {
  const mesh::TetMesh* mesh = nullptr;
  const VecX* u_star = nullptr;  ///< #F v*, prescribed velocities set (FluidPrediction)
  /// #F the half cells' normal velocity at tⁿ on Solid faces (the prediction's v*, which an
  /// iterated scheme's u_star overrides with its iterate); null: u_star
  const VecX* u_ref = nullptr;
  /// u_ref, or u_star where it is not given.
  const VecX& half_cell_u0() const { return u_ref ? *u_ref : *u_star; }
  const VecX* rho = nullptr;     ///< #T fluid density per cell
  const VecX* p_open = nullptr;  ///< #F dynamic pressure on Open faces (Pa)
  double h = 0.0;
  /// The fluid's gravity (liquids): the hydrostatic pressure ρ g·x pushes the free bodies
  /// exactly (face_pressure_forces), J carries only the dynamic pressure.
  Vec3 gravity = Vec3::Zero();
  Vec3 hydrostatic_origin = Vec3::Zero();         ///< as fluid::FluidParams
  const InterfaceOperators* interface = nullptr;  ///< H, J, D1 of `mesh` and the bodies
  /// #F the interface half cells' lengths δ_eff with the bodies' normals spreading
  /// (half_cells.hpp); null: δ_f = max(d_f, 0)
  const VecX* half_cell_lengths = nullptr;
  const std::vector<CoupledBody>* bodies = nullptr;  ///< every body of the mesh, by index
  VolumeTargets* volume_targets = nullptr;           ///< may be null: no volume correction
};

/// The input of a solve from the fluid's prediction of the step (its mesh, v*, densities,
/// open pressures, h) and its parameters (gravity, hydrostatic origin). The pointers refer to
/// `pred`, `ops` (built on pred.mesh) and `bodies`, which must outlive the input.
CoupledInput make_input(const fluid::FluidPrediction& pred, const fluid::FluidParams& params,
                        const InterfaceOperators& ops, const std::vector<CoupledBody>& bodies,
                        VolumeTargets* targets = nullptr);

/// An enclosed region of this step.
struct EnclosedRegion {
  std::int64_t key = 0;
  Index cells = 0;
  double volume = 0.0;  ///< V of its cavity at tⁿ (m³)
  double target = 0.0;  ///< V_target
  double after = 0.0;   ///< V after Eq. (5) with the solution
  double flux = 0.0;    ///< the net flux c allowed (m³/s)
};

struct CoupledReport {
  std::string backend;
  bool converged = false;
  int iterations = 0;     ///< Krylov iterations (1 for LU), summed over right-hand sides
  double residual = 0.0;  ///< worst relative residual of the solves
  /// Largest round-off floor measured (SolveReport::floor): 0 unless a solve stopped above
  /// rel_tol.
  double floor = 0.0;
  /// Solves that stopped above rel_tol but within a small factor of their round-off floor,
  /// counted as converged: rel_tol is below what round-off allows for this system.
  int solves_at_floor = 0;
  bool stagnated = false;  ///< an unconverged solve stopped by stagnation, not its limit
  Index solid_unknowns = 0, pressure_unknowns = 0;
  /// pᵀ Jᵀ uⁿ⁺¹ = pᵀ V D1 H uⁿ⁺¹: the power of the dynamic pressure on the free bodies (W).
  double interface_power = 0.0;
  /// pᵀ Jᵀ uⁿ⁺¹ − pᵀ V D1 H uⁿ⁺¹: the power the interface creates, the dynamic pressure's
  /// power on the bodies minus the bodies' on the fluid (W). 0 when J = (V D1 H)ᵀ (the tet
  /// fluid, the grid's consistent form) but for round-off; the grid's paper J is built apart.
  double interface_imbalance = 0.0;
  double divergence_before = 0.0;  ///< max_t |(D v*)_t| (1/s)
  double divergence_after = 0.0;   ///< max_t |(D v)_t − s_t/V_t| after Eq. (8) (1/s)
  Index pinned_regions = 0;
  double incompatibility = 0.0;  ///< as fluid::ProjectionReport, pinned regions only
  std::vector<EnclosedRegion> enclosed;
  double assembly_s = 0.0, setup_s = 0.0, solve_s = 0.0;
};

struct CoupledSolution {
  std::vector<VecX> u;  ///< per body: uⁿ⁺¹ (3n) of free bodies, empty for the others
  VecX p;               ///< #T dynamic pressure (Pa)
  VecX u_face;          ///< #F face velocities, Eq. (8)
  /// Per body: the fluid's force on each node (3n, N): J p plus the hydrostatic part.
  std::vector<VecX> fluid_force;
  CoupledReport report;
};

/// Assemble and solve, see the file comment: assemble_coupled, then solve_schur_amg or
/// solve_assembled, then solve_enclosed_volumes, then finish_coupled (Eq. (8)).
/// @throws SolverError if a factorization fails or the result is not finite;
///   InputError for inconsistent sizes (naming them).
CoupledSolution solve_coupled(const CoupledInput& in, const CoupledOptions& opt);

/// The fluid's force on every node of every body (3n each, N) of a pressure p (#T, dynamic,
/// Pa) on the interface's mesh, with the hydrostatic part ρ g·(x − origin) at the face
/// centroids: J p + F_hydro. Time splitting holds it over the next solid step.
std::vector<VecX> fluid_forces(const InterfaceOperators& ops, const VecX& p, const VecX& rho,
                               const Vec3& gravity, const Vec3& origin = Vec3::Zero());

// ---- the parts of solve_coupled (coupled_assembly.cpp, coupled_solvers.cpp,
//      enclosed_volume.cpp) ----------------------------------------------------------------

/// A cavity: the body triangles (body, triangle) bounding an enclosed region, once each.
struct Cavity {
  std::vector<std::pair<Index, Index>> triangles;
};

/// The assembled system of one solve (plain data; the tet fluid's assembly, a grid fluid
/// would fill the same): unknowns u (ns free DOFs) and p (ng pressure groups),
///     [ A     −J ] [u]   [ bs   ]
///     [ −Jᵀ   −C ] [p] = [ R2_k ]
/// for the right-hand-side columns k = 0 (the step's) and 1 + e (unit net flux out of
/// enclosed region e; bs = 0 for those).
struct CoupledSystem {
  const CoupledInput* in = nullptr;                  ///< the tet fluid's input (null on the grid)
  const std::vector<CoupledBody>* bodies = nullptr;  ///< every body, by index
  const std::vector<BodyInterface>* interfaces = nullptr;  ///< their surfaces, by index
  double h = 0.0;
  /// Jt = Jᵀ. false: the grid's paper form, J (the first block row's pressure forces) built
  /// apart from the second row's V D1 H = Jt; only the general solvers accept it.
  bool symmetric = true;
  Index nb = 0, ns = 0, ng = 0, nr = 0;
  std::vector<Index> dof0;  ///< first free DOF of each body (#bodies + 1)
  VecX d_eff;               ///< #F effective dual lengths
  fluid::PressureGroups groups;
  fluid::Regions regions;
  VecX gvol, grho;             ///< per group: volume (m³), density
  VecXi greg;                  ///< per group: region
  VecX rvol;                   ///< per region: volume (m³)
  std::vector<bool> lifted;    ///< per region: a free body's J touches it
  fluid::Regions pin_regions;  ///< regions' has_open: true where the level is fixed
  SparseMatrix J, Jt;          ///< ns × ng (free DOFs × groups); ng × ns (V D1 H)
  SparseMatrix C;              ///< ng × ng: diag(h/ρ_g) L, pinned where nothing fixes it
  VecX gs;                     ///< per group h/ρ
  VecX bs;                     ///< ns: the bodies' b plus the hydrostatic forces
  /// per body: A plus the interface half cells' M_I/h (file comment); empty: the body's A
  std::vector<SparseMatrix> A;
  /// #F ρ_t δ_f / A_f on the Solid faces (M_I = Σ_f that · w_f w_fᵀ, w_f the J entries of
  /// face f); empty without the half cells' mass
  VecX half_mass;
  /// Body b's A in the system (with the half cells' mass when counted).
  const SparseMatrix& body_A(Index b) const {
    return static_cast<Index>(A.size()) > b && A[b].size() ? A[b] : (*bodies)[b].A;
  }
  /// ns × ns: contact between the bodies (CoupledOptions::contact), added to the blocks;
  /// empty (no nonzeros): none
  SparseMatrix Ac;
  std::vector<VecX> R2;          ///< second block row right-hand sides (1 + #enclosed)
  std::vector<Index> enclosed;   ///< region ids of the enclosed regions
  std::vector<Cavity> cavities;  ///< per enclosed region
  /// The grid fluid: the grid cell of each group (dims 0 on the tet mesh). schur_amg then
  /// preconditions with hypre's structured multigrid (make_pfmg_preconditioner).
  GridLayout grid;
};

/// Stack the free DOFs, J between them and the groups, C, the right-hand sides, the pins and
/// the enclosed regions; fills rep.solid_unknowns, pressure_unknowns, divergence_before,
/// pinned_regions, incompatibility. @throws InputError for inconsistent sizes.
CoupledSystem assemble_coupled(const CoupledInput& in, const CoupledOptions& opt,
                               CoupledReport& rep);

/// The dynamic pressure on one Open face, as the second block row sees it.
struct OpenFaceTerm {
  Index group = -1;     ///< the pressure unknown of the face's fluid cell
  double area = 0.0;    ///< A_f (m²)
  double dual = 0.0;    ///< the distance from the cell's pressure sample to the face (m)
  double p_open = 0.0;  ///< Pa
};
/// The right-hand side of the second block row, [Chentanez06, Eq. (6)] times V, for both
/// discretisations (tet, grid): r_g = r_prescribed,g + Σ_{c in g} flux_c −
/// Σ_{Open f of g} (h/ρ_g) (A_f/d_f) p_open,f, cells in order then the Open faces in order,
/// with the net flux of every region that nothing fixes removed (remove_pinned_flux).
/// @param cell_flux the net outward flux of v* without the free bodies' faces, per cell
/// @param cell_group the pressure unknown of each cell (−1: not a fluid cell)
VecX second_row_rhs(const CoupledSystem& sys, VecX r_prescribed, const VecX& cell_flux,
                    const VecXi& cell_group, const std::vector<OpenFaceTerm>& open,
                    CoupledReport& rep);
/// The shared end of both assemblies (tet, grid): the second row r (per group) with the net
/// flux of every region that nothing fixes removed (rep.pinned_regions, incompatibility).
void remove_pinned_flux(const CoupledSystem& sys, VecX& r, CoupledReport& rep);
/// sys.bs from the free bodies' b plus `hydro`; sys.R2 from the step's row r and one unit net
/// flux column per enclosed region (sys.enclosed must be set).
void stack_right_hand_sides(CoupledSystem& sys, VecX r, const VecX& hydro);
/// sys.Ac and the contact's right-hand side into sys.bs from opt.contact (if any).
/// @throws InputError if its size is not the free DOFs'.
void add_contact(CoupledSystem& sys, const CoupledOptions& opt);

/// Solutions per right-hand side: u (ns), p = Z Pa + P (Z the Schur solver's coarse space of
/// body-held region constants; Pa empty otherwise).
struct CoupledSolves {
  std::vector<VecX> U, P, Pa;
  Eigen::MatrixXd Z;
};

/// The assembled system (paper form, scaled by 1/V_g, for umfpack and bicgstab_ilut; the
/// symmetric form for symmetric_umfpack) with a general sparse solver. Merges into rep.
CoupledSolves solve_assembled(const CoupledSystem& sys, CoupledSolverKind which,
                              const CoupledOptions& opt, CoupledReport& rep);

/// schur_amg: CG on S = C + Jᵀ A⁻¹ J with BoomerAMG on P = C + Jᵀ diag(A)⁻¹ J and the
/// balancing coarse space; falls back to solve_assembled(symmetric_umfpack) when S is not
/// positive definite. Merges into rep.
CoupledSolves solve_schur_amg(const CoupledSystem& sys, const CoupledOptions& opt,
                              CoupledReport& rep);

/// The net flux c (m³/s) of every enclosed region that keeps its cavity's exact volume after
/// Eq. (5) (Newton per region, Gauss–Seidel over regions); fills rep.enclosed.
VecX solve_enclosed_volumes(const CoupledSystem& sys, const CoupledSolves& x,
                            VolumeTargets& targets, CoupledReport& rep);

/// Node positions of the free bodies after Eq. (5) with the solve's uⁿ⁺¹ (fixed DOFs at their
/// prescribed values); other bodies' entries empty.
std::vector<MatX3> positions_after_step(const CoupledSystem& sys, const VecX& u);

/// The signed volume the cavity's triangles enclose at node positions x (per body).
double cavity_volume(const Cavity& cav, const std::vector<BodyInterface>& bodies,
                     const std::vector<MatX3>& x);

/// The step's solution of the solves with the fluxes c: u (ns) and p per group.
std::pair<VecX, VecX> combine_solves(const CoupledSolves& x, const VecX& c);
/// uⁿ⁺¹ per body (3n) from the stacked u, fixed DOFs at their prescribed values; empty for
/// bodies that are not free.
std::vector<VecX> body_velocities(const CoupledSystem& sys, const VecX& u);

/// The assembled system solved by opt.solver (checked finite, a warning if unconverged) and
/// the enclosed regions' fluxes c (empty without them). `what` names the solve in messages.
/// @throws SolverError if the result is not finite.
std::pair<CoupledSolves, VecX> solve_system(const CoupledSystem& sys, const CoupledOptions& opt,
                                            VolumeTargets* targets, CoupledReport& rep,
                                            const char* what);

/// The interface half cells' inertia on every body (coupled_system.hpp) added to `force`:
/// −Σ_f ρ_t A_f δ_f (u_f − u_f⁰)/h H_fᵀ with the face velocities u_f of the solution.
void add_half_cell_forces(const CoupledSystem& sys, const VecX& u_face, std::vector<VecX>& force);

/// Combine the solves with the fluxes c and finish: p per cell, u per body, the interface
/// power, Eq. (8) for the face velocities, the divergence after, the fluid's forces.
void finish_coupled(const CoupledSystem& sys, const CoupledSolves& x, const VecX& c,
                    CoupledSolution& sol);

}  // namespace tetfsi::coupling
