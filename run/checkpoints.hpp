#pragma once
/// @file checkpoints.hpp
/// The checkpoints of a run's output folder (`tetfsi run --checkpoint-every N`, `tetfsi
/// resume`): where they live, which to keep, which scene they belong to, and the listing of
/// `tetfsi checkpoint FILE`. The file format is core/checkpoint.hpp's; what a run stores in it
/// is in run/run.hpp (records "sim/" from coupling::FsiSimulation::save_state, "run/" from
/// the run loop).
///
///     OUT/checkpoints/step_000120.tfck    the state after step 120
///     OUT/checkpoints/step_000120.tfck.tmp  being written (a crash leaves it; never read)
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tetfsi::app {

/// OUT/checkpoints
std::filesystem::path checkpoint_dir(const std::filesystem::path& out_dir);
/// OUT/checkpoints/step_NNNNNN.tfck (six digits, more past 999999).
std::filesystem::path checkpoint_path(const std::filesystem::path& out_dir, int step);

struct CheckpointFile {
  int step = 0;
  std::filesystem::path path;
};
/// The checkpoint files of OUT (names step_<digits>.tfck), by step, oldest first; none if the
/// folder does not exist. Their contents are not read.
std::vector<CheckpointFile> list_checkpoints(const std::filesystem::path& out_dir);

/// After the checkpoint of `step` was written: delete every checkpoint of a later step (left
/// by a run that went on past the checkpoint this one resumed from), all but the `keep`
/// newest of the rest, and any leftover temporary file (a write that was killed). Failures
/// to delete are logged, not thrown.
void prune_checkpoints(const std::filesystem::path& out_dir, int step, int keep);

/// A fresh run into a folder that holds an earlier run: delete that run's checkpoints (and
/// leftover temporary files), which `resume` would otherwise take for this run's; logs how
/// many. Other files in OUT/checkpoints stay.
void remove_earlier_checkpoints(const std::filesystem::path& out_dir);

/// The resolved scene without what a resumed run may change: output.* (frames, compression,
/// checkpoints), time.steps and time.end_time (the run's length), and description.
nlohmann::json physics_part(const nlohmann::json& resolved);
/// 64-bit FNV-1a of physics_part(resolved).dump(): equal for scenes with equal physics.
std::uint64_t physics_hash(const nlohmann::json& resolved);
/// The first difference between two JSON values, depth first in `a`'s key order, as
/// "fluid.density: 1.2 vs 2" (array elements as bodies[0]); nothing if they are equal.
std::optional<std::string> first_difference(const nlohmann::json& a, const nlohmann::json& b,
                                            const std::string& path = "");

/// "HH:MM:SS" (hours may exceed 23; minutes and seconds 0..59) → seconds.
/// @throws InputError naming the text.
double parse_wall_time(const std::string& text);

/// `s` quoted for a POSIX shell if it needs it ('it''s' style), else as it is.
std::string shell_quote(const std::string& s);

/// `tetfsi checkpoint FILE`: verify the file and list its run (step, time, scene, format
/// version, size) and every record (key, type, shape, bytes). Returns the exit code.
/// @throws CheckpointError for an unusable file.
int checkpoint_command(const std::filesystem::path& file, std::ostream& out);

}  // namespace tetfsi::app
