#pragma once
/// @file output.hpp
/// Simulation output for ParaView: one `.vtu` per body and frame, a `.pvd` collection per
/// body that lists the frames with their times, and a `stats.csv` with one row per step.
/// A scene with a fluid also gets the fluid mesh and its solid-interface faces per frame (a
/// grid fluid: its cells as image data and the bodies' surface triangles).
///
/// Layout of an output folder `OUT` (all of it written by `OutputWriter`):
/// ```
/// OUT/scene.resolved.json          the scene with every default filled in
/// OUT/<body>.pvd                   collection: (time, file) per frame, open this in ParaView
/// OUT/<body>/<body>_<step>.vtu     frames (step number, 6 digits)
/// OUT/fluid.pvd                    fluid scenes: the fluid mesh of each frame
/// OUT/fluid/fluid_<step>.vtu         (write_fluid_vtu), or for a grid fluid
/// OUT/fluid/fluid_<step>.vti         (write_grid_vti, OutputWriter::write_grid_frame)
/// OUT/interface.pvd                fluid scenes: the fluid faces on the solids of each frame
/// OUT/interface/interface_<step>.vtp (write_interface_vtp; grid fluid: write_grid_interface_vtp)
/// OUT/stats.csv                    one row per step (see StatsWriter::columns())
/// OUT/summary.json                 written by the run loop at the end (run/run.hpp)
/// ```
/// Every collection lists the same times (a frame's files are all written before any `.pvd`
/// lists it), except that frames without a fluid mesh (none could be built at t = 0) are in
/// the bodies' collections only. The fluid mesh of a frame is the one its state lives on: in
/// a two-way simultaneous run it was built around the predicted surfaces x* = xⁿ + h uⁿ
/// (coupling/coupled_step.hpp), so its interface faces follow the body's frame at xⁿ⁺¹ only
/// to O(h² |du/dt|), not exactly as in a one-way run.
/// Robustness: every file is written under a temporary name and renamed into place, and the
/// `.pvd` is rewritten after every frame, so a run killed at any moment leaves a collection
/// that ParaView can open, listing only complete frames. (Atomic against a killed process;
/// no fsync, so not against power loss.) Nothing that tetfsi did not write is ever deleted.
///
/// VTK stays inside output.cpp; this header only sees plain types.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/checkpoint.hpp"
#include "core/enum_names.hpp"
#include "core/timer.hpp"
#include "core/types.hpp"
#include "fluid/frame.hpp"
#include "io/export.hpp"
#include "mesh/tet_mesh.hpp"
#include "solid/pose.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid {
class SolidWorld;
}

