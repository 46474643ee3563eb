#pragma once
/// @file reconstruct.hpp
/// Velocity vectors from face normal components (docs/dev/architecture.md, one time step, step 3)
/// [KFCO06, §4]:
///  - VertexLeastSquares: at each vertex v, U_v = argmin Σ_{f ∋ v} A_f (n_f · U − u_f)²
///    (a 3 × 3 solve; every face around the vertex, boundary faces with their prescribed
///    values), then u(x) = Σ_i λ_i U_i inside a tet. Continuous; exact for uniform flow.
///  - Whitney (RT0) [Bossavit88]: in tet t with vertices x_i and outward fluxes Φ_k = s_tk A_k u_k
///  through
///    the face opposite x_k, u(x) = Σ_k Φ_k (x − x_k) / (3 V_t). Reproduces every face flux
///    exactly and uniform flow exactly; discontinuous between tets. A flat cell (volume below
///    2 % of the regular tet on its longest edge — the slivers a remesh can leave against a
///    solid) would amplify round-off in its fluxes by 1/V; it takes the vertex
///    least-squares values instead (also exact for uniform flow).
///  - VertexJets: at each vertex v the weighted least-squares linear field U_v + G_v (x − x_v)
///    fitted to the normal components of the faces of the cells around v (vertex_velocity_jets),
///    read in tet t as u(x) = Σ_i λ_i (U_i + ½ G_i (x − x_i)) (the scalars' jets of
///    sample_jets) plus the Whitney field of the faces' residuals u_f − (face mean of n_f ·
///    the jets), so that every face's flux is kept as with Whitney. Exact for linear fields
///    (a rigid rotation, a shear), second order for smooth ones; the two first-order
///    readings above are exact for uniform flow only.
/// Which one the fluid uses is FluidParams::reconstruction; the tests measure all three.
#include <utility>
#include <vector>

#include "core/types.hpp"
#include "fluid/params.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// A reconstructed velocity field on a fixed mesh (keeps a reference to it).
class VelocityField {
 public:
  /// @param u #F face normal velocities (m/s)
  VelocityField(const mesh::TetMesh& m, const VecX& u, Reconstruction kind);

  /// Velocity in tet t at barycentric coordinates λ (Σ λ = 1) (m/s).
  Vec3 at(Index t, const Vec4& bary) const;
  /// n · u at (t, λ), for the transfer. Whitney: clamped to the range of n · U_v over the
  /// tet's 4 vertex least-squares velocities U_v, widened by one range width on each side
  /// (a clamp in the manner of [Selle08]): RT0's corner values overshoot in poorly shaped
  /// cells, and semi-Lagrangian sampling of them gained energy (+51 % per revolution of a
  /// rigid rotation at 98k cells without the clamp; −12 % with it, −47 % with the bare range).
  double normal_at(Index t, const Vec4& bary, const Vec3& n) const;
  /// The range normal_at clamps to in tet t: n · U_v over the tet's 4 vertex least-squares
  /// velocities, widened by one range width on each side (both kinds; the second-order
  /// transfer clamps its corrected values to it [Selle08]).
  std::pair<double, double> normal_range(Index t, const Vec3& n) const;
  /// Velocity at the centroid of every tet (#T × 3).
  MatX3 cell_velocities() const;
  /// Vertex velocities (#V × 3): the least-squares U_v (VertexLeastSquares), the jets'
  /// U_v (VertexJets), or the volume-weighted mean of the adjacent tets' RT0 vertex values
  /// (Whitney).
  MatX3 vertex_velocities() const;
  /// The vertex velocities the clamp and the vorticity use (#V × 3): the vertex
  /// least-squares velocities (VertexLeastSquares, and Whitney, which keeps them for its flat
  /// cells and its clamp), or the jets' vertex values U_v (VertexJets).
  const MatX3& least_squares_vertices() const {
    return m_kind == Reconstruction::Whitney ? m_vertex_ls : m_values;
  }
  /// |curl u| per tet (#T, 1/s) of the linear interpolation of least_squares_vertices().
  VecX vorticity_magnitude() const;
  Reconstruction kind() const { return m_kind; }

 private:
  const mesh::TetMesh* m_mesh;
  Reconstruction m_kind;
  /// VertexLeastSquares and VertexJets: #V × 3 vertex values; Whitney: 4#T × 3, the RT0 field of
  /// tet t at its corner i in row 4t + i (the field is affine in each tet, so u = Σ λ_i u_ti).
  MatX3 m_values;
  MatX3 m_vertex_ls;  ///< Whitney: the vertex least-squares velocities, for normal_at's clamp
  std::vector<Mat3> m_grad;  ///< VertexJets: G_v per vertex (1/s)
  MatX3 m_corners;           ///< VertexJets: the Whitney field of the faces' residuals, as m_values
};

