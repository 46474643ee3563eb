#pragma once
/// @file grid/projection.hpp
/// The pressure projection on the MAC grid [Chentanez06, Eq. (2)], [Fedkiw01, §3]: one
/// pressure unknown per fluid cell, the 7-point Laplacian between fluid cells joined by an
/// Interior face, Dirichlet on Open box faces (the face half a cell from the centre) and at a
/// free surface (p = 0 where φ = 0 on the segment to the air cell, [Gibou02]), and
/// Neumann (prescribed velocity) on Wall, Inflow and Solid faces.
///
///  - net outward flux of cell c: Σ_f s_cf A_f u_f (s_cf = +1 on its upper face along the
///    axis, −1 on its lower one)
///  - u_f ← u_f − (q_c2 − q_c1) / h_a on Interior faces, u_f ← u_f ∓ (q_open − q_c) / (h_a/2)
///    on Open faces, q = (h/ρ) p
///  - regions (fluid cells connected through Interior faces) without an Open face get one
///    pin and their net boundary flux removed first, as on the tet mesh (tet/operators.hpp).
#include <vector>

#include "core/linear_solver.hpp"
#include "core/types.hpp"
#include "fluid/grid/grid.hpp"
#include "fluid/regions.hpp"
#include "fluid/step.hpp"

namespace tetfsi::fluid {

/// The smallest liquid share θ of a surface face's segment (a surface almost on a cell
/// centre; 1/θ enters the pressure matrix).
inline constexpr double k_min_surface_theta = 1e-2;
/// The liquid's share θ ∈ [k_min_surface_theta, 1] of the centre-to-centre segment of a
/// free-surface face (GridCells::surface_face), from φ at its two cells [Gibou02].
double grid_surface_theta(const GridCells& gc, Index f);
/// Distance from a cell centre to the cell centre across face f (Interior), to f (Open), or
/// to the free surface (θ h, a surface face: the ghost-fluid p = 0 there [Gibou02]).
double grid_face_dual(const GridCells& gc, Index f);
/// The fluid cell next to a box face (−1 if none).
Index grid_inner_cell(const GridCells& gc, Index f);

/// The pressure unknowns: one per fluid cell, in cell order.
struct GridNumbering {
  VecXi unknown;            ///< #C → unknown, −1 for solid cells
  std::vector<Index> cell;  ///< unknown → cell
};
GridNumbering number_fluid_cells(const GridCells& gc);

/// M = −V D G between the fluid cells (SPD with the pins): M_cc = Σ A/d, M_cn = −A/d over
/// Interior faces, A/(h/2) on Open faces; one pin per region of `pins` without has_open (its
/// first cell's diagonal doubled).
SparseMatrix grid_pressure_matrix(const GridCells& gc, const GridNumbering& n, const Regions& pins);

/// u ← u − G q on Interior faces and Open faces (q_open there; empty: 0), q per cell (#C).
void grid_apply_gradient(const GridCells& gc, const VecX& q, const VecX& q_open, VecX& u);

/// Net outward flux per cell (#C, m³/s; 0 for solid cells) of face velocities u (#F).
VecX grid_net_flux(const GridCells& gc, const VecX& u);
/// The net outward flux beyond what the cell is to have (gc.volume_source, a liquid's density
/// correction; none without it): what the projection drives to zero.
VecX grid_flux_excess(const GridCells& gc, const VecX& u);

/// Fluid regions of the grid: region per cell (−1 for solid cells), has_open, first cell.
Regions grid_regions(const GridCells& gc);

/// The projection: solve for q (#C, on exit; 0 in solid cells) so that every fluid cell's net
/// outward flux is 0, then correct u (#F) on Interior and Open faces. On entry u holds u*
/// with every prescribed face set. q_open: #F values of q on Open faces (empty: 0).
/// @throws SolverError if the solve's setup fails or the result is not finite.
ProjectionReport grid_project(const GridCells& gc, const VecX& q_open, VecX& u, VecX& q,
                              LinearSolver& solver);

}  // namespace tetfsi::fluid