namespace tetfsi::app {

/// Compression of the appended binary data of a `.vtu`. Measured here for one frame of a
/// 1M-tet body (176k nodes, every array below, Float64; the strain/stress fields take 0.06 s
/// of each): LZ4 0.15 s, 51 MiB (the default); ZLib level 1 0.77 s, 38 MiB; none 0.13 s,
/// 63 MiB.
enum class Compression { None, LZ4, ZLib };
/// The scene key output.compression, in the order its docs list them.
inline constexpr EnumNames<Compression, 3> k_compression_names{
    "compression",
    {{{Compression::LZ4, "lz4"}, {Compression::ZLib, "zlib"}, {Compression::None, "none"}}}};

/// "none" | "lz4" | "zlib" → Compression. @throws InputError naming the value and the valid ones.
Compression parse_compression(const std::string& name);
std::string to_string(Compression c);

/// Write the body's current deformed mesh as an XML unstructured grid (appended raw binary).
///
/// Points are x = X + d (m); cells are VTK_TETRA. Point data (Float64, 3 components unless
/// noted): `displacement` d (m), `velocity` u (m/s), `external_force` = applied loads + m g
/// (N), `rest_position` X (m), `fixed` (UInt8, 1 component: 1 if any DOF of the node is
/// fixed). Cell data (Float64): `green_strain_norm` |E|_F, `von_mises_stress` (Pa),
/// `volume_ratio` J = V/V0 (StvkElasticity::tet_fields).
///
/// Written to `<path>.tmp` and renamed to `path` (an existing file is replaced atomically).
/// @param gravity m/s², for `external_force`
/// @throws InputError naming the file if it cannot be written.
void write_body_vtu(const std::filesystem::path& path, const solid::SolidBody& body,
                    const Vec3& gravity, Compression compression);

/// Write a fluid mesh as an XML unstructured grid (appended raw binary), for watching the
/// dynamic mesh and its quality in ParaView.
///
/// Points are TetMesh::vertices (m); cells are its tets as VTK_TETRA, in order. Cell data
/// (Float64 unless noted): `volume` V_t (m³, TetMesh::volumes), and the figures of
/// mesh::tet_quality: `q_min_dihedral_deg`, `q_max_dihedral_deg` (degrees), `q_radius_edge`
/// (circumradius / shortest edge), `q_shape` (1 regular, → 0 flat); `touches_solid` (UInt8:
/// 1 if any of the tet's vertices lies on a solid surface, TetMesh::vertex_body ≥ 0).
/// Point data: `vertex_body` (Int32: the body whose surface the vertex lies on, −1 for fluid
/// samples).
///
/// Written to `<path>.tmp` and renamed to `path`, like write_body_vtu.
/// @throws InputError naming the file if it cannot be written.
/// The fluid's fields on the mesh of a frame, each sized for it (fluid/frame.hpp).
using FluidFrameFields = fluid::MeshFrameFields;

/// With `fields`, also: cell data `pressure`, `smoke_density`, `temperature`, `vorticity`,
/// `divergence` and `velocity` (3 components), point data `velocity` (3 components).
void write_fluid_vtu(const std::filesystem::path& path, const mesh::TetMesh& fluid,
                     Compression compression, const FluidFrameFields* fields = nullptr);

/// Write the solid-interface faces of a fluid mesh (TetMesh::face_kind == FaceKind::Solid)
/// as an XML poly data file of triangles (appended raw binary), in face order.
///
/// Points are the vertices these faces use, numbered in order of first use (m). Each
/// triangle keeps the face's stored vertex order, so its right-hand normal is n_f (from the
/// fluid into the solid). Cell data: `body` (Int32, TetMesh::face_body), `triangle` (Int32:
/// the triangle of that body's SolidSurface, TetMesh::face_triangle), `area` (m²),
/// `dual_length` d_f (m), `normal` n_f (3 components), `bary` (3 components: barycentric
/// weights of the face centroid on that triangle). Point data: `fluid_vertex` (Int32: the
/// point's index in the fluid mesh). With `fields`, also cell data `pressure` (Pa: the
/// pressure of the face's fluid cell, face_tets(f, 0), dynamic + hydrostatic as
/// FluidState::p) and `normal_velocity` (m/s: u_f along n_f, > 0 into the solid). A mesh
/// without solid faces gives an empty, valid file.
///
/// Written to `<path>.tmp` and renamed to `path`, like write_body_vtu.
/// @throws InputError naming the file if it cannot be written.
void write_interface_vtp(const std::filesystem::path& path, const mesh::TetMesh& fluid,
                         Compression compression, const FluidFrameFields* fields = nullptr);

/// One frame of the grid fluid (fluid/frame.hpp): plain data, the cells' fields and the
/// bodies' surface triangles.
using GridFrameFields = fluid::GridFrameFields;

/// Write the grid fluid of a frame as XML image data (`.vti`, appended raw binary), for
/// ParaView's slices and volume rendering.
///
/// Extent 0..n_a points per axis (n_a + 1 points, n_a cells), `origin` and `spacing` as
/// given. Cell data (Float64 unless noted): `pressure` (Pa), `smoke_density` (kg/m³),
/// `temperature` (K), `divergence` (1/s), `vorticity` (1/s), `velocity` (3 components, m/s),
/// `solid` (UInt8), and with a free surface `phi` (m, < 0 in the liquid). Compression as
/// write_body_vtu.
///
/// Written to `<path>.tmp` and renamed to `path`, like write_body_vtu.
/// @throws InternalError naming the array and both sizes if a cell array is not #C long, or
///   if a cell count is < 1 or a spacing not positive and finite (nothing is written then);
///   InputError naming the file if it cannot be written.
void write_grid_vti(const std::filesystem::path& path, const GridFrameFields& g,
                    Compression compression);

/// Write the liquid's surface (the zero of `phi`, trilinear between the cell centres and
/// carried to the box's walls, VTK's contour filter) as triangles (`.vtp`) with point data
/// `velocity` (m/s, interpolated from the cell centres) and `Normals`. Written like
/// write_grid_vti.
/// @throws InternalError if `phi` is not #C long.
void write_liquid_surface_vtp(const std::filesystem::path& path, const GridFrameFields& g,
                              Compression compression);

/// The liquid's surface as plain arrays (points, outward triangles, point velocity), for the
/// renderer export: as write_liquid_surface_vtp's but closed where the liquid touches the box's
/// walls (a cap on the wall), so that a renderer's water or glass material has a closed mesh.
/// @throws InternalError if `phi` is not #C long.
ExportSurface liquid_surface(const GridFrameFields& g);

/// Write the grid fluid's solid interface, the bodies' surface triangles of the frame, as an
/// XML poly data file (appended raw binary), in triangle order.
///
/// Points are `surface_points` (m), triangles `surface_triangles` in their stored order (so
/// the right-hand normal points out of the body). Cell data: `body` (Int32), `pressure` (Pa),
/// `pressure_jump` (Pa), `area` (m²), `normal` (3 components: the unit outward normal, 0 for a
/// degenerate triangle). Point data: `fluid_force` (3 components, N). No triangles gives an
/// empty, valid file.
///
/// Written to `<path>.tmp` and renamed to `path`, like write_body_vtu.
/// @throws InternalError naming the array and both sizes if a surface array has the wrong
///   size, or naming the triangle if it indexes past #P (nothing is written then); InputError
///   naming the file if it cannot be written.
void write_grid_interface_vtp(const std::filesystem::path& path, const GridFrameFields& g,
                              Compression compression);

/// `s` with its line breaks turned into spaces, and any run of more than 240 characters
/// without a space shortened to its first 160 and last 40: the CLI prints messages as
/// single readable lines.
std::string one_line(std::string s);

/// Write `text` to `path` atomically: `<path>.tmp`, flush, close, rename over `path`.
/// @throws InputError naming the file if it cannot be written.
void write_text_file_atomic(const std::filesystem::path& path, const std::string& text);

/// One entry of a `.pvd` collection.
struct PvdEntry {
  double time = 0.0;  ///< s (pseudo-time for static runs)
  std::string file;   ///< path of the dataset relative to the `.pvd`'s folder
};

/// A ParaView data collection (`.pvd`) for one stream of frames. VTK has no writer for it,
/// so the XML is written here:
/// ```xml
/// <?xml version="1.0"?>
/// <VTKFile type="Collection" version="0.1" byte_order="LittleEndian">
///   <Collection>
///     <DataSet timestep="0.5" group="" part="0" file="sheet/sheet_000050.vtu"/>
///   </Collection>
/// </VTKFile>
/// ```
/// Times are printed with 17 significant digits (they read back bit-identical).
class PvdWriter {
 public:
  /// @param pvd_path the collection file; nothing is written before the first `add`
  explicit PvdWriter(std::filesystem::path pvd_path);