/// The jets of VertexJets: at each vertex v, U_v and G_v minimising
/// Σ_f w_f (n_f · (U_v + G_v (x_f − x_v)) − u_f)² over the faces f of the cells around v
/// (boundary faces with their prescribed values; x_f the face centroid, w_f = A_f / (¼ +
/// |x_f − x_v|²/L²), L the faces' rms distance; a vertex on a wall or a solid adds the faces
/// of the next ring of cells). Exact for linear fields where the 12 × 12 system is well
/// determined; elsewhere, and at vertices where boundary faces of different kinds or
/// patches meet (the prescribed values jump there), vertex_least_squares's U_v with G_v = 0.
/// Sets U (#V × 3) and G (#V).
void vertex_velocity_jets(const mesh::TetMesh& m, const VecX& u, MatX3& U, std::vector<Mat3>& G);

/// Per-vertex least-squares velocities (#V × 3), see the file comment.
MatX3 vertex_least_squares(const mesh::TetMesh& m, const VecX& u);

/// Volume-weighted average of cell values at the vertices (#V) — for scalar interpolation.
VecX cell_to_vertex(const mesh::TetMesh& m, const VecX& cell_values);

/// Vertex values of a cell field for continuous linear interpolation (#V): at each vertex v
/// the linear least-squares fit c ≈ a + g · (x̄_t − x_v) over the cells around v (weights
/// V_t), a taken and clamped to the min/max of those cells (the clamp of [Selle08]); where the fit
/// is not determined (fewer than 4 cells, or centroids in a plane) the volume-weighted mean. Exact
/// for linear fields, so interpolating it diffuses only the curvature of a field (the plain mean of
/// cell_to_vertex also flattens its slopes); the clamp and the barycentric interpolation
/// make no new extrema. (A per-cell clamped linear reconstruction kept fronts sharper but
/// left cell-to-cell speckle in the smoke.)
VecX cell_to_vertex_linear(const mesh::TetMesh& m, const VecX& cell_values);

/// A cell field read at any point through vertex values and gradients fitted to the cells
/// around each vertex (see vertex_quadratic_fit).
struct VertexJets {
  VecX value;   ///< #V: the fit's value at the vertex, clamped to lo..hi
  MatX3 grad;   ///< #V × 3: the fit's gradient there (units per m)
  VecX lo, hi;  ///< #V: the range of the cells around the vertex
};

/// What vertex_quadratic_fit needs of a mesh whatever the field: the cells around each
/// vertex (cells[start[v]] .. cells[start[v + 1] − 1]) and every cell's centroid. Build it
/// once per mesh for several fields.
struct VertexStencils {
  std::vector<Index> start, cells;
  MatX3 centroids;  ///< #T × 3
};
VertexStencils vertex_stencils(const mesh::TetMesh& m);

/// At each vertex v the weighted least-squares quadratic c ≈ a + g·d + ½ dᵀ H d
/// (d = x̄_t − x_v, weights V_t / (¼ + |d|²/L²), L the cells' rms distance) over the cells
/// around v and their face neighbours (the cells around v alone can lie on a sphere about it,
/// as in the regular lattice, which leaves a and tr H apart); where that is not determined,
/// the linear fit on the same cells, and where neither is, their mean. Exact for quadratic
/// fields where the fit is determined. Vertices whose cells hold one value take it (g = 0).
VertexJets vertex_quadratic_fit(const mesh::TetMesh& m, const VertexStencils& stencils,
                                const VecX& cell_values);

/// The value at barycentrics λ of tet t: Σ_i λ_i clamp(a_i + ½ g_i · (x − x_i), lo_i, hi_i).
/// Exact for quadratic fields: with g_i = g(x) − H (x − x_i) the terms sum to
/// f(x) − ½ g(x) · Σ λ_i (x − x_i) = f(x). Continuous across faces (a face's value depends on
/// its own vertices only), and within the range of the cells around the tet's vertices.
double sample_jets(const mesh::TetMesh& m, const VertexJets& j, Index t, const Vec4& bary);

/// The gradient of cell_to_vertex_linear's fit at every vertex (#V × 3, units of the values
/// per m), with the cell values sitting at `points` (#T × 3: e.g. the circumcentres of
/// pressures): exact for linear fields; zero where the fit is not determined or the values
/// are uniform.
MatX3 vertex_gradients(const mesh::TetMesh& m, const VecX& cell_values, const MatX3& points);

/// Gradients of the barycentric functions of tet t (row i = ∇λ_i, 1/m).
Eigen::Matrix<double, 4, 3> barycentric_gradients(const mesh::TetMesh& m, Index t);

/// curl of the vertex-interpolated field per tet (#T × 3, 1/s): ω_t = Σ_i ∇λ_i × U_i.
MatX3 cell_vorticity(const mesh::TetMesh& m, const MatX3& vertex_velocity);

}  // namespace tetfsi::fluid
