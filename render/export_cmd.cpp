/// @file export_cmd.cpp
/// `tetfsi export`: a run's frames read back and written through io/export.hpp
/// (export_cmd.hpp).
#include "render/export_cmd.hpp"

#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <ostream>
#include <regex>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/output.hpp"
#include "render/frame_data.hpp"
#include "render/run_folder.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace tetfsi::app {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// "frames 0..12" (or "frame 0") for the messages about --frames.
std::string frames_of(int count) {
  return count == 1 ? std::string("frame 0") : fmt::format("frames 0..{}", count - 1);
}

/// "834 kB", "12.3 MB".
std::string human_size(std::uintmax_t bytes) {
  if (bytes < 100'000) return fmt::format("{:.3g} kB", double(bytes) / 1e3);
  return fmt::format("{:.3g} MB", double(bytes) / 1e6);
}

/// @throws InputError naming the option whose value is out of range.
void check_options(const ExportOptions& opt) {
  if (opt.voxel_size && !(std::isfinite(*opt.voxel_size) && *opt.voxel_size > 0.0))
    throw InputError(
        fmt::format("--voxel-size: must be a length > 0 (m), got {}", *opt.voxel_size));
  if (opt.subsamples < 1 || opt.subsamples > 8)
    throw InputError(fmt::format("--subsamples: must be in 1..8, got {}", opt.subsamples));
  if (!(std::isfinite(opt.smoke_threshold) && opt.smoke_threshold >= 0.0))
    throw InputError(
        fmt::format("--threshold: must be a density >= 0 (kg/m^3), got {}", opt.smoke_threshold));
}

/// The target folder, created if needed. @throws InputError if it cannot be created or
/// written into.
fs::path target_folder(const fs::path& out_dir, const ExportOptions& opt) {
  const fs::path dir = opt.to.empty() ? out_dir : opt.to;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw InputError(fmt::format("cannot create the folder '{}': {} (choose another with --to)",
                                 dir.string(), ec ? ec.message() : "not a folder"));
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw InputError(fmt::format("cannot write into '{}': {} (choose a writable folder with --to)",
                                 dir.string(), std::strerror(errno)));
  return dir;
}

/// The scene's value at `keys` (nested objects) if it is a number.
std::optional<double> scene_number(const json& scene, std::initializer_list<const char*> keys) {
  const json* j = &scene;
  for (const char* k : keys) {
    if (!j->is_object() || !j->contains(k)) return std::nullopt;
    j = &(*j)[k];
  }
  return j->is_number() ? std::optional<double>(j->get<double>()) : std::nullopt;
}

/// What export_frame is asked for, from the options and the run.
ExportRequest request_of(const RunIndex& run, const ExportOptions& opt) {
  ExportRequest r;
  const bool both = !opt.vdb && !opt.ply;
  r.vdb = (both || opt.vdb) && run.has_fluid;
  r.ply = both || opt.ply;
  if (opt.vdb && !opt.ply && !run.has_fluid)
    throw InputError(fmt::format(
        "--vdb: the run in '{}' has no fluid, so no volume to export; export its surfaces "
        "with --ply",
        run.dir.string()));
  r.scene = run.name;
  r.smoke_threshold = opt.smoke_threshold;
  r.voxels.subsamples = opt.subsamples;
  r.voxels.voxel_size = opt.voxel_size.value_or(
      scene_number(run.scene, {"fluid", "mesh", "surface_size"}).value_or(r.voxels.voxel_size));
  r.voxels.ambient_temperature =
      scene_number(run.scene, {"fluid", "buoyancy", "ambient_temperature"})
          .value_or(r.voxels.ambient_temperature);
  return r;
}

/// The manifest in `folder`, with the frames an earlier export listed that still match the
/// run (same frame number and step). @throws InputError if an export.json there is not one.
ExportManifest open_manifest(const fs::path& folder, const RunIndex& run) {
  ExportManifest manifest(folder / "export.json", run.name);
  std::error_code ec;
  if (!fs::exists(manifest.path(), ec)) return manifest;
  std::vector<ExportedFrame> kept;
  try {
    std::ifstream f(manifest.path());
    const json j = json::parse(f);
    for (const json& fr : j.at("frames")) {
      ExportedFrame e = exported_frame_from_json(fr);
      const auto k = static_cast<size_t>(e.frame);
      if (e.frame >= 0 && k < run.frames.size() && run.frames[k].step == e.step)
        kept.push_back(std::move(e));
    }
  } catch (const std::exception& e) {
    throw InputError(fmt::format(
        "{}: not a readable export manifest ({}); remove it, or export into another folder "
        "with --to",
        manifest.path().string(), one_line(e.what())));
  }
  manifest.reset(std::move(kept));
  return manifest;
}

/// The surfaces of frame `fr`: each body's boundary, then the liquid's surface (io's
/// liquid_surface of the grid frame `grid`, as the run's own export writes it).
std::vector<NamedSurface> surfaces_of(const RunIndex& run, const FrameFiles& fr,
                                      const fluid::GridFrameFields* grid) {
  std::vector<NamedSurface> out;
  for (size_t b = 0; b < fr.bodies.size(); ++b) {
    const TetBodyFrame body = read_body_frame(fr.bodies[b]);
    out.push_back({run.body_names[b],
                   tet_boundary_surface(body.points, body.tets, body.velocity, body.von_mises)});
  }
  if (!fr.liquid.empty() && grid) out.push_back({"liquid", liquid_surface(*grid)});
  return out;
}

/// The fluid of frame `fr` on voxels: the grid frame `grid`'s cells as they are, or the tet
/// fluid sampled.
std::optional<VoxelFrame> voxels_of(const FrameFiles& fr, const ExportRequest& request,
                                    const fluid::GridFrameFields* grid) {
  if (grid) return voxel_frame_of(*grid, request.voxels.ambient_temperature);
  if (fr.fluid.empty()) return std::nullopt;
  return voxelize(read_tet_fluid_frame(fr.fluid), request.voxels);
}

/// Frame `index` of the run read and written into `folder`. A frame file that cannot be read
/// is an InputError naming the frame, the step and the file.
ExportedFrame export_one(const RunIndex& run, int index, const ExportRequest& request,
                         const fs::path& folder) {
  const FrameFiles& fr = run.frames[static_cast<size_t>(index)];
  std::vector<NamedSurface> surfaces;
  std::optional<VoxelFrame> voxels;
  try {
    std::optional<fluid::GridFrameFields> grid;  // read once for the voxels and the liquid
    if (fr.fluid.extension() == ".vti" && (request.vdb || (request.ply && !fr.liquid.empty())))
      grid = read_grid_fluid_frame(fr.fluid);
    if (request.ply) surfaces = surfaces_of(run, fr, grid ? &*grid : nullptr);
    if (request.vdb) voxels = voxels_of(fr, request, grid ? &*grid : nullptr);
  } catch (const InputError& e) {
    throw InputError(fmt::format(
        "frame {} (step {}) of the run in '{}': {}; re-run the scene to write it again, or "
        "leave the frame out with --frames",
        index, fr.step, run.dir.string(), e.what()));
  }
  return export_frame(folder, index, fr.step, fr.time, surfaces, voxels ? &*voxels : nullptr,
                      request);
}

/// The frames' `.vdb` bytes (0 for a file that is not there).
std::uintmax_t vdb_bytes(const fs::path& folder, const ExportedFrame& f) {
  std::error_code ec;
  if (f.vdb_file.empty()) return 0;
  const std::uintmax_t n = fs::file_size(folder / f.vdb_file, ec);
  return ec ? 0 : n;
}

/// The voxel options a grid fluid ignores, as a note ("" if none was given).
std::string grid_note(const ExportOptions& opt) {
  if (!opt.voxel_size && opt.subsamples == ExportOptions().subsamples) return "";
  return "the fluid is a grid: its cells are the voxels, --voxel-size and --subsamples do not "
         "apply";
}

}  // namespace

