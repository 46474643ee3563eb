#pragma once
/// @file scene.hpp
/// JSON scene files → plain structs. Strict: an unknown key is an error naming its JSON path
/// and the nearest valid key; a wrong type, an out-of-range value or a missing file is an
/// error naming the path and the problem. Relative paths resolve against the scene file's
/// folder. Physics never sees JSON: `build_world` turns a Scene into solid:: objects.
///
/// Every key with its type, default, range, unit and meaning is declared once, in the tables
/// of scene_keys.hpp (`tetfsi scene --keys`); the parser, the resolved scene and README.md's
/// key tables come from them. Schema (every key optional unless marked):
/// ```json
/// {
///   "name": "sheet_sag",
///   "description": "free text, kept in the resolved scene",
///   "mode": "dynamic" | "static",
///   "time":   { "dt": 0.005, "end_time": 2.0 }            // or "steps": 400 (not both)
///   "output": { "every": 4, "compression": "lz4" | "zlib" | "none",
///               "checkpoint_every": 0, "keep_checkpoints": 2 },
///   "gravity": [0, 0, -9.81],
///   "solver": { "linear": "cholmod", "rel_tol": 1e-8, "max_iterations": 1000 },
///   "solid":  { "integrator": "linearized" | "newton" | "modified_newton" | "bfgs",
///               "trapezoid": "paper" | "midpoint",             // linearized only
///               "rtol": 1e-3, "etol": 1e-5, "stol": 0.5,       // [BatheSonnad80, Eqs. (10)-(13)]
///               "max_iterations": 30, "max_updates": 20, "line_search": true,
///               "reform": "step" | "run" },
///   "static": { "load_steps": 1, "rel_tol": 1e-9, "max_iterations": 60 },
///   "bodies": [ {                              // required, at least one (without "fluid")
///       "name": "sheet",                                   // required, unique
///       "mesh": { "box": { "lo": [..], "hi": [..], "cells": [nx, ny, nz] } }
///             | { "file": "meshes/bar.msh" }               // .msh .node .ele .vtu
///             | { "surface": "meshes/ball.off", "cell_size": 0.02 },  // .off .obj .stl
///             | { "sphere": { "center": [..], "radius": 0.1, "subdivisions": 2 } }
///             | { "shell": { "center": [..], "inner_radius": 0.08, "outer_radius": 0.1,
///                            "subdivisions": 2, "layers": 1 } }   // cavity: fluid inside
///             | { "hollow_box": { "lo": [..], "hi": [..], "thickness": 0.01,
///                                 "cells": [nx, ny, nz] } }       // one closed box cavity
///             | { "tube": { "center": [..], "axis": "z", "inner_radius": 0.08,
///                           "outer_radius": 0.1, "length": 0.8,
///                           "cells": [radial, around, axial] } },  // open at both ends
///       "transform": { "scale": 1.0, "rotate_deg": [0, 0, 0], "translate": [0, 0, 0] },
///       "material": { "density": 1000, "youngs_modulus": 1e5, "poisson_ratio": 0.3,
///                     "rayleigh_alpha": 0, "rayleigh_beta": 0 },
///       "pins":  [ { "box": { "lo": [..], "hi": [..] }, "axes": "xyz" }
///                | { "nodes": [0, 5], "axes": "z" } ],
///       "loads": [ { "box": { "lo": [..], "hi": [..] }, "total_force": [0, 0, -1] }
///                | { "nodes": [..], ... } ],
///       "initial_velocity": [0, 0, 0],
///       "kinematic": { "velocity": [0, 0, 0],              // m/s: moved by the scene, not
///                      "angular_velocity_deg": [0, 0, 0],  // the FEM (deg/s about the axis
///                      "center": [cx, cy, cz] }            // through center; default: the
///                                                          // mean of the rest nodes)
///   } ],
///   "obstacles": [ { "type": "plane", "point": [0,0,0], "normal": [0,0,1],
///                    "restitution": 0.3, "friction": 0.5 }
///                | { "type": "box", "lo": [..], "hi": [..], "restitution": .., "friction": .. } ]
///                  // each may have a "name" (default "plane0", "box1", ...)
///   "fluid": {                      // optional: a fluid mesh rebuilt around the bodies each step
///     "domain": { "lo": [..], "hi": [..],                   // required, lo < hi (m)
///                 "default": "wall" | "inflow" | "open",    // kind of box faces not on a patch
///                 "patches": [ { "name": "jet", "kind": "inflow", "side": "-x",
///                                "lo": [a, b], "hi": [c, d],
///                                "speed": 0,          // inflow only: m/s into the domain
///                                "smoke": 0,          // inflow only: emitted smoke (kg/m^3)
///                                "temperature": 300,  // inflow only: emitted T (K); default:
///                                                     //   ambient (emits_temperature = false)
///                                "pressure": 0 } ] }, // open only: prescribed pressure (Pa)
///     "mesh":   { "surface_size": 0.05, "far_size": 0.2, "grading": 0.5, "max_cells": 0 },
///     "density": 1.2,                                       // kg/m^3
///     "enclosed_density": 0,     // kg/m^3 of liquid sealed inside closed bodies; 0: density
///     "gravity": false,          // true: the fluid feels the scene's gravity (liquids)
///     "buoyancy": { "alpha": 0, "beta": 0, "ambient_temperature": 0 },
///     "vorticity_confinement": 0,
///     "decay": { "smoke": 0, "temperature": 0 },            // per second
///     "reconstruction": "whitney" | "vertex_ls" | "vertex_jets",
///     "transfer": { "scalars": "bfecc", "velocity": "semi_lagrangian",  // or "maccormack"
///                   "scalar_interpolation": "quadratic",  // or "vertex_fit"
///                   "pressure_along_path": false },
///     "min_dual_fraction": 1e-6,
///     "solver": { "linear": "amg", "rel_tol": 1e-8, "max_iterations": 500 },  // pressure
///     "sources": [ { "name": "src0", "box": { "lo": [..], "hi": [..] },
///                    "smoke": 1.0, "temperature": 310 } ],  // temperature: optional
///     "refine": { "size": 0, "density_threshold": 0.01, "vorticity_threshold": 0 }
///   },
///   "coupling": {                   // fluid scenes only: how the fluid and the bodies interact
///     "scheme": "simultaneous" | "splitting" | "bfgs" | "modified_newton" | "newton" | "none",
///     "solver": "schur_amg" | "umfpack" | "bicgstab_ilut" | "symmetric_umfpack",
///     "rel_tol": 1e-10, "max_iterations": 500,              // of the coupled solve
///     "conserve_volume": true    // enclosed regions keep their volume (coupled_system.hpp)
///   }
/// }
/// ```
/// Rules beyond the types: a pin or load gives exactly one of "box" / "nodes"; a load needs
/// "total_force"; selection boxes may be flat (lo ≤ hi, e.g. one face of a box body; they
/// include nodes within 1e-9 m), mesh and obstacle boxes need lo < hi; sphere radius > 0,
/// subdivisions 0..6 (surface edges about radius / 2^s; default 2); shell 0 < inner_radius <
/// outer_radius, subdivisions 0..7 (default 2), layers >= 1 (default 1); hollow_box
/// thickness > 0 and 2 thickness < hi − lo in every axis, cells as for box (default [1, 1,
/// 1]); tube (mesh::make_tube: centre ± length / 2 along axis) axis "x", "y" or "z" (default
/// "z"), 0 < inner_radius < outer_radius, length > 0, cells required: radial >= 1, around
/// >= 6, axial >= 1; the transform applies to generated meshes as to any other; a key given
/// twice in one object is an error (load_scene only: nlohmann would keep the last silently).
/// Fluid: a patch's "side" is one of "-x", "+x", "-y", "+y", "-z", "+z"; its rectangle
/// lo < hi is in the side's two other coordinates in increasing axis order (side ±y: (x, z))
/// and must overlap that face of the box; patch names are unique (default "patch<i>");
/// 0 < surface_size <= far_size (m), grading > 0, max_cells >= 0 (0: no budget). Whether the
/// bodies lie inside the box is checked by the run (their positions change every step).
/// Fluid physics (fluid::FluidParams, units there): speed, smoke >= 0; density > 0;
/// enclosed_density >= 0 (0: the same as density); buoyancy alpha, beta >= 0;
/// vorticity_confinement, decay rates >= 0; 0 < min_dual_fraction
/// <= 0.1; solver.linear one of solver_names(), rel_tol > 0, max_iterations >= 1; a source box
/// has lo < hi, overlaps the fluid box and a unique name (default "source<i>"), smoke >= 0;
/// refine.size >= 0 (0: off) and <= mesh.far_size, thresholds >= 0. FluidParams::up is
/// −gravity / |gravity| (+z for zero gravity) whatever "gravity" says.
/// Coupling (coupling/coupled_step.hpp): only with a "fluid" section. "simultaneous" (the
/// default of a dynamic scene with at least one deformable, i.e. non-kinematic, body),
/// "splitting" and the iterated schemes "bfgs", "modified_newton", "newton" [BatheSonnad80]
/// (with the solid.* tolerances) are two-way: the fluid pushes the bodies. "none" (the default
/// otherwise) is one-way: the bodies step alone and the fluid follows them. solver one of
/// coupling::k_coupled_solver_names.names(), rel_tol > 0, max_iterations >= 1, conserve_volume a
/// boolean. A static scene ignores the coupling (the run warns if it is two-way).
/// Solid (solid/nonlinear_trapezoid.hpp, core/equilibrium.hpp): "integrator" is how the bodies
/// step when they step alone (a solid-only or one-way scene): "linearized" (the default,
/// [Chentanez06, Eqs. (4)–(5)], one linear solve) or the nonlinear trapezoidal rule iterated
/// to equilibrium by full Newton, modified Newton or BFGS [BatheSonnad80]. "trapezoid" only
/// applies to the linearized integrator: giving it with another is an error; so is a
/// nonlinear integrator in a two-way coupled scene, unless it names the coupling scheme (the
/// coupled step integrates the bodies by its scheme). The iteration's
/// tolerances (EquilibriumOptions; also those of the iterated coupling schemes bfgs,
/// modified_newton, newton): rtol > 0 (Eq. (12)), etol > 0 (Eq. (13)), 0 < stol < 1 (the line
/// search, Eq. (10)), max_iterations >= 1 per step, max_updates >= 1 (BFGS updates before the
/// matrix is re-formed), line_search a boolean; "reform" is when modified Newton and BFGS form
/// their starting matrix: "step" (every step) or "run" (once, at the first step: keep_matrix).
/// Bodies: a scene with a "fluid" section may have none ("bodies": [] or no key). A kinematic
/// body has no pins, no loads and no (nonzero) initial_velocity; its material still must be
/// valid (mass, energies).
///
/// Every error is one line, "<scene file as given>: <json.path>: <problem>", e.g.
///   "scene.json: time.dt: expected a number, got string \"abc\""
///   "scene.json: bodies[0].mesh.file: no such file '/abs/meshes/x.msh'"
///   "scene.json: line 4, column 24: invalid JSON: syntax error while parsing object - ..."
///   "scene.json: --set 'time.dt': expected key.path=value (no '=')"
///   "scene.json: bodies[0].pins[1]: the box [..]..[..] selects no node; the body spans [..]..[..]"
/// The top level is named "(top level)".
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/enum_names.hpp"
#include "core/types.hpp"
#include "coupling/coupled_step.hpp"
#include "coupling/grid_coupled.hpp"
#include "fluid/grid/grid.hpp"
#include "fluid/params.hpp"
#include "io/output.hpp"
#include "mesh/remesh.hpp"
#include "solid/material.hpp"
#include "solid/obstacles.hpp"
#include "solid/world.hpp"

