#pragma once
/// @file operators.hpp
/// The discrete operators of the fluid on a TetMesh and the pressure projection
/// [Chentanez06, §3.3], [KFCO06, §3]: normal velocity u_f per face along n_f, pressure per
/// tet at its circumcentre.
///
///  - divergence (D u)_t = (1/V_t) Σ_k s_tk A_f u_f [docs/method/tet_fluid.md]
///  - gradient on an interior face (G q)_f = (q_t2 − q_t1) / d̃_f, on an Open face
///    (q_open − q_t1) / d̃_f; other boundary faces carry a prescribed velocity (Neumann)
///  - the pressure matrix M = −V D G (SPD once a Dirichlet face or a pin fixes the
///    constant): M_tt = Σ_f A_f/d̃_f, M_tn = −A_f/d̃_f
///
/// Co-spherical cells. Delaunay faces between cells with the same circumcentre have d_f = 0
/// (the remesher's octree transitions leave ~12 % of the interior faces so), which would give
/// A_f/d_f = ∞. Such cells — every interior face with d_f ≤ δ ℓ_f joins them, ℓ_f the face's
/// mean edge and δ = FluidParams::min_dual_fraction — form one group with one pressure
/// unknown (mesh::cospherical_groups): the Laplacian is assembled between groups, and a
/// face inside a group (its "internal" faces) gets
///  - u_f = u*_f − n_f · ∇q_g, with ∇q_g the least-squares gradient that matches G q on the
///    group's other faces (exact for a linear q, so a uniform acceleration — a pure
///    gradient — is removed exactly), then
///  - the smallest correction (Σ A_f δ_f² minimal) that makes every cell of the group
///    divergence-free (a Laplacian solve on the group's few cells).
/// So every cell ends divergence-free to solver tolerance, a uniform flow is kept exactly and
/// a gradient field is removed exactly.
/// For Open faces d_f is the circumcentre's distance to the face plane, bounded below by
/// a quarter of the tet's height over the face (the circumcentre of an obtuse boundary tet
/// may lie beyond the face).
#include "core/linear_solver.hpp"
#include "core/types.hpp"
#include "fluid/regions.hpp"
#include "fluid/step.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// d̃_f (#F, m): see the file comment. Walls/inflow/solid faces get their d_f bounded too
/// (unused by the projection).
VecX effective_dual_lengths(const mesh::TetMesh& m, double min_dual_fraction);

/// (D u)_t (#T, 1/s) of face velocities u (#F, m/s).
VecX divergence(const mesh::TetMesh& m, const VecX& u);

/// Net outward flux Σ_k s_tk A_f u_f per cell (#T, m³/s) = V_t (D u)_t.
VecX net_flux(const mesh::TetMesh& m, const VecX& u);

/// Face gradient (G q)_f (#F) of cell values q: interior and Open faces as above (q_open: #F
/// values on Open faces, ignored elsewhere; may be empty for 0), 0 on the other boundary
/// faces. For test fields; faces with d_f ≈ 0 give what d_eff gives.
VecX gradient(const mesh::TetMesh& m, const VecX& d_eff, const VecX& q, const VecX& q_open);

/// The regions of the mesh (regions.hpp): cells joined through interior faces, has_open where
/// a region has an Open boundary face.
Regions fluid_regions(const mesh::TetMesh& m);

/// Pressure unknowns: one per group of co-spherical cells (see the file comment).
struct PressureGroups {
  VecXi cell_group;  ///< #T → group
  Index count = 0;
  /// Interior face f is internal to a group (both cells in it: no Laplacian weight).
  bool internal(const mesh::TetMesh& m, Index f) const {
    const Index t2 = m.face_tets(f, 1);
    return t2 >= 0 && cell_group[m.face_tets(f, 0)] == cell_group[t2];
  }
};
PressureGroups pressure_groups(const mesh::TetMesh& m, double min_dual_fraction);

/// The pressure matrix M (#groups × #groups, SPD): −V D G between groups, with one pin per
/// region that has no Open face (the group of its first cell gets its diagonal doubled —
/// exact for a compatible right-hand side, see project()).
SparseMatrix pressure_matrix(const mesh::TetMesh& m, const VecX& d_eff, const PressureGroups& g,
                             const Regions& regions);

/// u ← u − G q on the faces between groups and on Open faces, and the group-internal faces
/// as in the file comment, so that every cell's net outward flux becomes its `cell_source`
/// (m³/s per cell; nullptr: 0, divergence-free) — to the accuracy with which q solves the
/// pressure equation. On entry u holds u* with every prescribed boundary velocity set (Wall,
/// Inflow, Solid faces). q: #T cell values (equal within a group); q_open: #F values on Open
/// faces (may be empty for 0). [Chentanez06, Eq. (8)]
/// @return the number of group-internal faces
Index apply_pressure_gradient(const mesh::TetMesh& m, const VecX& d_eff, const PressureGroups& g,
                              const VecX& q, const VecX& q_open, VecX& u,
                              const VecX* cell_source = nullptr);

/// The projection [Chentanez06, Eq. (2)] with q = (h/ρ) p: solve M q = −V D u* + (Open-face
/// terms) on the groups, then u = u* − G q on interior and Open faces (internal faces of a
/// group as in the file comment). On entry u holds u* with the
/// prescribed normal velocity already set on Wall, Inflow and Solid faces; q is the initial
/// guess (resized to 0 if its size is wrong). q_open: #F values of q on Open faces (may be
/// empty for 0).
/// @throws SolverError if the solver's setup fails or the result is not finite.
/// @param q #T cell values on exit (equal within a group)
ProjectionReport project(const mesh::TetMesh& m, double min_dual_fraction, const VecX& q_open,
                         VecX& u, VecX& q, LinearSolver& solver);

}  // namespace tetfsi::fluid
