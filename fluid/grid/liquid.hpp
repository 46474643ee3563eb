#pragma once
/// @file grid/liquid.hpp
/// A liquid with a free surface on the MAC grid [Chentanez06, §4]: FLIP particles carry the
/// liquid and its velocity [ZhuBridson05], its surface is the level set φ the particles
/// define at the cell centres [ZhuBridson05], the air cells (φ ≥ 0) have p = 0 and the
/// projection places the surface inside a cell with the ghost fluid [Gibou02, Enright03]
/// (grid/projection.hpp). One step (GridFluid):
///
///  1. move the particles through the last velocity (RK2), stopped before a body triangle
///     they would enter and at the box (a particle leaving through an Open face is gone);
///  2. fill the sources' cells, rebuild φ and the air cells;
///  3. particles → faces (trilinear weights), extrapolated into the air: u_old;
///  4. gravity, the boundary velocities and the projection (or the coupled solve): u;
///  5. u extrapolated into the air; each particle's velocity
///     v ← flip (v + u(x) − u_old(x)) + (1 − flip) u(x).
///
/// Why particles: a still surface stays exactly still (the particles do not move), and the
/// volume is carried by the particles rather than by a level set advected semi-Lagrangian,
/// which loses thin parts (measured in tests/fluid/test_grid_liquid.cpp).
#include <cstdint>
#include <vector>

#include "core/types.hpp"
#include "fluid/grid/grid.hpp"
#include "fluid/params.hpp"

