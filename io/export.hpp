#pragma once
/// @file export.hpp
/// Frames for renderers (Blender, Houdini): the fluid as OpenVDB volumes and the surfaces
/// (bodies, the liquid) as binary PLY meshes, one file per frame, numbered by frame so that
/// a renderer loads them as a sequence.
///
/// Layout in a run's folder `OUT` (written by OutputWriter with the scene's `output.export`,
/// or afterwards by `tetfsi export OUT`):
/// ```
/// OUT/vdb/fluid_<frame>.vdb        the fluid's grids (write_vdb), frame = 0, 1, 2, ... (6 digits)
/// OUT/ply/<body>_<frame>.ply       each body's deformed boundary surface (write_ply)
/// OUT/ply/liquid_<frame>.ply       a free surface: the liquid's surface
/// OUT/export.json                  the manifest: per frame its step, time and files, and
///                                  what each holds (grid names, active voxels, value ranges,
///                                  bounds; vertex and triangle counts)
/// ```
/// Axes and units: the scene's axes (z up in every shipped scene, as in Blender), metres,
/// seconds and SI units throughout; no rescaling.
///
/// The tet fluid lives on an unstructured mesh: `voxelize` samples it onto a regular voxel
/// grid (in parallel), each voxel the average of s³ sub-samples, so that the voxels' smoke
/// mass Σ ρ h³ converges to the mesh's Σ ρ_t V_t. The grid fluid's cells are its voxels.
///
/// OpenVDB stays inside vdb.cpp; this header only has plain types.
#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/types.hpp"
#include "fluid/frame.hpp"

namespace tetfsi::solid {
class SolidBody;
}