namespace tetfsi::app {

struct BoxSpec {
  Vec3 lo = Vec3::Zero();
  Vec3 hi = Vec3::Zero();
  bool contains(const Vec3& x, double tol = 1e-9) const {
    return (x.array() >= lo.array() - tol).all() && (x.array() <= hi.array() + tol).all();
  }
};

/// A body's mesh: read, tetrahedralised (CGAL) or generated (mesh/generate.hpp).
struct MeshSpec {
  enum class Kind { Box, File, Surface, Sphere, Shell, HollowBox, Tube, Bowl };
  Kind kind = Kind::Box;
  std::filesystem::path file;  ///< File / Surface: absolute (resolved against the scene folder)
  BoxSpec box;                 ///< Box, HollowBox: extent (m)
  /// Box: hexahedra per axis (6 tets each); HollowBox: across the cavity (the walls get
  /// round(thickness / cavity cell) cells, at least one); Tube: (radial, around, axial)
  Vec3i cells = Vec3i::Ones();
  double cell_size = 0.0;      ///< Surface: Mesh_3 cell size (m)
  Vec3 center = Vec3::Zero();  ///< Sphere, Shell, Tube, Bowl (m)
  double radius = 0.0;         ///< Sphere: mesh::make_ball (m)
  double inner_radius = 0.0;   ///< Shell: mesh::make_spherical_shell, Tube, Bowl; < outer (m)
  double outer_radius = 0.0;   ///< Shell, Tube, Bowl (m)
  int subdivisions = 2;        ///< Sphere (0..6), Shell (0..7): icosphere level of the surface
  int layers = 1;              ///< Shell, Bowl: prism layers across the wall (1..10000)
  int meridian_cells = 8;      ///< Bowl: mesh::make_bowl's cells from the bottom to the rim
  double thickness = 0.0;      ///< HollowBox: wall thickness on all six sides (m)
  int axis = 2;                ///< Tube: mesh::make_tube's axis, 0, 1, 2 = x, y, z
  double length = 0.0;         ///< Tube: along the axis, centred on center (m)
};

/// x ↦ translate + R (scale · x), R = Rz · Ry · Rx from rotate_deg (degrees about x, y, z).
struct TransformSpec {
  double scale = 1.0;
  Vec3 rotate_deg = Vec3::Zero();
  Vec3 translate = Vec3::Zero();
};

/// A set of nodes chosen by a box (rest positions after the transform) or an explicit list.
struct NodeSelection {
  std::optional<BoxSpec> box;
  std::vector<Index> nodes;
};

struct PinSpec {
  NodeSelection select;
  std::string axes = "xyz";  ///< which components are fixed: any of x, y, z
};

struct LoadSpec {
  NodeSelection select;
  Vec3 total_force = Vec3::Zero();  ///< N, spread evenly over the selected nodes
};

/// A body moved by the scene instead of by the FEM (becomes a solid::KinematicMotion).
struct KinematicSpec {
  Vec3 velocity = Vec3::Zero();              ///< m/s
  Vec3 angular_velocity_deg = Vec3::Zero();  ///< deg/s, about the axis through `center`
  /// m; unset: the mean of the body's rest nodes after the transform (known once the mesh
  /// is built, so build_world computes it and the resolved scene omits it).
  std::optional<Vec3> center;
};

struct BodySpec {
  std::string name;
  MeshSpec mesh;
  TransformSpec transform;
  solid::Material material;
  std::vector<PinSpec> pins;
  std::vector<LoadSpec> loads;
  Vec3 initial_velocity = Vec3::Zero();
  std::optional<KinematicSpec> kinematic;  ///< set: a kinematic body
};

struct TimeSpec {
  double dt = 0.01;                ///< s, > 0
  std::optional<double> end_time;  ///< s; default 1.0 if neither end_time nor steps given
  std::optional<int> steps;
  /// Number of steps the run takes: steps, or ceil(end_time / dt − 1e-9).
  int num_steps() const;
};

struct OutputSpec {
  int every = 1;                    ///< write a frame every this many steps (≥ 1)
  std::string compression = "lz4";  ///< "lz4", "zlib" or "none"
  /// A checkpoint every this many steps (and at the last step); 0: only when the run is
  /// stopped (signal, OUT/STOP, wall time). run/checkpoints.hpp.
  int checkpoint_every = 0;
  int keep_checkpoints = 2;  ///< the newest checkpoints kept (>= 1)
  /// Renderer files besides the .vtu frames (io/export.hpp): "vdb", "ply".
  std::vector<std::string> export_formats;
  double voxel_size = 0.0;        ///< m; 0: the fluid's surface size (tet fluid only)
  int voxel_subsamples = 2;       ///< VoxelOptions::subsamples
  double smoke_threshold = 1e-4;  ///< kg/m³, VdbFrameInfo::smoke_threshold
};

struct SolverSpec {
  std::string linear = "cholmod";  ///< a name of solver_names()
  double rel_tol = 1e-8;
  int max_iterations = 1000;
};

struct SolidSpec {
  /// How bodies that step alone are integrated (SolidWorld::integrator).
  solid::Integrator integrator = solid::Integrator::Linearized;
  std::string trapezoid = "paper";  ///< "paper" [Chentanez06, Eq. (4)] or "midpoint"; linearized
  /// K' of every integrator (StvkElasticity::set_tangent); default Definite with `contact`.
  solid::Tangent tangent = solid::Tangent::Exact;
  /// The equilibrium iteration's options (SolidWorld::equilibrium; `method` is unused here:
  /// it comes from `integrator`, or from the coupling scheme). reform "run" = keep_matrix.
  EquilibriumOptions equilibrium;
};

/// The scene key `contact`: contact between bodies and self-contact (solid/contact.hpp).
struct ContactSpec {
  std::optional<double> gap;  ///< d̂ (m); unset: solid::default_contact_gap
  double friction = 0.0;
  double restitution = 0.0;
  bool self = true;
  double stiffness = 1e4;
};

struct StaticSpec {
  int load_steps = 1;
  double rel_tol = 1e-9;
  int max_iterations = 60;
};

/// Where the fluid lives: the dynamic tet mesh, or the regular MAC grid.
enum class Discretization { Tet, Grid };
inline constexpr EnumNames<Discretization, 2> k_discretization_names{
    "fluid discretization", {{{Discretization::Tet, "tet"}, {Discretization::Grid, "grid"}}}};

/// The scene keys fluid.grid: the MAC grid over the fluid box (coupling/grid_coupled.hpp).
struct GridKeys {
  double cell_size = 0.0;       ///< m; 0: from `cells`
  Vec3i cells = Vec3i::Zero();  ///< per axis; resolved from cell_size when that is given
  int max_cells = 2'000'000;
  coupling::GridPressureForces pressure_forces = coupling::GridPressureForces::Paper;
};

/// The optional fluid of a scene: the box it fills and the size of its mesh, as the remesher
/// takes them (mesh/remesh.hpp), and its physics. `sizing.refine` is never set from a scene
/// (`params.refine` says what the run should ask for).
struct FluidSpec {
  mesh::FluidDomain domain;
  mesh::Sizing sizing;
  /// Physics and numerics; `params.patches` has one entry per `domain.patches` entry (same
  /// order), `params.gravity` is the scene's gravity if `gravity` else zero.
  fluid::FluidParams params;
  bool gravity = false;  ///< the scene key fluid.gravity
  Discretization discretization = Discretization::Tet;
  GridKeys grid;  ///< grid scenes: the keys (cells resolved)
  /// grid scenes: the grid the fluid runs on
  std::optional<fluid::GridSpec> grid_spec;
};

/// How the fluid and the bodies of a fluid scene interact (the scene key "coupling").
struct CouplingSpec {
  /// true: two-way, `params.scheme` (any coupling::Scheme); false: "none", one-way (the
  /// bodies step alone, the fluid follows them, coupling::FsiSimulation).
  bool two_way = false;
  coupling::CouplingParams params;  ///< the scheme and the coupled solve's options
  std::string scheme_name() const { return two_way ? coupling::to_string(params.scheme) : "none"; }
};

enum class Mode { Dynamic, Static };

struct Scene {
  std::filesystem::path file;  ///< the scene file (absolute), or empty for an in-memory scene
  std::string name;            ///< default: the file's stem
  std::string description;     ///< free text (optional)
  Mode mode = Mode::Dynamic;
  TimeSpec time;
  OutputSpec output;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);
  SolverSpec solver;
  SolidSpec solid;
  StaticSpec statics;
  std::vector<BodySpec> bodies;
  std::vector<solid::Obstacle> obstacles;
  std::optional<FluidSpec> fluid;        ///< set if the scene has a "fluid" section
  std::optional<CouplingSpec> coupling;  ///< set iff `fluid` is (resolved default, see above)
  std::optional<ContactSpec> contact;    ///< set if the scene has a "contact" section
  /// True if the run couples the fluid and the bodies both ways (a dynamic fluid scene whose
  /// coupling scheme is not "none").
  bool two_way() const { return fluid && coupling && coupling->two_way && mode == Mode::Dynamic; }
  nlohmann::json resolved;  ///< the scene with every default filled in (written to the output)
};

