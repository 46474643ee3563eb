#pragma once
/// @file transfer.hpp
/// Transfer = advection from the old mesh onto the new one (docs/dev/architecture.md, one time
/// step, step 3), semi-Lagrangian and so unconditionally stable [Stam99], [KFCO06, §4]: every face
/// centre of the new mesh is traced back through the old mesh's reconstructed velocity (RK2) and
/// takes the normal component of the old field there; cell scalars (smoke, temperature) are
/// traced from the cell centroids and read there through vertex jets fitted quadratically to
/// the old cells (ScalarInterpolation::Quadratic, reconstruct.hpp vertex_quadratic_fit: exact
/// for quadratic fields) or linearly between fitted vertex values (VertexFit,
/// cell_to_vertex_linear: exact for linear fields); both clamped, so no new extrema.
///
/// A scalar back-trace stopped at an Inflow face takes the patch's emitted smoke and
/// temperature (TransferInput::inflow_density): that is how jets emit.
///
/// Back-traces never cross the fluid boundary: the path is walked tet by tet through the old
/// mesh and stops where it would leave the fluid (at a wall, a solid face or the box). So
/// smoke cannot jump through a thin solid, and nothing is read from inside a solid.
#include <vector>

#include "core/types.hpp"
#include "fluid/params.hpp"
#include "mesh/locate.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

struct TracePoint {
  Index tet = -1;
  Vec4 bary = Vec4::Zero();
  bool clamped = false;  ///< the path was stopped at the fluid boundary
  Index exit_face = -1;  ///< clamped: the boundary face it was stopped at
};

/// Barycentric coordinates in the tets of a fixed mesh, from per-tet inverse edge matrices
/// computed once (the walks evaluate them millions of times per transfer). Keeps a reference
/// to the mesh.
class Barycentrics {
 public:
  explicit Barycentrics(const mesh::TetMesh& m);
  /// λ of x in tet t (Σ λ = 1; all ≥ 0 inside).
  Vec4 operator()(Index t, const Vec3& x) const;
  const mesh::TetMesh& mesh() const { return *m_mesh; }

 private:
  const mesh::TetMesh* m_mesh;
  std::vector<Mat3> m_inv;  ///< E⁻¹ with E = [x1 − x0, x2 − x0, x3 − x0] per tet
};

/// Walk the straight path from the point at (tet, bary) of `bary.mesh()` to x1 through face
/// neighbours; return where x1 is, or the point where the path leaves the fluid (clamped).
TracePoint walk_segment(const Barycentrics& bary, const TracePoint& from, const Vec3& x1);

/// Position of a trace point (m).
Vec3 position(const mesh::TetMesh& m, const TracePoint& p);

struct TransferInput {
  const mesh::TetMesh* old_mesh = nullptr;
  const VecX* old_u = nullptr;  ///< #F_old face normal velocities
  const VecX* old_density = nullptr;
  const VecX* old_temperature = nullptr;
  Reconstruction reconstruction = Reconstruction::VertexLeastSquares;
  /// First-order semi-Lagrangian, or one of the second-order schemes of [Selle08] (see
  /// `transfer`), for the cell scalars and for the face velocities.
  TransferScheme scalar_scheme = TransferScheme::SemiLagrangian;
  TransferScheme velocity_scheme = TransferScheme::SemiLagrangian;
  /// How a scalar is read at a traced point: linear between fitted vertex values, or through
  /// quadratic vertex jets (params.hpp ScalarInterpolation; FluidParams defaults to the jets).
  ScalarInterpolation scalar_interpolation = ScalarInterpolation::VertexFit;
  /// The old pressure (#T_old, Pa) and fluid density per old cell (#T_old, kg/m³). When both
  /// are given, the velocity transfer takes the old pressure's acceleration along the path by
  /// the midpoint rule instead of at the path's end (see `transfer`).
  const VecX* old_pressure = nullptr;
  const VecX* old_cell_density = nullptr;
  /// What enters through the old mesh's Inflow faces, by patch (TetMesh::face_patch): a
  /// scalar back-trace stopped at an Inflow face takes these values (the fluid that came in
  /// through the patch during the step). Empty: the boundary value is interpolated as
  /// anywhere else.
  std::vector<double> inflow_density, inflow_temperature;
};

struct TransferOutput {
  VecX u;             ///< #F_new: n_f · u_old(x_back) on every face
  VecX density;       ///< #T_new
  VecX temperature;   ///< #T_new
  Index clamped = 0;  ///< traces stopped at the fluid boundary
};

/// Advect the old state by h onto `new_mesh` (see the file comment).
///
/// The second-order schemes [Selle08] go old mesh → new mesh → old mesh: the first-order
/// values φ̂ on the new mesh are carried back (old points traced forward through the old
/// velocity, located in the new fluid) to give φ̄ on the old mesh; e = (φⁿ − φ̄)/2 estimates
/// the transfer's error, and φ = φ̂ + e, with e read at the new point (MacCormack) or at its
/// back-trace's end (BFECC, i.e. the transfer of φⁿ + e), clamped to the old values around
/// the back-trace's end (face velocities: normal_range of the old field; scalars: the cell and
/// its face neighbours, widened to include φ̂ so that a sharp first-order value is kept). The
/// velocity's error field is reconstructed by vertex least squares (smooth) whatever the transfer's
/// reconstruction. Samples whose trace touched the boundary or an Inflow patch stay first order.
///
/// The pressure along the path (old_pressure given): the projection applies the pressure
/// acceleration −∇p/ρ at the end of the path only, where the flow felt it all along: a vector
/// carried round a curved path keeps its direction and the projection then removes the part
/// that no longer points along the flow (a rigid rotation loses 1 − cos(Ω h) of its angular
/// momentum per step). Adding h/ρ (∇pⁿ(x) − ∇pⁿ(x_mid)) · n_f — the old pressure's
/// acceleration at the RK2 midpoint of the back-trace instead of at x — integrates it by the
/// midpoint rule; the new projection then only adds the change of pressure. ∇p is the vertex
/// fit of vertex_gradients, interpolated linearly; faces whose trace touched the boundary
/// take no correction.
TransferOutput transfer(const TransferInput& in, const mesh::TetMesh& new_mesh, double h);

}  // namespace tetfsi::fluid
