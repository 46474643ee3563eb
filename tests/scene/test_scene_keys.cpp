/// @file test_scene_keys.cpp
/// The scene-key tables (scene/scene_keys.hpp): docs/user/scene_keys.md's tables are the
/// generated ones, the tables' defaults are what the parser fills in, and every key's unknown-key
/// suggestion and range check come from its row.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "core/error.hpp"
#include "scene/scene.hpp"
#include "scene/scene_keys.hpp"

using nlohmann::json;
using namespace tetfsi;
using namespace tetfsi::app;
namespace fs = std::filesystem;

namespace {

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// docs/user/scene_keys.md's generated blocks by section name: "<!-- keys:begin NAME -->" ...
/// through
/// "<!-- keys:end -->\n".
std::map<std::string, std::string> readme_blocks(const std::string& text) {
  const std::string begin = "<!-- keys:begin ", end = "<!-- keys:end -->\n";
  std::map<std::string, std::string> blocks;
  for (std::size_t at = text.find(begin); at != std::string::npos; at = text.find(begin, at + 1)) {
    const std::size_t name_end = text.find(" -->", at);
    const std::size_t stop = text.find(end, at);
    REQUIRE(name_end != std::string::npos);
    REQUIRE_MESSAGE(stop != std::string::npos, "scene_keys.md: a keys:begin without keys:end");
    const std::string name = text.substr(at + begin.size(), name_end - at - begin.size());
    CHECK_MESSAGE(blocks.count(name) == 0, "scene_keys.md: section '" << name << "' twice");
    blocks[name] = text.substr(at, stop + end.size() - at);
  }
  return blocks;
}

/// A fluid scene with one body and every fluid sub-section given empty (all defaults).
json fluid_scene() {
  return json::parse(R"({
    "bodies": [ { "name": "b", "mesh": { "box": { "lo": [0.4, 0.4, 0.4], "hi": [0.6, 0.6, 0.6] } } } ],
    "fluid": { "domain": { "lo": [0, 0, 0], "hi": [1, 1, 1] }, "mesh": {}, "buoyancy": {},
               "decay": {}, "transfer": {}, "solver": {}, "refine": {} },
    "time": {}, "output": {}, "solver": {}, "solid": {}, "static": {}, "coupling": {}
  })");
}

/// The sections that sit at one fixed path of fluid_scene() (not inside an array).
const std::set<std::string> k_fixed = {"",
                                       "time",
                                       "output",
                                       "solver",
                                       "solid",
                                       "static",
                                       "fluid",
                                       "fluid.domain",
                                       "fluid.mesh",
                                       "fluid.buoyancy",
                                       "fluid.decay",
                                       "fluid.transfer",
                                       "fluid.solver",
                                       "fluid.refine",
                                       "coupling"};

json* at_path(json& root, const std::string& path) {
  json* cur = &root;
  std::stringstream ss(path);
  for (std::string part; std::getline(ss, part, '.');) cur = &(*cur)[part];
  return cur;
}

