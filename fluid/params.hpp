#pragma once
/// @file params.hpp
/// Plain parameter structs of the fluid (what a scene's `fluid` section turns into). Physics
/// never sees JSON: scene/scene.cpp fills these. SI units throughout.
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "core/linear_solver.hpp"
#include "core/types.hpp"
#include "mesh/volume_mesh.hpp"

namespace tetfsi::fluid {

/// What happens on the faces of one domain patch (mesh::DomainPatch of the same index).
struct PatchConditions {
  /// Inflow patches: speed into the domain (m/s, ≥ 0); the face normal velocity is −speed
  /// (n_f points out of the fluid).
  double inflow_speed = 0.0;
  /// Inflow patches: smoke density (kg/m³ of smoke, ≥ 0) and temperature (K) of the
  /// emitted fluid; the cells on the patch are set to them every step.
  double smoke_density = 0.0;
  double temperature = 0.0;
  bool emits_temperature = false;  ///< false: the patch emits fluid at ambient temperature
  /// Inflow patches: the patch's nominal area (m², the rectangle within the box side). If > 0,
  /// the face speed is scaled by area / (area of the mesh faces tagged with the patch), so the
  /// volume flux is speed × area exactly although the mesh covers the rectangle only up to its
  /// edge length. 0: no scaling.
  double area = 0.0;
  /// Open patches: prescribed pressure (Pa, relative to ambient). For liquids it is the
  /// pressure above the hydrostatic one, ρ g·(x − hydrostatic_origin): 0 makes a still
  /// outlet at any height (a vertical side open to a reservoir, or the free top).
  double pressure = 0.0;
};

/// A volume source of smoke and heat: every cell whose centroid is in the box is set to
/// (at least) this density and temperature each step. No mass is injected.
struct SmokeSource {
  std::string name;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  double smoke_density = 1.0;      ///< kg/m³ of smoke
  double temperature = 0.0;        ///< K
  bool emits_temperature = false;  ///< false: leave the temperature alone
};

/// Where the remesher should refine for the fluid (mesh::Sizing::refine).
struct RefineParams {
  double size = 0.0;  ///< target edge (m) where smoke or vorticity is significant; 0: off
  double density_threshold = 0.01;   ///< smoke density above which a cell counts (kg/m³)
  double vorticity_threshold = 0.0;  ///< |ω| above which a cell counts (1/s); 0: ignore ω
};

/// Velocity reconstruction inside a tet from the face normal components (tet/reconstruct.hpp).
enum class Reconstruction {
  VertexLeastSquares,  ///< least squares of the face components around each vertex, then
                       ///< barycentric interpolation (continuous; exact for uniform flow)
  Whitney,             ///< lowest-order Raviart–Thomas / Whitney face elements per tet
                       ///< (exact for uniform flow, discontinuous between tets)
  VertexJets,          ///< least-squares value and gradient at each vertex, read as jets
                       ///< (continuous; exact for linear flow, e.g. a rigid rotation)
};

inline constexpr EnumNames<Reconstruction, 3> k_reconstruction_names{
    "velocity reconstruction",
    {{{Reconstruction::VertexLeastSquares, "vertex_ls"},
      {Reconstruction::Whitney, "whitney"},
      {Reconstruction::VertexJets, "vertex_jets"}}}};
/// "vertex_ls" | "whitney" | "vertex_jets". @throws InputError naming the value.
Reconstruction parse_reconstruction(const std::string& name);
const char* to_string(Reconstruction r);

/// How the transfer (advection) carries velocity and scalars from the old mesh to the new one
/// (tet/transfer.hpp).
enum class TransferScheme {
  SemiLagrangian,  ///< one RK2 back-trace per sample, first order [Stam99], [KFCO06, §4]
  MacCormack,      ///< + the back-and-forth error estimate on the old mesh, sampled at the new
                   ///< point, clamped to the local extrema [Selle08]
  Bfecc,           ///< + the same error estimate carried along the back-trace, clamped [Selle08]
};

inline constexpr EnumNames<TransferScheme, 3> k_transfer_scheme_names{
    "transfer scheme",
    {{{TransferScheme::SemiLagrangian, "semi_lagrangian"},
      {TransferScheme::MacCormack, "maccormack"},
      {TransferScheme::Bfecc, "bfecc"}}}};
const char* to_string(TransferScheme s);

/// How the transfer reads a cell scalar (smoke, temperature) at a traced point (tet/transfer.hpp).
enum class ScalarInterpolation {
  VertexFit,  ///< linear between vertex values fitted to the cells around each vertex
              ///< (tet/reconstruct.hpp cell_to_vertex_linear): continuous
  Quadratic,  ///< vertex values and gradients of quadratic fits, interpolated exactly
              ///< for quadratic fields (tet/reconstruct.hpp vertex_quadratic_fit): continuous
};

inline constexpr EnumNames<ScalarInterpolation, 2> k_scalar_interpolation_names{
    "scalar interpolation",
    {{{ScalarInterpolation::VertexFit, "vertex_fit"},
      {ScalarInterpolation::Quadratic, "quadratic"}}}};
const char* to_string(ScalarInterpolation s);

/// A region the liquid fills at the start (grid/liquid.hpp): the intersection of whichever of
/// a box [lo, hi] (when lo < hi), a sphere (when radius > 0) and the inside of a closed
/// surface (when `surface` is set) it has, at least one.
struct LiquidRegion {
  std::string name;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  Vec3 centre = Vec3::Zero();
  double radius = 0.0;
  std::filesystem::path surface_file;  ///< where `surface` was read from (scene coordinates)
  std::shared_ptr<const mesh::SurfaceMesh> surface;
  bool has_box() const { return (lo.array() < hi.array()).all(); }
  /// Inside the box and the sphere, those it has (the surface is tested by seed_liquid).
  bool contains(const Vec3& x) const {
    if (radius > 0 && (x - centre).squaredNorm() > radius * radius) return false;
    return !has_box() || ((x.array() >= lo.array()).all() && (x.array() <= hi.array()).all());
  }
};

/// A nozzle: the box [lo, hi] is kept full of liquid moving at `velocity` from `start` to
/// `stop` (s).
struct LiquidSource {
  std::string name;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  Vec3 velocity = Vec3::Zero();
  double start = 0.0;
  double stop = std::numeric_limits<double>::infinity();
};

/// A liquid with a free surface on the grid (grid/liquid.hpp): FLIP particles carry it, the
/// surface is their level set, p = 0 in the air.
struct LiquidParams {
  bool enabled = false;
  std::vector<LiquidRegion> regions;
  std::vector<LiquidSource> sources;
  /// The FLIP share of the particles' velocity update (1: pure FLIP, 0: PIC) [ZhuBridson05].
  double flip = 0.95;
  int particles_per_axis = 2;  ///< seeded per cell and axis (2: 8 per cell)
  /// Share of a deep cell's particle-density error the projection corrects per step
  /// (liquid_volume_source); 0: off.
  double density_correction = 0.0;
  /// Shift the level set each step so that it holds the volume the particles carry
  /// (hold_liquid_volume); false: the level set as the particles give it.
  bool hold_volume = true;
};

/// The fluid's physics and numerics.
struct FluidParams {
  double density = 1.2;  ///< ρ (kg/m³): 1.2 for air, 1000 for water
  /// ρ (kg/m³) of the fluid in enclosed regions: regions bounded only by solid faces, i.e.
  /// a liquid sealed inside a closed body (a toy, a water balloon) in air. 0: `density`.
  /// Regions never exchange fluid, so each keeps its own density (cell_fluid_density).
  double enclosed_density = 0.0;
  /// Gravity acting on the fluid itself (m/s², liquids). For a single-density fluid it is a
  /// pure gradient and is carried by the hydrostatic part of the pressure: p = p_dyn + ρ g·x
  /// (exact; the velocity never sees it). Smoke scenes use buoyancy instead.
  Vec3 gravity = Vec3::Zero();
  /// Where the hydrostatic pressure ρ g·(x − origin) is zero (m). Scenes put it at the top
  /// of the fluid box (the box corner highest against gravity), so that a liquid's total
  /// pressure is 0 at an open top and positive below.
  Vec3 hydrostatic_origin = Vec3::Zero();
  Vec3 up = Vec3(0.0, 0.0, 1.0);  ///< unit "up" for buoyancy (scenes: −gravity direction)
  /// Boussinesq buoyancy on the faces, (−α ρ_smoke + β (T − T_ambient)) up
  /// [Fedkiw01, Eq. (8)]: α in m⁴/(kg s²) (so that α ρ_smoke is m/s²),
  /// β in m/(s² K).
  double buoyancy_alpha = 0.0;
  double buoyancy_beta = 0.0;
  double ambient_temperature = 0.0;  ///< K (any offset: only T − T_ambient matters)
  /// Vorticity confinement strength ε (dimensionless; 0 = off) [Fedkiw01, Eq. (11)]:
  /// f = ε h_cell (N × ω), N = ∇|ω| / |∇|ω||.
  double vorticity_confinement = 0.0;
  /// Dissipation per second of smoke density and of T − T_ambient (0 = none).
  double smoke_decay = 0.0;
  double temperature_decay = 0.0;
  /// Whitney by default: measured (tests/fluid/test_simulation.cpp) it dissipates 7–9× less
  /// kinetic energy on Taylor–Green (0.026 vs 0.197 /s at 9k cells, 0.011 vs 0.099 at 61k) and
  /// keeps more angular momentum in rigid rotation than vertex least squares.
  Reconstruction reconstruction = Reconstruction::Whitney;
  /// How the transfer carries smoke density and temperature, and the face velocities
  /// (tet/transfer.hpp). Measured (docs/results/fluid.md, transfer): BFECC keeps 7× more of a
  /// rotating blob's peak than semi-Lagrangian at 119k cells, clamped (no new extrema), so it
  /// is the scalars' default; the second-order velocity options are not the default (they
  /// lose more on the coarse Taylor–Green and gain energy in the fine rotation).
  TransferScheme scalar_transfer = TransferScheme::Bfecc;
  TransferScheme velocity_transfer = TransferScheme::SemiLagrangian;
  /// How the scalars' transfer reads the old (and, for the second-order schemes, the
  /// intermediate) cell values at a traced point. Quadratic by default: measured (the
  /// docs/results/fluid.md, transfer) with BFECC it keeps 91 % of a rotating blob's peak at 119k
  /// cells (51 % with the linear reading), a fifth of the L1 error and more of the mass.
  ScalarInterpolation scalar_interpolation = ScalarInterpolation::Quadratic;
  /// The transfer takes the old pressure's acceleration at the midpoint of each back-trace
  /// rather than at its end (tet/transfer.hpp): second order in time along curved paths.
  bool pressure_along_path = false;
  /// δ: cells joined by an interior face with d_f ≤ δ × (its mean edge) share one pressure
  /// unknown (co-spherical cells, A_f/d_f = ∞; tet/operators.hpp). Larger values merge cells
  /// whose circumcentres differ, which costs accuracy near solids (measured: a uniform
  /// acceleration left 0.5 h|a| at δ = 0.01, 6e-12 at 1e-6).
  double min_dual_fraction = 1e-6;
  /// A liquid with a free surface (the grid only; `gravity` then acts on the velocity and
  /// the pressure is the whole pressure, 0 at the surface).
  LiquidParams liquid;
  /// The pressure solve: `amg` (hypre BoomerAMG + CG) by default; `cholmod`, `cg_ic`,
  /// `bicgstab_ilut` or `umfpack` selectable.
  SolverKind solver = SolverKind::Amg;
  double solver_rel_tol = 1e-8;
  int solver_max_iterations = 500;
  std::vector<PatchConditions> patches;  ///< one per mesh::FluidDomain::patches entry
  std::vector<SmokeSource> sources;
  RefineParams refine;
};

}  // namespace tetfsi::fluid
