/// @file run_folder.cpp
/// A run's output folder: scene.resolved.json and the `.pvd` collections (run_folder.hpp).
#include "render/run_folder.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include <fmt/format.h>

#include "core/error.hpp"
#include "io/output.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace tetfsi::app {

/// The (time, file) entries of a `.pvd`, files resolved against its folder.
std::vector<std::pair<double, fs::path>> read_pvd(const fs::path& pvd) {
  std::ifstream f(pvd);
  if (!f) throw InputError(fmt::format("cannot read '{}': {}", pvd.string(), std::strerror(errno)));
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  static const std::regex dataset(R"(<DataSet\b[^>]*>)");
  static const std::regex timestep(R"(\btimestep\s*=\s*"([^"]*)\")");
  static const std::regex file(R"(\bfile\s*=\s*"([^"]*)\")");
  std::vector<std::pair<double, fs::path>> out;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), dataset);
       it != std::sregex_iterator(); ++it) {
    const std::string tag = it->str();
    std::smatch t, fm;
    if (!std::regex_search(tag, t, timestep) || !std::regex_search(tag, fm, file))
      throw InputError(fmt::format("{}: a DataSet without timestep or file: {}", pvd.string(),
                                   tag.substr(0, 120)));
    double time = 0.0;
    try {
      time = std::stod(t[1].str());
    } catch (const std::exception&) {
      throw InputError(fmt::format("{}: timestep '{}' is not a number", pvd.string(), t[1].str()));
    }
    out.emplace_back(time, pvd.parent_path() / fm[1].str());
  }
  return out;
}

/// The step in a frame's file name (`sheet_000050.vtu` → 50), or −1.
int step_of(const fs::path& file) {
  static const std::regex re(R"(_(\d+)$)");
  std::smatch m;
  const std::string stem = file.stem().string();
  if (!std::regex_search(stem, m, re) || m[1].length() > 9) return -1;
  return std::stoi(m[1].str());
}

/// The numbers of `vec` as a Vec3 (or a 2-vector padded with 0).
Vec3 vec3_of(const json& v) {
  Vec3 x = Vec3::Zero();
  for (size_t i = 0; i < std::min<size_t>(3, v.size()); ++i) x(i) = v[i].get<double>();
  return x;
}

namespace {

/// @throws InputError unless `dir` is a folder.
void check_run_folder(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec))
    throw InputError(fmt::format(
        "no such output folder '{}': give the folder a run wrote (`tetfsi run SCENE --out {}`)",
        dir.string(), dir.string()));
  if (!fs::is_directory(dir, ec))
    throw InputError(
        fmt::format("'{}' is not a folder: give the output folder of a run (OUT of "
                    "`tetfsi run SCENE --out OUT`)",
                    dir.string()));
}

/// The run's resolved scene (scene.resolved.json) into `run.scene`.
void read_resolved_scene(const fs::path& dir, RunIndex& run) {
  std::error_code ec;
  run.dir = dir;
  const fs::path resolved = dir / "scene.resolved.json";
  if (!fs::exists(resolved, ec))
    throw InputError(
        fmt::format("'{}' holds no run: no scene.resolved.json there; give the "
                    "folder `tetfsi run SCENE --out OUT` wrote",
                    dir.string()));
  try {
    std::ifstream f(resolved);
    run.scene = json::parse(f);
  } catch (const std::exception& e) {
    throw InputError(
        fmt::format("{}: not readable JSON ({})", resolved.string(), one_line(e.what())));
  }
}