  /// Append a frame and rewrite the whole collection atomically.
  /// @param relative_file dataset path relative to the `.pvd`'s folder ('/' separators)
  void add(double time, const std::string& relative_file);
  /// Replace every entry (a resumed run's collection so far) and rewrite the collection.
  void reset(std::vector<PvdEntry> entries);

  const std::filesystem::path& path() const { return m_path; }
  const std::vector<PvdEntry>& entries() const { return m_entries; }

  /// The XML text of a collection (exposed for tests).
  static std::string to_xml(const std::vector<PvdEntry>& entries);

 private:
  std::filesystem::path m_path;
  std::vector<PvdEntry> m_entries;
};

/// The fluid part of a stats.csv row: the mesh built after the step and the fluid's step
/// (fluid::FluidStepReport; NaN before the fluid has taken a step).
struct FluidStepStats {
  Index cells = 0;             ///< fluid tets
  Index vertices = 0;          ///< fluid mesh vertices
  Index steiner_points = 0;    ///< RemeshReport::steiner_points
  int recovery_rounds = 0;     ///< RemeshReport::recovery_rounds
  int remesh_incremental = 0;  ///< RemeshReport::incremental (1: updated, 0: rebuilt)
  Index vertices_removed = 0, vertices_inserted = 0;  ///< RemeshReport's
  double remesh_s = 0.0;                              ///< RemeshReport::seconds_total (s)
  /// mesh::quality_columns(mesh::summarize_quality(mesh)): (name, value) in that fixed order.
  std::vector<std::pair<std::string, double>> quality;
  // ---- the fluid step (columns after the quality columns) ----
  int pressure_iterations = 0;        ///< iterations of the pressure solve
  double pressure_residual = NAN;     ///< its relative residual
  double divergence_before = NAN;     ///< max |D u*| before the projection (1/s)
  double divergence = NAN;            ///< max |D u| after it (1/s)
  double fluid_kinetic_energy = NAN;  ///< J
  double smoke_mass = NAN;            ///< kg
  double inflow_flux = NAN;           ///< m³/s into the box through inflow patches
  double outflow_flux = NAN;          ///< m³/s out through open faces
  double solid_flux = NAN;            ///< m³/s into the solids (0 for rigid motion)
  double max_speed = NAN;             ///< max |u_f| (m/s)
  double cfl = NAN;                   ///< max h |u| / cell size
  Index traces_clamped = 0;           ///< back-traces stopped at the fluid boundary
  // ---- a liquid with a free surface (fluid::FluidStepReport) ----
  double liquid_volume = NAN;        ///< m³
  double liquid_volume_drift = NAN;  ///< relative to what the particles carry
  double liquid_shift = NAN;         ///< m: the level set's volume-holding shift
  double liquid_area = NAN;          ///< m²
  Index liquid_particles = 0;
  double liquid_advect_s = NAN, liquid_surface_s = NAN, liquid_p2g_s = NAN;  ///< seconds
};

/// The two-way coupling part of a stats.csv row (coupling::CoupledStepReport of the step).
struct CoupledStepStats {
  int iterations = 0;     ///< coupled_iterations: of the coupled solve (1 for LU)
  double residual = NAN;  ///< coupled_residual: its worst relative residual
  /// W, pᵀ Jᵀ uⁿ⁺¹ of the dynamic pressure on the free bodies (CoupledReport::
  /// interface_power); 0 in the splitting scheme, whose solve holds every body.
  double interface_power = NAN;
  /// total_energy_coupled: fluid kinetic + solid kinetic + elastic after the step (J)
  double total_energy = NAN;
  double enclosed_volume = 0.0;  ///< m³, Σ over enclosed regions of their volume after the step
  double enclosed_volume_drift = 0.0;  ///< max over enclosed regions of |after − target| / target
  /// contact_rounds: the solves of the step's floor active set (solid/floor_contact.hpp): the
  /// simultaneous scheme's coupled solves, splitting's most of one body's; 1 when the set
  /// held at once, 0 in the iterated schemes (floors projected after the step).
  int contact_rounds = 0;
};

/// Contact between bodies (the scene's `contact`): a stats.csv row's last columns.
struct ContactStepStats {
  Index pairs = 0;       ///< contact_pairs: constraints in the set after the step
  double min_gap = NAN;  ///< contact_min_gap: smallest surface distance (m, capped at 4 d̂)
  double force = 0.0;    ///< contact_force: Σ of the pairs' normal forces (N)
  Index crossings = 0;   ///< contact_crossings: pairs found crossed by the continuous check
  int rounds = 0;        ///< contact_solves: solves of the step with the contacts in them
  double seconds = 0.0;  ///< contact_s: detection and assembly (s)
};

/// One row of stats.csv.
struct StepStats {
  int step = 0;       ///< step number, 1-based (0 would be the initial state)
  double time = 0.0;  ///< s, time at the end of the step
  double dt = 0.0;    ///< s
  PhaseTimes phases;  ///< seconds per phase; columns as StatsWriter::phase_columns()
  int solver_iterations = 0;
  double solver_residual = 0.0;
  Index contacts = 0;
  double kinetic_energy = 0.0;     ///< J, summed over bodies
  double elastic_energy = 0.0;     ///< J
  double gravity_potential = 0.0;  ///< J, −Σ m g·x
  /// The equilibrium iteration of the step [BatheSonnad80] (core/equilibrium.hpp): a
  /// nonlinear solid.integrator (SolidStepReport: the most iterations of any body, the
  /// residual evaluations summed over bodies) or an iterated coupling scheme
  /// (CoupledStepReport::equilibrium); 0 for the linearized integrator and the simultaneous
  /// and splitting schemes.
  int equilibrium_iterations = 0;
  int equilibrium_evaluations = 0;
  /// Fluid scenes: figures of the fluid mesh (a row without them writes "nan" there).
  std::optional<FluidStepStats> fluid;
  /// Two-way coupled runs: the coupling figures (a row without them writes "nan" there).
  std::optional<CoupledStepStats> coupled;
  /// Per body, in body order: its pose after the step (solid::body_pose with
  /// solid::up_direction(world.gravity)); empty writes "nan" in every body column.
  std::vector<solid::BodyPose> bodies;
  /// Scenes with contact between bodies: their figures, after the bodies'.
  std::optional<ContactStepStats> contact;
  /// kinetic + elastic + gravity potential (J); the work of applied loads is not included.
  double total_energy() const { return kinetic_energy + elastic_energy + gravity_potential; }
};

/// stats.csv: a header line, then one row per `write` (flushed at once so that a killed run
/// keeps every completed step). Doubles are printed with 17 significant digits.
class StatsWriter {
 public:
  /// Creates (truncates) the file and writes the header; or, with `continue_after` (a resumed
  /// run), keeps the existing file's header and its rows of steps 1..continue_after (rewritten
  /// atomically without the later ones) and appends after them.
  /// @param fluid write the fluid columns too (columns(true))
  /// @param coupled (with `fluid`) a two-way coupled run: columns(true, true)
  /// @param bodies the bodies' column names (stats_body_names), in body order: three columns
  ///   each, after every other column (stats_columns.hpp's body_columns)
  /// @throws InputError naming the file if it cannot be opened; with `continue_after`, if it
  ///   is missing, its header is not this run's, or its rows do not run 1..continue_after.
  explicit StatsWriter(const std::filesystem::path& path, bool fluid = false, bool coupled = false,
                       std::optional<int> continue_after = std::nullopt,
                       std::vector<std::string> bodies = {}, bool contact = false,
                       bool liquid = false);
  ~StatsWriter();
  StatsWriter(const StatsWriter&) = delete;
  StatsWriter& operator=(const StatsWriter&) = delete;

