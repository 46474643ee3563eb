#pragma once
/// @file half_cells.hpp
/// The interface half cells' lengths (coupled_system.hpp, "Interface half cells"), with the
/// spreading of a curved body's normals counted.
///
/// The half cell of a Solid face is the pyramid from the face (area A_f) to its cell's
/// circumcentre, of height δ_f = max(d_f, 0), and its fluid moves with the face's normal
/// velocity u_n = (H u)_f. Taking u_n for the whole pyramid overstates its kinetic energy off a
/// convex body: for a divergence-free flow the normal component falls off the wall as
/// ∂u_n/∂n = −2H u_n − ∇_s·u_t, and the first term, the spreading of the normals (2H, the
/// mean curvature), is the body's geometry. Along the tube that the face sweeps when offset by
/// s along the body's vertex normals (its area A(s)), that part keeps the flux A u_n, so
/// u_n(s) = u_n(0) A(0)/A(s); the pyramid's cross-sections are A_f (1 − s/δ)², and its
/// kinetic energy ½ ρ ∫ 3 u_n² dV (the dual cells' share of |u|², as in Σ_f A_f d_f u_f²) is
/// ½ ρ A_f δ_eff u_n(0)² with
///
///     δ_eff = δ · 3 ∫₀¹ (1 − t)² (A(0) / A(tδ))² dt.
///
/// For a sphere of radius a, A(s)/A(0) = (1 + s/a)² and the integral is a/(a + δ): δ_eff =
/// δ a/(a + δ) (inside a spherical cavity δ a/(a − δ)); on a plane δ_eff = δ. The second term (the
/// tangential flow's surface divergence) depends on the flow and is left to the cells. A(s)/A(0) is
/// held at or above ½ (a cavity whose radius of curvature is below 2δ), so δ_eff ≤ 4δ.
#include <vector>

#include "core/types.hpp"
#include "fluid/tet/interface.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::coupling {

/// The area of a body triangle offset by s along its vertex normals, into the fluid:
/// A(s)/A(0) = 1 + c1 s + c2 s² (c1 = 2H, c2 the Gauss curvature, on a smooth surface).
struct TubeSpreading {
  double c1 = 0.0;  ///< 1/m
  double c2 = 0.0;  ///< 1/m²
};

/// The tube of the triangle (p0, p1, p2) with unit vertex normals (n0, n1, n2), s measured
/// along the normals (negate them to measure the other way).
TubeSpreading tube_spreading(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& n0,
                             const Vec3& n1, const Vec3& n2);

/// δ_eff / δ for a half cell of height δ (m) on that tube (file comment).
double half_cell_spreading(const TubeSpreading& tube, double delta);

/// δ_eff (m) of every Solid face of area > 0 (0 elsewhere, #F). x[b]: body b's node positions
/// (#n_b × 3, the geometry its vertex normals, area-weighted over its interface triangles,
/// come from); empty (or beyond x): body b's half cells keep δ_f.
VecX half_cell_lengths(const mesh::TetMesh& m, const std::vector<fluid::BodyInterface>& bodies,
                       const std::vector<MatX3>& x);

}  // namespace tetfsi::coupling