/// "[x, y, z]" with 6 significant digits, for one-line messages and summaries.
std::string fmt_vec(const Vec3& v);

/// Parse a scene from JSON. `file` names the scene in messages and anchors relative paths.
/// @throws InputError "<file>: <json.path>: <problem>", e.g.
///   "scene.json: bodies[0].material.poison_ratio: unknown key (did you mean 'poisson_ratio'?)"
Scene parse_scene(const nlohmann::json& j, const std::filesystem::path& file);

/// Read, apply `--set key.path=value` overrides (value parsed as JSON, else as a string;
/// array elements as `bodies.0.material.density=500`), then parse.
/// @throws InputError for a missing file, a JSON syntax error (with line and column), a bad
///   override (naming it) or anything parse_scene rejects.
Scene load_scene(const std::filesystem::path& file, const std::vector<std::string>& overrides = {});

/// As load_scene, from JSON text already read (a checkpoint's stored scene): `file` names the
/// scene in messages and anchors relative paths.
/// @throws InputError as load_scene.
Scene parse_scene_text(const std::string& text, const std::filesystem::path& file,
                       const std::vector<std::string>& overrides = {});

/// Build the bodies (read/generate/tetrahedralise meshes, transform, pins, loads, initial
/// velocity, kinematic motion with its state at t = 0) and obstacles of a scene.
/// @throws InputError / MeshError naming the scene file and the body, e.g.
///   "scene.json: bodies[1] 'flag': meshes/flag.msh: tet 17 (...) is inverted ...".
solid::SolidWorld build_world(const Scene& scene);

/// What the scene's output folder holds (io::OutputWriter's plan): its compression, whether
/// it has a fluid, a free surface, a two-way coupling, and the resolved scene.
OutputPlan output_plan(const Scene& scene);

}  // namespace tetfsi::app