std::string parse_error(const json& j) {
  try {
    parse_scene(j, "scene.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("docs/user/scene_keys.md's scene key tables are the generated ones") {
  const fs::path readme = fs::path(TETFSI_SOURCE_DIR) / "docs" / "user" / "scene_keys.md";
  const std::map<std::string, std::string> blocks = readme_blocks(read_text(readme));
  std::set<std::string> names;
  for (const KeySection& s : scene_key_sections()) {
    const std::string name = section_name(s);
    names.insert(name);
    const auto it = blocks.find(name);
    CHECK_MESSAGE(it != blocks.end(), "docs/user/scene_keys.md has no table for section '"
                                          << name << "': regenerate with "
                                          << "`build/cli/tetfsi scene --keys --markdown`");
    if (it == blocks.end()) continue;
    CHECK_MESSAGE(it->second == section_markdown(s),
                  "docs/user/scene_keys.md's table of section '"
                      << name << "' differs from scene/scene_keys.cpp; regenerate it with "
                      << "`build/cli/tetfsi scene --keys --markdown`:\n"
                      << section_markdown(s));
  }
  for (const auto& [name, text] : blocks)
    CHECK_MESSAGE(
        names.count(name) == 1,
        "docs/user/scene_keys.md has a table of an unknown section '" << name << "'; remove it");
  // --markdown is the blocks, in order, one blank line apart.
  std::string all;
  for (const KeySection& s : scene_key_sections()) {
    if (!all.empty()) all += '\n';
    all += section_markdown(s);
  }
  CHECK(scene_keys_markdown() == all);
}

TEST_CASE("every section's keys are unique and documented") {
  std::set<std::string> paths;
  for (const KeySection& s : scene_key_sections()) {
    CHECK_MESSAGE(paths.insert(section_name(s)).second,
                  "section '" << section_name(s) << "' twice");
    CHECK_FALSE(s.title.empty());
    std::set<std::string> keys;
    for (const KeyRow& r : s.rows) {
      INFO(s.path << "." << r.spec.key);
      CHECK(keys.insert(r.spec.key).second);
      CHECK_FALSE(r.spec.doc.empty());
      CHECK(r.spec.doc.find('\n') == std::string::npos);
      CHECK(r.spec.choices.empty() == r.spec.choice_what.empty());
    }
  }
  // The plain listing has a line per key.
  std::size_t rows = 0;
  for (const KeySection& s : scene_key_sections()) rows += s.rows.size();
  const std::string text = scene_keys_text();
  CHECK(static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) ==
        rows + 2 * scene_key_sections().size() + scene_key_sections().size() - 1);
}

TEST_CASE("the tables' defaults are what the parser fills in") {
  const Scene s = parse_scene(fluid_scene(), "scene.json");
  json resolved = s.resolved;
  int compared = 0;
  for (const KeySection& sec : scene_key_sections()) {
    if (!k_fixed.count(sec.path)) continue;
    const json& values = sec.path.empty() ? resolved : *at_path(resolved, sec.path);
    for (const KeyRow& r : sec.rows) {
      const KeyType t = r.spec.type;
      if (!r.spec.default_text.empty() || r.spec.required || t == KeyType::Object ||
          t == KeyType::Array)
        continue;
      INFO(sec.path << "." << r.spec.key);
      const json v = values.contains(r.spec.key) ? values.at(r.spec.key) : json();
      CHECK(key_value_text(v) == r.default_text);
      ++compared;
    }
  }
  CHECK(compared >= 45);
}

TEST_CASE("every key's typo is caught with a suggestion, every bound is checked") {
  int typos = 0, bounds = 0, upper = 0;
  for (const KeySection& sec : scene_key_sections()) {
    if (!k_fixed.count(sec.path)) continue;
    for (const KeyRow& r : sec.rows) {
      const std::string full = sec.path.empty() ? r.spec.key : sec.path + "." + r.spec.key;
      INFO(full);
      // A typo: one letter doubled.
      json j = fluid_scene();
      json& section = sec.path.empty() ? j : *at_path(j, sec.path);
      std::string typo = r.spec.key;
      typo.push_back(typo.back());
      section[typo] = 1;
      const std::string prefix = sec.path.empty() ? typo : sec.path + "." + typo;
      CHECK(parse_error(j) ==
            fmt::format("scene.json: {}: unknown key (did you mean '{}'?)", prefix, r.spec.key));
      ++typos;
      // Just outside the upper bound (the row's range within its unit's limits).
      const Range range = r.spec.limits();
      const bool numeric = r.spec.type == KeyType::Number || r.spec.type == KeyType::Integer;
      if (numeric && std::isfinite(range.hi) && r.spec.type == KeyType::Number) {
        json k = fluid_scene();
        const double above = range.hi_open ? range.hi : range.hi * 1.5 + 1;
        (sec.path.empty() ? k : *at_path(k, sec.path))[r.spec.key] = above;
        const std::string message = parse_error(k);
        CHECK(message.rfind(fmt::format("scene.json: {}: must be", full), 0) == 0);
        CHECK(message.find(range.text(false)) != std::string::npos);
        ++upper;
      }
      // Just outside the lower bound.
      if (!numeric || !std::isfinite(range.lo)) continue;
      json k = fluid_scene();
      const double below = range.lo_open ? range.lo : range.lo - 1;
      (sec.path.empty() ? k : *at_path(k, sec.path))[r.spec.key] = below;
      const std::string message = parse_error(k);
      CHECK(message.rfind(fmt::format("scene.json: {}: must be", full), 0) == 0);
      CHECK(message.find(fmt::format("got {}", below)) != std::string::npos);
      ++bounds;
    }
  }
  CHECK(typos >= 60);
  CHECK(bounds >= 25);
  CHECK(upper >= 15);
}
