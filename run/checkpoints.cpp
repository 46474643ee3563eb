#include "run/checkpoints.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ostream>

#include <fmt/format.h>

#include "core/checkpoint.hpp"
#include "core/error.hpp"
#include "core/log.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace tetfsi::app {

fs::path checkpoint_dir(const fs::path& out_dir) {
  return out_dir / "checkpoints";
}

fs::path checkpoint_path(const fs::path& out_dir, int step) {
  return checkpoint_dir(out_dir) / fmt::format("step_{:06d}.tfck", step);
}

namespace {

/// The step of "step_000120.tfck", or nothing for any other name.
std::optional<int> step_of(const std::string& name) {
  const std::string prefix = "step_", suffix = ".tfck";
  if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
    return std::nullopt;
  const std::string digits =
      name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
  if (digits.size() > 9 ||
      !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); }))
    return std::nullopt;
  return std::stoi(digits);
}

void remove_logged(const fs::path& p) {
  std::error_code ec;
  fs::remove(p, ec);
  if (ec) logger().warn("could not delete '{}': {}", p.string(), ec.message());
}

}  // namespace

std::vector<CheckpointFile> list_checkpoints(const fs::path& out_dir) {
  std::vector<CheckpointFile> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(checkpoint_dir(out_dir), ec)) {
    if (const auto step = step_of(e.path().filename().string())) files.push_back({*step, e.path()});
  }
  std::sort(files.begin(), files.end(),
            [](const CheckpointFile& a, const CheckpointFile& b) { return a.step < b.step; });
  return files;
}

void prune_checkpoints(const fs::path& out_dir, int step, int keep) {
  std::vector<CheckpointFile> files = list_checkpoints(out_dir);
  int kept = 0;
  for (auto it = files.rbegin(); it != files.rend(); ++it) {
    if (it->step > step || kept >= keep)
      remove_logged(it->path);
    else
      ++kept;
  }
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(checkpoint_dir(out_dir), ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0 &&
        step_of(name.substr(0, name.size() - 4)))
      remove_logged(e.path());
  }
}

void remove_earlier_checkpoints(const fs::path& out_dir) {
  const std::vector<CheckpointFile> files = list_checkpoints(out_dir);
  if (files.empty()) return;
  prune_checkpoints(out_dir, -1, 0);  // every step is "later" than -1
  logger().warn("removed the {} checkpoint(s) of an earlier run in '{}' (this run replaces it)",
                files.size(), checkpoint_dir(out_dir).string());
}

json physics_part(const json& resolved) {
  json j = resolved;
  if (!j.is_object()) return j;
  j.erase("output");
  j.erase("description");
  if (j.contains("time") && j["time"].is_object()) {
    j["time"].erase("steps");
    j["time"].erase("end_time");
  }
  return j;
}

std::uint64_t physics_hash(const json& resolved) {
  const std::string text = physics_part(resolved).dump();
  std::uint64_t h = 14695981039346656037ull;  // FNV-1a, 64 bit
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::optional<std::string> first_difference(const json& a, const json& b, const std::string& path) {
  const std::string where = path.empty() ? "(top level)" : path;
  if (a.is_object() && b.is_object()) {
    for (const auto& [k, v] : a.items()) {
      const std::string p = path.empty() ? k : path + "." + k;
      if (!b.contains(k)) return fmt::format("{}: {} vs (none)", p, v.dump());
      if (auto d = first_difference(v, b.at(k), p)) return d;
    }
    for (const auto& [k, v] : b.items()) {
      const std::string p = path.empty() ? k : path + "." + k;
      if (!a.contains(k)) return fmt::format("{}: (none) vs {}", p, v.dump());
    }
    return std::nullopt;
  }
  if (a.is_array() && b.is_array()) {
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
      if (auto d = first_difference(a[i], b[i], fmt::format("{}[{}]", path, i))) return d;
    if (a.size() != b.size())
      return fmt::format("{}: {} elements vs {}", where, a.size(), b.size());
    return std::nullopt;
  }
  if (a == b) return std::nullopt;
  return fmt::format("{}: {} vs {}", where, a.dump(), b.dump());
}

double parse_wall_time(const std::string& text) {
  int h = 0, m = 0, s = 0;
  char c1 = 0, c2 = 0;
  int used = 0;
  const bool ok = std::sscanf(text.c_str(), "%d%c%d%c%d%n", &h, &c1, &m, &c2, &s, &used) == 5 &&
                  used == static_cast<int>(text.size()) && c1 == ':' && c2 == ':' && h >= 0 &&
                  m >= 0 && m < 60 && s >= 0 && s < 60 &&
                  std::isdigit(static_cast<unsigned char>(text[0]));
  TETFSI_REQUIRE(InputError, ok && (h > 0 || m > 0 || s > 0),
                 "--wall-time: expected HH:MM:SS (e.g. 11:30:00), got '{}'", text);
  return 3600.0 * h + 60.0 * m + s;
}

std::string shell_quote(const std::string& s) {
  const bool plain = !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) {
    return std::isalnum(c) || std::strchr("_-./=:@%+,", c) != nullptr;
  });
  if (plain) return s;
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

int checkpoint_command(const fs::path& file, std::ostream& out) {
  const CheckpointReader r(file);
  out << fmt::format("checkpoint '{}': format version {}, {} records, {} bytes, every CRC valid\n",
                     file.string(), k_checkpoint_version, r.entries().size(), r.file_bytes());
  if (r.has("run/step")) {
    std::string scene = "?";
    if (r.has("run/scene")) {
      const json j = json::parse(r.get_text("run/scene"), nullptr, false);
      if (j.is_object() && j.contains("name")) scene = j["name"].get<std::string>();
    }
    out << fmt::format(
        "run: scene '{}', step {} of {}, t = {:.17g} s, physics hash {:016x}\n", scene,
        r.get_int("run/step"), r.has("run/steps_planned") ? r.get_int("run/steps_planned") : -1,
        r.has("run/time") ? r.get_double("run/time") : NAN,
        r.has("run/physics_hash") ? static_cast<std::uint64_t>(r.get_int("run/physics_hash")) : 0);
  }
  std::size_t width = 3;
  for (const auto& e : r.entries()) width = std::max(width, e.key.size());
  out << fmt::format("{:<{}}  {:<6}  {:>15}  {:>12}\n", "key", width, "type", "shape", "bytes");
  for (const auto& e : r.entries()) {
    const std::string shape =
        e.type == RecordType::Text ? "text" : fmt::format("{} x {}", e.rows, e.cols);
    out << fmt::format("{:<{}}  {:<6}  {:>15}  {:>12}\n", e.key, width, to_string(e.type), shape,
                       e.bytes);
  }
  return 0;
}

}  // namespace tetfsi::app