  void write(const StepStats& row);

  /// The column names in order (io/stats_columns.hpp's tables): step_head_columns, the
  /// phases of `phase_columns(fluid, coupled)`, step_columns; with `fluid` then
  /// fluid_mesh_columns, mesh::quality_columns, fluid_step_columns; with `coupled` (and
  /// `fluid`) coupled_columns; then body_columns for each of `bodies`; with `contact` then
  /// contact_columns; with `liquid` the liquid_columns last. The columns before the bodies'
  /// depend on `fluid` and `coupled` only, so a column's position does not depend on the
  /// bodies.
  static std::vector<std::string> columns(bool fluid = false, bool coupled = false,
                                          const std::vector<std::string>& bodies = {},
                                          bool contact = false, bool liquid = false);
  /// The names of the timed phases that get a column (stats_columns.hpp's phase_columns).
  static const std::vector<std::string>& phase_columns(bool fluid = false, bool coupled = false);

  bool has_fluid() const { return m_fluid; }
  bool has_coupling() const { return m_coupled; }

 private:
  std::filesystem::path m_path;
  std::FILE* m_file = nullptr;
  bool m_fluid = false;
  bool m_coupled = false;
  std::vector<std::string> m_bodies;  ///< the bodies' column names
  bool m_contact = false;
  bool m_liquid = false;
};

/// What a run's output folder holds, as the run's scene says (scene/scene.hpp's
/// output_plan): the writers know no scene.
struct OutputPlan {
  std::string compression = "lz4";  ///< the scene's output.compression (parse_compression)
  bool fluid = false;               ///< fluid.pvd, interface.pvd and the fluid stats columns
  bool two_way = false;             ///< the coupling stats columns
  bool liquid = false;              ///< a free surface: liquid.pvd and the liquid stats columns
  nlohmann::json resolved;          ///< written to scene.resolved.json (null: an empty object)
  /// Renderer files with every frame (output.export): OUT/vdb/, OUT/ply/, OUT/export.json.
  ExportRequest exports;
};

/// Owns the output folder of one run: writes scene.resolved.json, the frames and their
/// `.pvd` collections, and stats.csv.
class OutputWriter {
 public:
  /// Creates `out_dir` (and parents) and one subfolder per body (and `fluid/`, `interface/`
  /// if the plan has a fluid), writes `scene.resolved.json` and starts `stats.csv` (with
  /// the fluid columns if the plan has a fluid, the coupling columns if it is two-way). If the
  /// folder holds an earlier run (a stats.csv, summary.json or scene.resolved.json), logs a
  /// warning: our files are overwritten, nothing else is touched or deleted. With `resume_step`
  /// (`tetfsi resume`), the folder's run continues after that step instead: stats.csv keeps its
  /// rows up to it (StatsWriter's continue_after) and load_state restores the collections.
  /// @throws InputError if the folder cannot be created or written, if two body names map
  ///   to the same file name or the same stats.csv column name (stats_body_names), or if a
  ///   body's file name is "fluid" or "interface" in a scene with a fluid.
  /// On a rank other than 0 (mpirun) nothing is created or written (m_quiet).
  OutputWriter(const std::filesystem::path& out_dir, const OutputPlan& plan,
               const solid::SolidWorld& world, std::optional<int> resume_step = std::nullopt);

