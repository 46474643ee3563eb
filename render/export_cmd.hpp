#pragma once
/// @file export_cmd.hpp
/// `tetfsi export OUT`: a finished (or running) run's frames as files for renderers — the
/// fluid as OpenVDB volumes, the bodies' and the liquid's surfaces as PLY meshes, and the
/// manifest export.json — in the layout of io/export.hpp, written by its `export_frame` and
/// `ExportManifest` (the one place that writes them; the run's own export writes the same).
///
/// Per frame (the run's frames in step order, numbered 0, 1, 2, ... as the files are):
///  - each body's `.vtu` (points, tets, point `velocity`, cell `von_mises_stress`) →
///    tet_boundary_surface → `ply/<body>_<frame>.ply`;
///  - a liquid: the grid fluid's `.vti` (its `phi`) → liquid_surface (io/output.hpp, as the
///    run's own export: closed on the box's walls) → `ply/liquid_<frame>.ply`, for the frames
///    whose liquid `.vtp` the run wrote;
///  - the tet fluid's `.vtu` (cell `smoke_density`, `temperature`, `pressure`, point
///    `velocity`) → TetVolume → voxelize (voxel size default: the resolved scene's
///    `fluid.mesh.surface_size`) → `vdb/fluid_<frame>.vdb`; the grid fluid's `.vti` →
///    GridFrameFields → voxel_frame_of (its cells are the voxels: the voxel options do not
///    apply).
/// Nothing of the run is modified: only vdb/, ply/ and export.json under the target folder
/// (default OUT) are written. An export.json already there keeps its other frames.
///
/// VTK stays in frame_data.cpp, OpenVDB in io/; this header only has plain types.
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "io/export.hpp"

namespace tetfsi::app {

struct ExportOptions {
  bool vdb = false;  ///< the fluid's `.vdb` files (neither vdb nor ply: both)
  bool ply = false;  ///< the surfaces' `.ply` files
  /// The tet fluid's voxel edge (m); default the scene's fluid.mesh.surface_size.
  std::optional<double> voxel_size;
  int subsamples = 2;             ///< VoxelOptions::subsamples, in 1..8
  double smoke_threshold = 1e-4;  ///< VdbFrameInfo::smoke_threshold (kg/m³), ≥ 0
  std::string frames;             ///< parse_frame_range's text; "" every frame
  std::filesystem::path to;       ///< the target folder; "" the run's folder
};

/// A half-open range of the run's frame indices [begin, end).
struct FrameRange {
  int begin = 0, end = 0;
};

/// `--frames` against a run of `count` frames: "A:B" the frames A to B − 1 (half-open, as
/// Python's slices), "A:" from A to the last, ":B" from 0 to B − 1, "A" frame A alone, ""
/// every frame. @throws InputError naming the text and the run's frames ("the run has frames
/// 0..12") if it is malformed, empty or outside the run.
FrameRange parse_frame_range(const std::string& text, int count);

struct ExportReport {
  std::string scene_name;
  std::filesystem::path folder;    ///< the target folder
  std::filesystem::path manifest;  ///< its export.json
  FrameRange range;
  std::vector<ExportedFrame> frames;  ///< the frames written, in order
  bool grid = false;                  ///< the fluid is a grid (its cells are the voxels)
  double voxel_size = 0.0;            ///< the tet fluid's voxel edge (m); 0 without voxels
  std::uintmax_t vdb_bytes = 0;       ///< the `.vdb` files written
  int vdb_files = 0, ply_files = 0;
  double seconds = 0.0;  ///< wall time
  std::string note;      ///< one line for the user (voxel options a grid ignores), or ""
};

/// Export the frames of the run in `out_dir` that `options` selects, one progress line per
/// frame on `progress` (if given): "frame 3 [1/4] step 60 t=1.2 s: vdb 1.2 MB (0.4 s), 2 ply".
/// @throws InputError (one line naming the folder, file or frame and what to do) for a folder
///   that is no run or has no frames, a frame range outside the run, a frame file missing or
///   unreadable, --vdb for a run without a fluid, bad options, or a target folder that cannot
///   be written.
ExportReport export_run(const std::filesystem::path& out_dir, const ExportOptions& options,
                        std::ostream* progress);

/// `tetfsi export`: export_run with its progress and a summary line on `out`. Returns 0.
int export_command(const std::filesystem::path& out_dir, const ExportOptions& options,
                   std::ostream& out);

}  // namespace tetfsi::app
