#pragma once
/// @file run_folder.hpp
/// A run's output folder as `tetfsi run` wrote it (io/output.hpp): its resolved scene
/// (scene.resolved.json) and its frames, found through the `.pvd` collections of the bodies,
/// the fluid and the liquid. Read by `tetfsi render` and `tetfsi export`; the frame files
/// themselves are read by their callers (render.cpp, frame_data.hpp).
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/types.hpp"

namespace tetfsi::app {

/// The files of one frame (one step).
struct FrameFiles {
  int step = 0;
  double time = 0.0;
  std::filesystem::path fluid;                ///< "" if the frame has no fluid mesh
  std::filesystem::path liquid;               ///< the liquid's surface (liquid.pvd), "" if none
  std::vector<std::filesystem::path> bodies;  ///< per body, in body order
};

/// An axis-aligned box (m).
struct Box {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Ones();
  Vec3 center() const { return 0.5 * (lo + hi); }
};

/// A run's output folder, read from scene.resolved.json and the `.pvd` collections.
struct RunIndex {
  std::filesystem::path dir;
  std::string name;
  nlohmann::json scene;
  std::vector<std::string> body_names;  ///< file-safe names, in body order
  std::vector<bool> kinematic;          ///< per body: moved rigidly (no stress to colour)
  bool has_fluid = false;
  bool has_liquid = false;         ///< a free surface: liquid.pvd
  std::optional<Box> domain;       ///< fluid.domain
  double emitted_smoke = 0.0;      ///< largest smoke density of an inflow patch or source
  std::optional<double> jet_z;     ///< mean height of the inflow patches' centres (m)
  std::vector<FrameFiles> frames;  ///< by step

  const FrameFiles* find(int step) const {
    for (const FrameFiles& f : frames)
      if (f.step == step) return &f;
    return nullptr;
  }
};

/// The (time, file) entries of a `.pvd`, files resolved against its folder.
/// @throws InputError naming the file if it cannot be read or a DataSet lacks its timestep
///   or file.
std::vector<std::pair<double, std::filesystem::path>> read_pvd(const std::filesystem::path& pvd);

/// The step in a frame's file name (`sheet_000050.vtu` → 50), or −1.
int step_of(const std::filesystem::path& file);

/// The numbers of `vec` as a Vec3 (or a 2-vector padded with 0).
Vec3 vec3_of(const nlohmann::json& v);

/// The run in `dir`: its scene's facts and its frames (the steps of the bodies' collections,
/// the fluid's without bodies; a frame not every collection lists yet is left out).
/// @throws InputError for a missing folder, a folder without scene.resolved.json, a missing
///   collection or no frames, each naming the folder and what to do.
RunIndex read_run(const std::filesystem::path& dir);

/// "0, 2, 4, ..., 98, 100 (51 frames)" for the message of a missing step.
std::string list_steps(const RunIndex& run);

}  // namespace tetfsi::app
