#pragma once
/// @file grid/interface.hpp
/// The fluid–solid interface operators on the MAC grid [Chentanez06, §3.4, last paragraph],
/// the grid's counterpart of tet/interface.hpp (same DOF stacking: body b's node i is DOF block
/// node_offsets()[b] + i, 3 per node):
///
///  - H (#F × 3N): (H u)_f = e_a · Σ_k w_k u_{a_k} on every Solid face f of axis a, w the
///    barycentric weights of the crossing of its centre-to-centre segment with the body
///    triangle (classify_grid) [GSLF05];
///  - D1 (#C × #F): (D1 u)_c = (1/V) Σ_{Solid f of c} s_cf A_f u_f (s_cf = +1 on c's upper
///    face along the axis);
///  - J, two forms:
///     - paper (J_paper): the pressure interpolated (side-aware: only fluid cells the sample
///       point sees; trilinear, or a linear least-squares fit where a trilinear corner is
///       missing, grid_cell_stencil_linear) at quadrature points of every body triangle and
///       integrated, node k of the triangle getting −w_k(x_q) A_q p(x_q) n_out; J stores the
///       interpolation stencils. Exact for a linear pressure;
///     - energy-consistent (J_consistent) = (V D1 H)ᵀ: the pressure of cell c pushes each of its
///       Solid faces with s_cf A_f p_c e_a, spread by the crossing's weights. Then the power
///       the fluid does on the solid equals the power the solid does on the fluid, exactly.
#include <array>
#include <utility>
#include <vector>

#include "core/types.hpp"
#include "fluid/body_interface.hpp"
#include "fluid/grid/grid.hpp"

namespace tetfsi::fluid {

/// One Solid face of the grid and the body nodes of the triangle its segment crosses.
struct GridInterfaceFace {
  Index face = -1;
  int axis = 0;
  Index body = -1;
  Index node[3] = {-1, -1, -1};  ///< body-local node indices
  Index dof[3] = {-1, -1, -1};   ///< 3 × the stacked node index
  double weight[3] = {0, 0, 0};  ///< barycentric weights of the crossing
};

class GridInterface {
 public:
  /// @param gc the classified grid; it must outlive the operators
  /// @param bodies one per body index of the grid's surfaces (GridSolids::surfaces()[b].body
  ///   indexes it; triangles and vertices in the same compact numbering)
  /// @throws MeshError naming the face if a crossing refers to a body or triangle that does
  ///   not exist.
  GridInterface(const GridCells& gc, std::vector<BodyInterface> bodies);

  const GridCells& cells() const { return *m_gc; }
  const std::vector<GridInterfaceFace>& faces() const { return m_faces; }
  const std::vector<Index>& node_offsets() const { return m_offsets; }
  Index num_dofs() const { return 3 * m_offsets.back(); }
  const std::vector<BodyInterface>& bodies() const { return m_bodies; }

  /// u_face[f] = (H u)_f for the Solid faces of every body b whose u[b] is not empty.
  void apply_H(const std::vector<VecX>& u, VecX& u_face) const;
  SparseMatrix H() const;
  SparseMatrix D1() const;
  /// (V D1 H)ᵀ, 3N × #C.
  SparseMatrix J_consistent() const;
  /// The paper's J, 3N × #C: `per_cell` quadrature points per cell width along a triangle's
  /// longest edge (at least one sub-triangle). One is converged: 2 moves the released
  /// sphere's acceleration by 0.02 % of g at 20³–40³ and costs 4× the samples.
  SparseMatrix J_paper(int per_cell = 1) const;

 private:
  const GridCells* m_gc = nullptr;
  std::vector<BodyInterface> m_bodies;
  std::vector<Index> m_offsets;
  std::vector<GridInterfaceFace> m_faces;
};

/// At most 8 (cell, weight) pairs, held inline (no allocation).
struct CellStencil8 {
  std::array<std::pair<Index, double>, 8> items{};
  int size = 0;
  bool empty() const { return size == 0; }
  const std::pair<Index, double>* begin() const { return items.data(); }
  const std::pair<Index, double>* end() const { return items.data() + size; }
  std::pair<Index, double>* begin() { return items.data(); }
  std::pair<Index, double>* end() { return items.data() + size; }
};

/// Side-aware trilinear interpolation stencil of cell-centred values at x: (cell, weight)
/// pairs over the fluid cells of the 2 × 2 × 2 block around x that x sees (GridSolids),
/// weights summing to 1; empty if none.
CellStencil8 grid_cell_stencil8(const GridCells& gc, const Vec3& x);
/// grid_cell_stencil8's pairs as a vector.
std::vector<std::pair<Index, double>> grid_cell_stencil(const GridCells& gc, const Vec3& x);

/// The same where all 8 cells are usable; otherwise a least-squares linear fit
/// p ≈ a + b·(c − x) over the usable cells of the 4 × 4 × 4 block around x (weighted by
/// 1/(1 + |c − x|²/h²)), returning a's stencil — exact for a linear field, which the
/// renormalised stencil is not next to a solid. Falls back to grid_cell_stencil when fewer
/// than 4 usable cells span a volume.
std::vector<std::pair<Index, double>> grid_cell_stencil_linear(const GridCells& gc, const Vec3& x);

}  // namespace tetfsi::fluid