  /// The collections and the frame count into a checkpoint, as records under "run/output/":
  /// the frames of steps <= `through_step` only (a frame written because the run ended or
  /// stopped, off the output.every schedule, is not one of the continued run's frames).
  void save_state(CheckpointWriter& w, int through_step) const;
  /// A resumed run: the collections and frame count of save_state's records; every `.pvd` is
  /// rewritten with them, and the frame files of later steps that this writer's streams hold
  /// (written after the checkpoint by the run that stopped) are deleted.
  /// @throws CheckpointError if the records do not fit this scene's streams.
  void load_state(const CheckpointReader& r);

  /// Write one `.vtu` per body for the world's current state, labelled `step` (file name)
  /// and `time` (in the `.pvd`), and update every `.pvd`. In a fluid scene, also the fluid
  /// mesh and its interface faces (fluid.pvd, interface.pvd) if `fluid` is given; without it
  /// (no mesh could be built) the frame has bodies only. Every file of the frame is written
  /// before any `.pvd` lists it, so that a frame that fails half-way is in no collection and
  /// the collections keep the same times.
  void write_frame(const solid::SolidWorld& world, int step, double time,
                   const mesh::TetMesh* fluid = nullptr,
                   const FluidFrameFields* fluid_fields = nullptr);
  /// As write_frame, with the grid fluid: `fluid/fluid_<step>.vti` (write_grid_vti) in
  /// fluid.pvd and `interface/interface_<step>.vtp` (write_grid_interface_vtp) in
  /// interface.pvd. The sizes of `grid` are checked before any file is written, and every file
  /// of the frame is written before any `.pvd` lists it.
  /// @throws InternalError if the scene has no fluid (has_fluid()) or `grid`'s sizes do not
  ///   agree (then no file of the frame is written).
  void write_grid_frame(const solid::SolidWorld& world, int step, double time,
                        const GridFrameFields& grid);
  /// Append a row to stats.csv.
  void write_stats(const StepStats& row) {
    if (m_stats) m_stats->write(row);
  }
  /// Write `summary.json` (pretty JSON text, atomically).
  void write_summary(const std::string& json_text);