FrameRange parse_frame_range(const std::string& text, int count) {
  if (text.empty()) return {0, count};
  static const std::regex re(R"(^\s*(\d{0,9})\s*(:?)\s*(\d{0,9})\s*$)");
  std::smatch m;
  const bool ok = std::regex_match(text, m, re) && (m[2].length() > 0 || m[1].length() > 0) &&
                  (m[2].length() > 0 || m[3].length() == 0);
  if (!ok)
    throw InputError(fmt::format(
        "--frames: expected A:B (frames A to B-1), A:, :B or A (frame indices from 0), got "
        "'{}'",
        text));
  FrameRange r{0, count};
  if (m[1].length() > 0) r.begin = std::stoi(m[1].str());
  if (m[2].length() == 0)
    r.end = r.begin + 1;
  else if (m[3].length() > 0)
    r.end = std::stoi(m[3].str());
  if (r.begin >= count || r.end > count)
    throw InputError(fmt::format("--frames {}: the run has {} ({} frames; A:B exports A to B-1)",
                                 text, frames_of(count), count));
  if (r.begin >= r.end)
    throw InputError(
        fmt::format("--frames {}: selects no frame (A:B exports frames A to B-1); the run has {}",
                    text, frames_of(count)));
  return r;
}

ExportReport export_run(const fs::path& out_dir, const ExportOptions& opt, std::ostream* progress) {
  const auto start = Clock::now();
  check_options(opt);
  const RunIndex run = read_run(out_dir);
  const int count = static_cast<int>(run.frames.size());
  ExportReport report;
  report.scene_name = run.name;
  report.range = parse_frame_range(opt.frames, count);
  const ExportRequest request = request_of(run, opt);
  report.folder = target_folder(out_dir, opt);
  ExportManifest manifest = open_manifest(report.folder, run);
  report.manifest = manifest.path();
  const auto& first = run.frames[static_cast<size_t>(report.range.begin)];
  report.grid = first.fluid.extension() == ".vti";
  if (request.vdb && !report.grid) report.voxel_size = request.voxels.voxel_size;
  if (request.vdb && report.grid) report.note = grid_note(opt);
  const int n = report.range.end - report.range.begin;
  for (int i = report.range.begin; i < report.range.end; ++i) {
    const auto frame_start = Clock::now();
    ExportedFrame f = export_one(run, i, request, report.folder);
    const std::uintmax_t bytes = vdb_bytes(report.folder, f);
    report.vdb_bytes += bytes;
    report.vdb_files += f.vdb_file.empty() ? 0 : 1;
    report.ply_files += static_cast<int>(f.meshes.size());
    if (progress) {
      std::string what;
      if (!f.vdb_file.empty()) what = fmt::format("vdb {}, ", human_size(bytes));
      *progress << fmt::format("frame {} [{}/{}] step {} t={:.4g} s: {}{} ply ({:.2f} s)\n", i,
                               i - report.range.begin + 1, n, f.step, f.time, what, f.meshes.size(),
                               seconds_since(frame_start))
                << std::flush;
    }
    manifest.add(f);
    report.frames.push_back(std::move(f));
  }
  report.seconds = seconds_since(start);
  return report;
}

int export_command(const fs::path& out_dir, const ExportOptions& opt, std::ostream& out) {
  const ExportReport r = export_run(out_dir, opt, &out);
  const size_t n = r.frames.size();
  std::string voxels;
  if (r.vdb_files > 0)
    voxels =
        r.grid ? "; voxels: the grid's cells"
               : fmt::format("; voxels {:.4g} m, {}^3 samples each", r.voxel_size, opt.subsamples);
  out << fmt::format(
      "exported {} frame{} ({}..{}) of {} into {}: {} vdb ({}), {} ply{}; manifest {}; "
      "{:.3g} s ({:.3g} s per frame)\n",
      n, n == 1 ? "" : "s", r.range.begin, r.range.end - 1, r.scene_name, r.folder.string(),
      r.vdb_files, human_size(r.vdb_bytes), r.ply_files, voxels, r.manifest.string(), r.seconds,
      r.seconds / double(std::max<size_t>(n, 1)));
  out.flush();
  if (!r.note.empty()) std::fprintf(stderr, "hint: %s\n", r.note.c_str());
  return 0;
}

}  // namespace tetfsi::app