namespace tetfsi::app {

/// What the coordinates of every exported file are: the `.vdb` files' `tetfsi_axes` and the
/// manifest's `axes`.
inline constexpr const char* k_export_axes = "scene axes (z up in the shipped scenes), metres";

// ---- surfaces: PLY ----------------------------------------------------------------------

/// A triangle surface for a renderer: one binary PLY per frame.
struct ExportSurface {
  MatX3 points;      ///< #P × 3 (m)
  MatX3i triangles;  ///< #Tr × 3 into points; right-hand normal outward (out of a body,
                     ///< out of the liquid)
  MatX3 velocity;    ///< #P × 3 (m/s), or empty (not written)
  VecX von_mises;    ///< #P (Pa), or empty (not written)
};

/// The boundary surface of a tet body (mesh::boundary_triangles) in a compact numbering of
/// the nodes it uses, with their velocity and the von Mises stress of each surface node
/// (the mean over the tets that share the node).
/// @param positions #V × 3 current positions; @param tets #T × 4 (positive volume)
/// @param velocity #V × 3, or empty; @param tet_von_mises #T, or empty
ExportSurface tet_boundary_surface(const MatX3& positions, const MatX4i& tets,
                                   const MatX3& velocity, const VecX& tet_von_mises);
/// The body's current surface: tet_boundary_surface of its deformed state.
ExportSurface body_export_surface(const solid::SolidBody& body);

/// Write `s` as a binary little-endian PLY: vertex properties x y z (float), then vx vy vz
/// (float, m/s) if `s.velocity` is given and von_mises (float, Pa) if `s.von_mises` is; faces
/// as `list uchar int vertex_indices`. Blender's and Houdini's importers read the positions
/// and faces; Houdini keeps the extra properties as point attributes. Written under a
/// temporary name and renamed into place.
/// @throws InternalError if an array has the wrong size or a triangle indexes past #P;
///   InputError naming the file if it cannot be written.
void write_ply(const std::filesystem::path& path, const ExportSurface& s);

/// Read a PLY written by write_ply (binary little-endian, those properties; others of type
/// float are skipped). @throws InputError naming the file and what is wrong.
ExportSurface read_ply(const std::filesystem::path& path);

// ---- volumes: voxels and OpenVDB ----------------------------------------------------------

/// A fluid frame on a regular voxel grid, dense, voxel (i, j, k) at index i + n_x (j + n_y k).
struct VoxelFrame {
  Vec3 origin = Vec3::Zero();             ///< the centre of voxel (0, 0, 0) (m)
  Vec3 spacing = Vec3::Ones();            ///< voxel size per axis (m)
  std::array<Index, 3> dims = {0, 0, 0};  ///< voxels per axis
  /// Per voxel: the fraction of it in the fluid (0 inside a body or outside the box, 1 fully
  /// in the fluid; a grid cell is 0 or 1).
  VecX fluid_fraction;
  VecX density;      ///< smoke density (kg/m³): the voxel's smoke mass / its volume
  VecX temperature;  ///< K, the average over the voxel's fluid part (ambient outside it)
  VecX pressure;     ///< Pa, the average over the voxel's fluid part (0 outside it)
  MatX3 velocity;    ///< #voxels × 3 (m/s), the average over its fluid part (0 outside it)
  VecX phi;          ///< the liquid's level set (m, < 0 in the liquid), or empty
  double ambient_temperature = 293.15;  ///< K: the temperature grid's background
  Index size() const { return dims[0] * dims[1] * dims[2]; }
  /// Σ density × voxel volume (kg): the smoke mass the voxels carry.
  double smoke_mass() const;
};

/// The tet fluid's fields as plain arrays: from the run's frame (fluid::MeshFrame) or from a
/// `.vtu` frame read back.
struct TetVolume {
  MatX3 vertices;         ///< #V × 3 (m)
  MatX4i tets;            ///< #T × 4
  VecX density;           ///< #T smoke density (kg/m³), or empty (0)
  VecX temperature;       ///< #T (K), or empty (ambient)
  VecX pressure;          ///< #T (Pa), or empty (0)
  MatX3 vertex_velocity;  ///< #V × 3 (m/s), interpolated linearly in each tet; or empty (0)
};
/// The mesh and fields of a run's frame, copied. @throws InternalError if it has no mesh
TetVolume tet_volume_of(const fluid::MeshFrame& frame);
/// The same from a mesh and its fields (the writer of a run's frame holds them apart).
TetVolume tet_volume_of(const mesh::TetMesh& mesh, const fluid::MeshFrameFields& fields);

struct VoxelOptions {
  /// Voxel edge (m); must be > 0 (the run and `tetfsi export` default it to the scene's
  /// fluid.mesh.surface_size).
  double voxel_size = 0.05;
  int subsamples = 2;  ///< s: each voxel averages s³ sub-samples (1: its centre only)
  double ambient_temperature = 293.15;  ///< K, where a voxel has no fluid
};

/// Sample the tet fluid onto voxels covering its vertices' bounding box (in parallel over
/// the tets and then the voxels; the same result at any thread count): each sub-sample point
/// takes the fields of the tet containing it (density, temperature, pressure per tet; the
/// velocity interpolated from the vertices); a point in no tet (inside a body) is outside.
/// The box [lo, hi] gets n_a = ceil((hi_a − lo_a) / h) voxels per axis (at least 1; a whole
/// number up to a relative 1e-12 is not rounded up), centred on the box (sticking out by at
/// most h/2 on each side); sub-sample a of a voxel's s per axis lies at its centre +
/// ((a + ½)/s − ½) h. A point on a face shared by tets (barycentric coordinates ≥ −1e-10)
/// belongs to the smallest tet index. Per voxel: fluid_fraction = (points in the fluid) / s³;
/// temperature, pressure and velocity the mean over its points in the fluid; density the smoke
/// mass of its points / h³, where each tet's mass ρ_t V_t is shared equally among the points it
/// holds (a tet that holds none puts it in the voxel of its centroid): the voxels carry the
/// mesh's smoke mass Σ ρ_t V_t exactly (to rounding), at any voxel size, where point values
/// would err by O(h) at the smoke's edges (measured on smoke_sheets: 3 % at s = 2). The price:
/// where tets are much smaller than a voxel, a voxel may read above the densest tet (1.21 for
/// 1.0 at smoke_sheets' inflow with 3 cm voxels at step 8, s = 2; 1.84 at step 100, its mesh
/// refined to ~1 cm by the smoke; exact tet–voxel intersection volumes would cure it). A mesh
/// without vertices gives no voxels (dims 0).
/// @throws InputError if voxel_size is not > 0 and finite, subsamples is not in 1 .. 16, or the
///   grid would exceed 2^31 sub-samples (naming the voxel size and the box: choose a larger one);
///   InternalError if a field's size does not fit the mesh.
VoxelFrame voxelize(const TetVolume& fluid, const VoxelOptions& options);

/// The grid fluid's cells as voxels (no resampling): fields copied, fluid_fraction 1 − solid.
VoxelFrame voxel_frame_of(const fluid::GridFrameFields& grid, double ambient_temperature);

/// What goes into a `.vdb` besides the grids: file metadata `tetfsi_step` (int),
/// `tetfsi_time` (s), `tetfsi_scene`, `tetfsi_axes` (k_export_axes).
struct VdbFrameInfo {
  int step = 0;
  double time = 0.0;
  std::string scene;
  /// Voxels with smoke density above this (kg/m³) are active; 0: every fluid voxel.
  double smoke_threshold = 1e-4;
};

/// One grid of a `.vdb` as read back (read_vdb_summary) or as written.
struct VdbGridSummary {
  std::string name;        ///< density, temperature, pressure, velocity, surface
  std::string type;        ///< OpenVDB's value type: "float", "vec3s"
  std::string grid_class;  ///< "fog volume", "level set", "unknown"
  std::int64_t active_voxels = 0;
  double min = 0.0, max = 0.0;  ///< over active voxels (vectors: of the magnitude)
  /// The world box of the active voxels (x0, y0, z0, x1, y1, z1; m, their outer faces), zeros
  /// without active voxels.
  std::array<double, 6> bounds = {0, 0, 0, 0, 0, 0};
  std::string unit;  ///< the grid's metadata `unit`
};

/// Write `v` as one `.vdb`, each grid with metadata `unit` and the transform voxel → world
/// (voxel centres at integer index coordinates: voxel (i, j, k) at origin + (i, j, k) ∘ spacing):
///  - `density` (float, fog volume, kg/m³, background 0) and `temperature` (float, K,
///    background the ambient) where the smoke density exceeds the threshold (on fluid voxels,
///    fluid_fraction > 0; a threshold ≤ 0 makes every fluid voxel active). Always written,
///    empty when no voxel is above the threshold;
///  - `velocity` (vec3s, m/s) and `pressure` (float, Pa) on the same voxels when the frame has
///    smoke, else on the liquid's voxels (fluid and φ < 0) with a level set, else on every
///    fluid voxel;
///  - `surface` (float, level set, m) when `v.phi` is given: active where |φ| < 3h (h the
///    largest spacing, a narrow band of 3 voxels each side), values clamped to ±3h, background
///    3h outside and −3h inside (signed flood fill).
/// File metadata as VdbFrameInfo says; OpenVDB's default compression (Blosc). Written under a
/// temporary name and renamed into place; returns the grids' summaries.
/// @throws InputError naming the file if it cannot be written; InternalError for wrong sizes.
std::vector<VdbGridSummary> write_vdb(const std::filesystem::path& path, const VoxelFrame& v,
                                      const VdbFrameInfo& info);

/// The grids of a `.vdb` file (any, not only ours) and its file metadata `tetfsi_step` /
/// `tetfsi_time` if present (else −1 / NaN), read with OpenVDB's reader.
struct VdbFileSummary {
  std::vector<VdbGridSummary> grids;
  int step = -1;
  double time = std::numeric_limits<double>::quiet_NaN();
};
/// @throws InputError naming the file if it is missing or not a readable `.vdb`.
VdbFileSummary read_vdb_summary(const std::filesystem::path& path);

/// Σ value × voxel volume over the active voxels of the float grid `name` in `path` (the
/// smoke mass of `density`). @throws InputError if the file or grid is missing.
double vdb_grid_integral(const std::filesystem::path& path, const std::string& name);

// ---- one frame of an export, and the manifest ---------------------------------------------

/// What to export and how (the scene's `output.export`, `output.voxel_size`, ... or the
/// options of `tetfsi export`).
struct ExportRequest {
  bool vdb = false;
  bool ply = false;
  VoxelOptions voxels;            ///< the tet fluid's sampling
  double smoke_threshold = 1e-4;  ///< VdbFrameInfo::smoke_threshold
  std::string scene;              ///< the scene's name (metadata)
};

/// A named surface of a frame: a body (its output file name) or "liquid".
struct NamedSurface {
  std::string name;
  ExportSurface surface;
};

/// What one exported frame holds (a frame of the manifest).
struct ExportedFrame {
  int frame = 0;  ///< 0, 1, 2, ... the run's frame index (the files' number)
  int step = 0;
  double time = 0.0;
  std::string vdb_file;  ///< relative to the folder ("vdb/fluid_000003.vdb"), "" if none
  std::vector<VdbGridSummary> grids;
  Vec3 voxel_size = Vec3::Zero();
  double smoke_mass = 0.0;  ///< VoxelFrame::smoke_mass (kg)
  struct Mesh {
    std::string name, file;  ///< file relative to the folder ("ply/sheet_000003.ply")
    Index vertices = 0, triangles = 0;
  };
  std::vector<Mesh> meshes;
};

/// Write frame `frame`'s files into `folder` (vdb/, ply/ created as needed): the `.vdb` of
/// `fluid` (if given and request.vdb) and one `.ply` per surface (if request.ply). Every
/// file is written under a temporary name and renamed into place.
/// @throws InputError naming the file if one cannot be written.
ExportedFrame export_frame(const std::filesystem::path& folder, int frame, int step, double time,
                           const std::vector<NamedSurface>& surfaces, const VoxelFrame* fluid,
                           const ExportRequest& request);

nlohmann::json to_json(const ExportedFrame& f);
ExportedFrame exported_frame_from_json(const nlohmann::json& j);

/// `export.json`: {"format": "tetfsi-export 1", "scene", "axes", "frames": [ExportedFrame...]},
/// rewritten atomically after every frame, like a `.pvd`.
class ExportManifest {
 public:
  ExportManifest(std::filesystem::path path, std::string scene);
  void add(ExportedFrame f);  ///< append (replacing a frame of the same number) and rewrite
  /// Keep the frames whose number is < `frames` and rewrite (a resumed run).
  void truncate(int frames);
  void reset(std::vector<ExportedFrame> frames);  ///< replace all and rewrite
  const std::vector<ExportedFrame>& frames() const { return m_frames; }
  const std::filesystem::path& path() const { return m_path; }
  nlohmann::json to_json() const;

 private:
  std::filesystem::path m_path;
  std::string m_scene;
  std::vector<ExportedFrame> m_frames;
  void write() const;
};

}  // namespace tetfsi::app