  const std::filesystem::path& out_dir() const { return m_out; }
  int frames_written() const { return m_frames; }
  Compression compression() const { return m_compression; }
  /// The `.pvd` of each body, in body order.
  std::vector<std::filesystem::path> pvd_paths() const;
  /// True if the scene has a fluid (fluid.pvd, interface.pvd and the fluid stats columns).
  bool has_fluid() const { return m_fluid_pvd.has_value(); }

 private:
  std::vector<std::string> m_file_names;  ///< per body: file-system safe name (checked first)
  std::filesystem::path m_out;
  Compression m_compression;
  std::vector<PvdWriter> m_pvd;              ///< per body
  std::optional<PvdWriter> m_fluid_pvd;      ///< fluid scenes: OUT/fluid.pvd
  std::optional<PvdWriter> m_interface_pvd;  ///< fluid scenes: OUT/interface.pvd
  std::optional<PvdWriter> m_liquid_pvd;     ///< a free surface: OUT/liquid.pvd
  /// On every rank but rank 0 of an mpirun job (core/ranks.hpp) the writer is quiet: it
  /// counts frames and collections as rank 0's does but creates, writes and removes nothing.
  bool m_quiet = false;
  std::optional<StatsWriter> m_stats;  ///< absent when quiet
  int m_frames = 0;
  std::vector<int> m_frame_steps;            ///< the step of every frame written, in order
  ExportRequest m_export;                    ///< the plan's renderer files
  std::optional<ExportManifest> m_manifest;  ///< OUT/export.json, when m_export asks for files

