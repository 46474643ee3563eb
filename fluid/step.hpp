#pragma once
/// @file step.hpp
/// What every discretisation of the fluid shares about a step: the bodies' surface motion it
/// is given, the report of its pressure projection and of the whole step (the stats.csv
/// columns), and the hydrostatic part of a liquid's pressure.
#include "core/types.hpp"

namespace tetfsi::fluid {

/// The velocity of every solid surface vertex, per body, in the vertex numbering of the
/// mesh::SolidSurface the mesh was built from (TetMesh::face_body / face_triangle refer to
/// it). The triangles are needed to interpolate at the Solid faces.
struct SolidSurfaceMotion {
  MatX3i triangles;  ///< #Ts × 3, as in mesh::SolidSurface
  MatX3 velocity;    ///< #Vs × 3 (m/s)
};

/// Diagnostics of one fluid step (stats.csv columns).
struct FluidStepReport {
  bool converged = true;           ///< the pressure solve converged
  int iterations = 0;              ///< pressure-solve iterations
  double residual = 0.0;           ///< its true relative residual
  double divergence_before = 0.0;  ///< max_t |(D u*)_t| before the projection (1/s)
  double divergence_after = 0.0;   ///< max_t |(D u)_t| after it (1/s)
  double kinetic_energy = 0.0;     ///< ½ ρ Σ_t V_t |u_t|², u_t reconstructed at centroids (J)
  double smoke_mass = 0.0;         ///< Σ_t V_t ρ_smoke,t (kg)
  double inflow_flux = 0.0;        ///< −Σ A_f u_f over Inflow faces (m³/s, > 0 into the box)
  double outflow_flux = 0.0;       ///< Σ A_f u_f over Open faces (m³/s, > 0 out of the box)
  double solid_flux = 0.0;         ///< Σ A_f u_f over Solid faces (m³/s)
  double max_speed = 0.0;          ///< max |u_f| (m/s)
  double cfl = 0.0;                ///< max over cells of h |u_t| / (cell edge)
  Index traces_clamped = 0;        ///< back-traces stopped at a wall / solid / the box
  /// A liquid with a free surface (grid/liquid.hpp; 0 without): its volume (m³), surface
  /// area (m²) and particles.
  double liquid_volume = 0.0;
  /// (volume − expected) / expected, expected = the first volume + the particles emitted
  /// less those gone through Open faces, at their seeding volume (cell / per_axis³)
  double liquid_volume_drift = 0.0;
  double liquid_area = 0.0;
  /// The shift of the level set that held the volume this step (m, > 0: the surface moved
  /// into the liquid; fluid.liquid.hold_volume, 0 without it)
  double liquid_shift = 0.0;
  Index liquid_particles = 0;
  /// Seconds of the step's surface tracking (inside the transfer phase): the particles'
  /// move, separation and sources; the level set, free surface and density correction; the
  /// particles' velocity to the faces and its extrapolation.
  double liquid_advect_s = 0.0, liquid_surface_s = 0.0, liquid_p2g_s = 0.0;
};

/// The pressure projection of a step [Chentanez06, Eq. (2)]: the solve and the divergence
/// before and after (fluid::project on the tet mesh, fluid::grid_project on the MAC grid).
struct ProjectionReport {
  bool converged = false;
  int iterations = 0;
  double residual = 0.0;           ///< true relative residual of the pressure solve
  double divergence_before = 0.0;  ///< max_t |(D u*)_t| (1/s)
  double divergence_after = 0.0;   ///< max_t |(D u)_t| (1/s)
  Index pinned_regions = 0;        ///< regions without an Open face (pressure pinned)
  /// Largest |Σ_t V_t (D u*)_t| / Σ_t |V_t (D u*)_t| over pinned regions: the net boundary flux
  /// of a closed region, which incompressibility cannot absorb; it is removed (spread over the
  /// region's cells in proportion to volume) before the solve and reported here.
  double incompatibility = 0.0;
  Index groups = 0;          ///< pressure unknowns (≤ #T)
  Index internal_faces = 0;  ///< faces inside groups
  double assembly_s = 0.0, setup_s = 0.0, solve_s = 0.0;
};

/// Hydrostatic part ρ g·(x − origin) of a liquid's pressure (Pa) at x (0 if the fluid has no
/// gravity).
inline double hydrostatic_pressure(double rho, const Vec3& gravity, const Vec3& origin,
                                   const Vec3& x) {
  return rho * gravity.dot(x - origin);
}

}  // namespace tetfsi::fluid