namespace tetfsi::fluid {

struct LiquidParticles {
  MatX3 x;  ///< positions (m)
  MatX3 v;  ///< velocities (m/s)
  Index size() const { return x.rows(); }
};

/// Particles sorted by cell: those of cell c are order[start[c] .. start[c + 1]).
struct ParticleBuckets {
  std::vector<Index> start;
  std::vector<Index> order;
};
ParticleBuckets bucket_particles(const GridSpec& g, const MatX3& x);

/// How φ is read from the particles [ZhuBridson05]: φ = |x − x̄| − radius, x̄ the
/// kernel-weighted mean of the particles within two cells (the box's walls mirror them: a
/// free-slip wall is a symmetry plane). `radius` is chosen so that the surface of a seeded
/// half-space, read linearly between the cell centres beside it, lies on its boundary: φ is
/// then −face_phi and +face_phi at those two centres.
struct LiquidSurfaceParams {
  double radius = 0.0;    ///< m
  double face_phi = 0.0;  ///< m
  int per_axis = 2;
};
LiquidSurfaceParams liquid_surface_params(const GridSpec& g, int per_axis);

/// per_axis³ particles per cell on a regular lattice, at rest, where a region holds the
/// lattice point and the cell is not inside a body.
/// @throws InputError naming the region if it seeds no particle
LiquidParticles seed_liquid(const GridCells& gc, const LiquidParams& p);

/// Keep each source active at time t full: a non-solid cell whose centre is in its box and
/// that holds fewer than half its lattice gets the lattice; every particle in the box takes
/// the source's velocity. Returns the number of particles added.
Index emit_liquid(const GridCells& gc, const LiquidParams& p, double t, LiquidParticles& lp);

/// φ at the cell centres (#C, m; < 0 in the liquid; at most the kernel radius, two cells,
/// which is also its value where no particle is that near) [ZhuBridson05]. A cell on a
/// body's surface (a Solid face) holding at least half its seeding lattice is liquid whatever
/// the mean says: φ ≤ −face_phi there, as in a seeded block (the body holds no particles, the
/// mean is pulled away from it, and the liquid would rest on a layer of air).
VecX liquid_level_set(const GridCells& gc, const MatX3& x, const LiquidSurfaceParams& sp);

/// Mark the air cells (non-solid cells with φ ≥ 0) and keep φ on gc.
void set_free_surface(GridCells& gc, VecX phi);

/// The velocity at x of face velocities u: each component trilinear from its own faces
/// (clamped to the box).
Vec3 face_velocity_at(const GridSpec& g, const VecX& u, const Vec3& x);

/// Particles → faces: each face's weighted mean of the particles' velocity components
/// (trilinear weights); `known` (#F) is 1 where some particle contributed.
VecX particles_to_faces(const GridSpec& g, const LiquidParticles& lp,
                        std::vector<std::uint8_t>& known);

/// Faces whose velocity the projection set or a boundary prescribes: a face next to a fluid
/// cell, or not Interior/Open.
std::vector<std::uint8_t> liquid_faces(const GridCells& gc);

/// Fill the faces not `known` from known faces of the same axis, one ring per layer (the
/// mean of the known neighbours), `layers` rings; faces still unknown get 0.
void extrapolate_faces(const GridSpec& g, std::vector<std::uint8_t> known, int layers, VecX& u);

/// Move the particles by u over h (RK2). A move that enters a body through its surface
/// stops just before it; positions are kept inside the box, and a particle leaving through
/// an Open face is removed. Returns the number removed.
Index advect_particles(const GridCells& gc, const VecX& u, double h, LiquidParticles& lp);

/// Particles closer than k_separation × the seeding spacing (cell / per_axis).
inline constexpr double k_separation = 0.6;
/// Push apart particles closer than k_separation × the seeding spacing: FLIP particles bunch
/// where the flow compresses them and thin out elsewhere, and a thinned region's level set
/// shrinks. Measured on the dam break at a/h = 16 to T = 6.8: without this it lost 6.7 % of
/// its volume; with the walls' mirror images, at 0.8 it gained 2.9 %, at 0.7 1.7 %, at 0.6 it
/// stays within 1.0 %. One relaxation
/// sweep: each particle moves by a quarter of its overlaps, not into a body, kept in the box.
/// A regular lattice (a still pool) is left exactly in place. Returns the particles moved.
Index separate_particles(const GridCells& gc, int per_axis, LiquidParticles& lp);

/// Particle-density errors up to this share are left alone (FLIP's own fluctuations).
inline constexpr double k_density_tolerance = 0.1;
/// The liquid's density correction, as a net outflow (m³/s) for each cell (#C; zero where it
/// does not apply) that the projection gives the velocity instead of zero: FLIP particles
/// thin out where a splash or an impact spreads them (nothing pulls them back together), and
/// the level set, which sees a cell as full whatever its particle count, then gains volume
/// (the bunny's pool measured +28 % at 1.4 s without it). A cell deep in the liquid (its
/// 3 × 3 × 3 block holds no air and no body cell) whose block's mean particle count n is off
/// the seeded n₀ by e = n / n₀ − 1 beyond k_density_tolerance gets rate · (|e| − tolerance)
/// · sign(e) · V / h (rate: LiquidParams::density_correction, the share corrected per step):
/// a thinned cell draws in, a crowded one pushes out. A lattice (a still pool, a fresh
/// region) has n = n₀ exactly and gets none.
VecX liquid_volume_source(const GridCells& gc, const MatX3& x, int per_axis, double rate, double h);

/// FLIP/PIC update of the particles' velocities [ZhuBridson05]:
/// v ← flip (v + u(x) − u_old(x)) + (1 − flip) u(x).
void faces_to_particles(const GridSpec& g, const VecX& u, const VecX& u_old, double flip,
                        LiquidParticles& lp);

struct LiquidMeasures {
  double volume = 0.0;  ///< m³
  double area = 0.0;    ///< m² of the surface (the box's walls not counted)
};
/// The region where φ, trilinear between the cell centres, is negative, in the cells the
/// surface may cross: its volume along 4 × 4 vertical lines per cell, each exact (continuous
/// in φ: a surface moved by δ changes it by δ × area), and its surface's area from the sign
/// changes between 4³ samples per cell (each Σ_a ΔA_a |n_a|, n = ∇φ/|∇φ|).
LiquidMeasures liquid_measures(const GridCells& gc);

/// The most a step's volume-holding shift changes the particles' radius r, as a share of r.
inline constexpr double k_max_volume_shift = 0.25;
/// Hold the level set's volume at `target` (m³, what the particles carry): φ ← φ + δ for
/// every cell — the particles' radius r of [ZhuBridson05] becomes r − δ — with δ found by the
/// Illinois false position until the volume (liquid_measures' rule) is within 1e-4 of the
/// target (its steps, where a sampling line runs along the surface, can leave a few 1e-4);
/// |δ| ≤ k_max_volume_shift · r (sp.radius). The air flags are set from the shifted φ.
/// FLIP's level set reads thin sheets thick (a splash gains) and streams thinner than its
/// two-cell kernel thin (a pour loses), and the particles, which carry the volume exactly,
/// cannot tell it; the shift moves the whole surface so that the two agree. Returns the
/// volume it took away (m³; < 0: added); over the surface's area, the mean distance the
/// surface moved. A still pool (its level set holds the target) is left exactly as it was.
double hold_liquid_volume(GridCells& gc, double target, const LiquidSurfaceParams& sp);

}  // namespace tetfsi::fluid