/// What the pictures need of the scene: the bodies' names, the fluid box, the jet's height,
/// the smoke it emits.
void read_scene_facts(const fs::path& dir, RunIndex& run) {
  const json& s = run.scene;
  run.name = s.value("name", dir.filename().string());
  if (s.contains("bodies"))
    for (const json& b : s["bodies"]) {
      run.body_names.push_back(file_safe_name(b.value("name", "")));
      run.kinematic.push_back(b.contains("kinematic") && b["kinematic"].is_object());
    }
  if (s.contains("fluid") && s["fluid"].is_object()) {
    run.has_fluid = true;
    const json& fl = s["fluid"];
    if (fl.contains("domain")) {
      const json& d = fl["domain"];
      run.domain = Box{vec3_of(d.at("lo")), vec3_of(d.at("hi"))};
      double z_sum = 0.0;
      int z_count = 0;
      for (const json& p : d.value("patches", json::array())) {
        if (p.value("kind", "") != "inflow") continue;
        run.emitted_smoke = std::max(run.emitted_smoke, p.value("smoke", 0.0));
        const std::string side = p.value("side", "");
        if (side.size() != 2 || side[1] == 'z') continue;  // a patch on a z side: no height
        z_sum += 0.5 * (p.at("lo")[1].get<double>() + p.at("hi")[1].get<double>());
        ++z_count;
      }
      if (z_count > 0) run.jet_z = z_sum / z_count;
    }
    for (const json& src : fl.value("sources", json::array()))
      run.emitted_smoke = std::max(run.emitted_smoke, src.value("smoke", 0.0));
  }
}

/// The frames: the steps of the bodies' collections (the fluid's without bodies), each with
/// its files; a frame not every collection lists yet is left out.
void read_frames(const fs::path& dir, RunIndex& run) {
  std::error_code ec;
  std::map<int, FrameFiles> by_step;
  auto add_stream = [&](const fs::path& pvd, int body) {
    if (!fs::exists(pvd, ec))
      throw InputError(
          fmt::format("{}: missing; the run in '{}' wrote no frames of it (was it "
                      "stopped before its first frame?)",
                      pvd.string(), dir.string()));
    for (const auto& [time, file] : read_pvd(pvd)) {
      const int step = step_of(file);
      if (step < 0) continue;
      FrameFiles& fr = by_step[step];
      fr.step = step;
      fr.time = time;
      if (body == -2)
        fr.liquid = file;
      else if (body < 0)
        fr.fluid = file;
      else {
        fr.bodies.resize(run.body_names.size());
        fr.bodies[static_cast<size_t>(body)] = file;
      }
    }
  };
  for (size_t b = 0; b < run.body_names.size(); ++b)
    add_stream(dir / (run.body_names[b] + ".pvd"), static_cast<int>(b));
  if (run.has_fluid) add_stream(dir / "fluid.pvd", -1);
  run.has_liquid = run.has_fluid && fs::exists(dir / "liquid.pvd", ec);
  if (run.has_liquid) add_stream(dir / "liquid.pvd", -2);
  for (auto& [step, fr] : by_step) {
    fr.bodies.resize(run.body_names.size());
    // A frame the bodies' collections do not all list (a frame being written) is left out.
    const bool complete = std::all_of(fr.bodies.begin(), fr.bodies.end(),
                                      [](const fs::path& p) { return !p.empty(); });
    if (complete && (!fr.bodies.empty() || !fr.fluid.empty())) run.frames.push_back(fr);
  }
  if (run.frames.empty())
    throw InputError(
        fmt::format("'{}' has no frames yet: its .pvd collections list none", dir.string()));
}

}  // namespace

RunIndex read_run(const fs::path& dir) {
  check_run_folder(dir);
  RunIndex run;
  read_resolved_scene(dir, run);
  read_scene_facts(dir, run);
  read_frames(dir, run);
  return run;
}

/// "0, 2, 4, ..., 98, 100 (51 frames)" for the message of a missing step.
std::string list_steps(const RunIndex& run) {
  std::vector<int> s;
  for (const FrameFiles& f : run.frames) s.push_back(f.step);
  auto join = [](auto begin, auto end) {
    std::string out;
    for (auto it = begin; it != end; ++it) out += (out.empty() ? "" : ", ") + std::to_string(*it);
    return out;
  };
  if (s.size() <= 8) return join(s.begin(), s.end());
  return fmt::format("{}, ..., {} ({} frames)", join(s.begin(), s.begin() + 3),
                     join(s.end() - 2, s.end()), s.size());
}

}  // namespace tetfsi::app