  /// A frame of `step` written (or, quiet, skipped): the count and the step list.
  void count_frame(int step);
  /// Every collection: the bodies' in body order, then fluid.pvd and interface.pvd.
  std::vector<const PvdWriter*> streams() const;
  std::vector<PvdWriter*> streams();

  /// Write every body's `.vtu` of the frame; returns their paths relative to m_out, in body
  /// order, for the `.pvd`s (which the caller updates once the frame's other files exist).
  std::vector<std::string> write_bodies(const solid::SolidWorld& world, int step);
  /// Add the frame to every body's `.pvd`.
  void add_bodies_to_pvds(const std::vector<std::string>& rel, double time);
  /// The frame's renderer files (io/export.hpp), if the plan asks for them: the bodies'
  /// surfaces, the fluid's voxels and the liquid's surface, numbered by frame (m_frames).
  /// Returns the manifest entry, added by the caller once the frame's collections are.
  std::optional<ExportedFrame> export_files(const solid::SolidWorld& world, int step, double time,
                                            const VoxelFrame* fluid, const ExportSurface* liquid);
  /// A resumed run: the manifest's frames before `frames`, and the later frames' files removed.
  void load_export_state(const CheckpointReader& r);
};

/// The output file name of each body (file_safe_name), in body order, checked as
/// OutputWriter does before it creates anything, so that `tetfsi validate` can say it; the
/// bodies' stats.csv column names (stats_body_names) are checked too.
/// @throws InputError if two body names map to the same file name or the same column name,
///   or a body's file name is "fluid" or "interface" in a plan with a fluid.
std::vector<std::string> output_file_names(const OutputPlan& plan, const solid::SolidWorld& world);

/// A body name made safe for file names: characters other than [A-Za-z0-9_.-] become '_'
/// (an empty name becomes "body").
std::string file_safe_name(const std::string& name);

/// A body name made safe for a stats.csv column: characters other than [A-Za-z0-9_] become
/// '_' (an empty name becomes "body"), so a column name never holds ',', ';', a quote or a
/// space.
std::string column_safe_name(const std::string& name);

/// The name of each body in its stats.csv columns (column_safe_name), in body order, checked
/// as OutputWriter does before it creates anything.
/// @throws InputError if two body names map to the same column name ("a-b" and "a.b" both
///   give a_b): the columns would be ambiguous, so the bodies must be renamed.
std::vector<std::string> stats_body_names(const solid::SolidWorld& world);

}  // namespace tetfsi::app
