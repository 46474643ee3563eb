// Issue 21's fuzz harness: seeded mutations of small scenes and mesh files through
// `tetfsi validate` (and `quality`, and a two-step `run` of what validate accepts), each under
// a memory and a time limit. Every outcome must be exit 0, or exit 1 with exactly one line
// `error: ...` that is not a bare C++ message; a crash, a signal, a hang or a second error
// line fails the case, whose input is kept in fuzz_failures/ (next to the test's working
// folder) to reproduce it. A short seeded sample runs in `make test`; the long run (label
// "long") does 2,500 scenes and 1,000 mesh files. TETFSI_FUZZ_SEED and TETFSI_FUZZ_CASES
// (scenes,meshes) override the seed and the counts for exploration.
#include <doctest/doctest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using tetfsi::test::CliResult;
using tetfsi::test::read_text;
using tetfsi::test::run_tetfsi;
using tetfsi::test::TempDir;

const fs::path k_src = TETFSI_SOURCE_DIR;
/// Per process: 4 GB of address space, 60 s (the shipped scenes validate within a second).
const char* const k_limits = "ulimit -v 4000000; timeout -s KILL 60";

using Rng = std::mt19937_64;

size_t pick(Rng& rng, size_t n) {
  return std::uniform_int_distribution<size_t>(0, n - 1)(rng);
}
bool chance(Rng& rng, double p) {
  return std::uniform_real_distribution<double>(0, 1)(rng) < p;
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

// ---- scene mutations ------------------------------------------------------------------------

/// Every value of the tree as a JSON pointer (the root excluded).
void collect_pointers(const json& j, const json::json_pointer& at,
                      std::vector<json::json_pointer>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      out.push_back(at / it.key());
      collect_pointers(*it, at / it.key(), out);
    }
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i) {
      out.push_back(at / i);
      collect_pointers(j[i], at / i, out);
    }
  }
}

json nested_array(int depth) {
  json j = json::array();
  for (int i = 0; i < depth; ++i) j = json::array({j});
  return j;
}

/// A value a hostile tester would put anywhere.
json hostile_value(Rng& rng) {
  static const std::vector<json> values = {0,
                                           -1,
                                           1,
                                           -0.0,
                                           1e308,
                                           -1e308,
                                           1e-308,
                                           4.9e-324,
                                           4294967295,
                                           -2147483648,
                                           9.2e18,
                                           18446744073709551615ull,
                                           1e15,
                                           -1e15,
                                           0.5,
                                           3,
                                           "nan",
                                           "inf",
                                           "",
                                           "x",
                                           nullptr,
                                           true,
                                           false,
                                           json::array(),
                                           json::object(),
                                           json::array({1, 2}),
                                           json::array({0, 0, 0}),
                                           json::array({1e308, 1e308, 1e308}),
                                           json::array({-1, -1, -1}),
                                           json::array({4294967295, 1, 1}),
                                           json::object({{"unknown_key", 1}})};
  const size_t k = pick(rng, values.size() + 2);
  if (k == values.size()) return nested_array(static_cast<int>(10 + pick(rng, 200)));
  if (k == values.size() + 1) return std::string(1 + pick(rng, 5000), 'a');
  return values[k];
}

/// One mutation of the tree at a random place: delete, replace, scale, rename, duplicate.
void mutate_tree(json& root, Rng& rng) {
  std::vector<json::json_pointer> ptrs;
  collect_pointers(root, json::json_pointer(), ptrs);
  if (ptrs.empty()) return;
  const json::json_pointer at = ptrs[pick(rng, ptrs.size())];
  json& v = root[at];
  json& parent = root[at.parent_pointer()];
  switch (pick(rng, 7)) {
    case 0:  // delete
      if (parent.is_object())
        parent.erase(at.back());
      else if (parent.is_array())
        parent.erase(static_cast<size_t>(std::stoul(at.back())));
      break;
    case 1:
    case 2:  // replace by something hostile
      v = hostile_value(rng);
      break;
    case 3:  // scale a number by up to 30 decades either way, or negate it
      if (v.is_number())
        v = chance(rng, 0.3)
                ? -v.get<double>()
                : v.get<double>() * std::pow(10.0, static_cast<double>(pick(rng, 61)) - 30);
      else
        v = hostile_value(rng);
      break;
    case 4:  // rename a key (a typo) or add an unknown one
      if (parent.is_object()) {
        std::string key = at.back();
        json moved = v;
        parent.erase(key);
        key = key.size() > 1 ? key.substr(1) : key + "_";
        parent[key] = std::move(moved);
      } else {
        v = json::object({{"bogus", 1}});
      }
      break;
    case 5:  // duplicate an array element (a second body with the same name, a second patch)
      if (parent.is_array())
        parent.push_back(v);
      else
        v = json::array({v, v});
      break;
    default:  // change the type: a number as a string, a string as a number
      if (v.is_number())
        v = v.dump();
      else if (v.is_string())
        v = 1.0;
      else
        v = hostile_value(rng);
  }
}

/// A plausible change: a number scaled by 1/4 to 4 (half of them), or an optional key
/// deleted. Such scenes are mostly still valid, so that the harness reaches the deeper
/// checks (the t = 0 fluid mesh, overlaps, the first steps) and not only the parser.
void mild_mutation(json& root, Rng& rng) {
  std::vector<json::json_pointer> ptrs, numbers;
  collect_pointers(root, json::json_pointer(), ptrs);
  for (const auto& p : ptrs)
    if (root[p].is_number()) numbers.push_back(p);
  if (numbers.empty()) return;
  json& v = root[numbers[pick(rng, numbers.size())]];
  const double f = std::pow(2.0, std::uniform_real_distribution<double>(-2, 2)(rng));
  if (v.is_number_integer())
    v = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::llround(v.get<double>() * f)));
  else
    v = v.get<double>() * f;
}

/// The text of a mutated scene: plausible changes (half of the cases) or 1-3 hostile tree
/// mutations, and now and then damaged text.
std::string mutate_scene(const json& base, Rng& rng) {
  json j = base;
  if (chance(rng, 0.5)) {
    for (size_t i = 0, n = 1 + pick(rng, 3); i < n; ++i) mild_mutation(j, rng);
    return j.dump(2);
  }
  const size_t n = 1 + pick(rng, 3);
  for (size_t i = 0; i < n; ++i) mutate_tree(j, rng);
  std::string text = j.dump(2);
  if (chance(rng, 0.15) && !text.empty()) {
    const size_t at = pick(rng, text.size());
    switch (pick(rng, 3)) {
      case 0:
        text.resize(at);
        break;  // truncated
      case 1:
        text[at] = static_cast<char>(pick(rng, 256));
        break;  // a byte flipped
      default:
        text.insert(at, std::string(1, ",]}:\"\\"[pick(rng, 6)]));  // a stray token
    }
  }
  return text;
}

// ---- mesh-file mutations --------------------------------------------------------------------

const std::vector<std::string> k_hostile_numbers = {"0",
                                                    "-1",
                                                    "-5",
                                                    "1",
                                                    "2",
                                                    "4294967295",
                                                    "4294967296",
                                                    "18446744073709551615",
                                                    "2147483647",
                                                    "1e308",
                                                    "-1e308",
                                                    "nan",
                                                    "inf",
                                                    "1e12",
                                                    "3.5",
                                                    "x",
                                                    ""};

/// One mutation of a mesh file's bytes: a number replaced, a line deleted, duplicated or
/// swapped, the file truncated, bytes flipped or inserted.
std::string mutate_mesh_text(std::string text, Rng& rng) {
  if (text.empty()) return text;
  switch (pick(rng, 6)) {
    case 0: {  // a number (or an XML attribute's value) replaced
      static const std::regex number(R"([-+]?[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?)");
      std::vector<std::pair<size_t, size_t>> spans;
      // Only the first 200 kB: the headers and counts are near the start.
      const std::string head = text.substr(0, std::min<size_t>(text.size(), 200000));
      for (auto it = std::sregex_iterator(head.begin(), head.end(), number);
           it != std::sregex_iterator(); ++it)
        spans.emplace_back(static_cast<size_t>(it->position()), static_cast<size_t>(it->length()));
      if (spans.empty()) break;
      // Favour the first numbers (headers, counts, attributes).
      const size_t k = chance(rng, 0.6) ? pick(rng, std::min<size_t>(spans.size(), 12))
                                        : pick(rng, spans.size());
      text.replace(spans[k].first, spans[k].second,
                   k_hostile_numbers[pick(rng, k_hostile_numbers.size())]);
      break;
    }
    case 1:
    case 2: {  // a line deleted, duplicated or two lines swapped
      std::vector<size_t> starts = {0};
      for (size_t i = 0; i < text.size(); ++i)
        if (text[i] == '\n' && i + 1 < text.size()) starts.push_back(i + 1);
      auto line = [&](size_t k) {
        const size_t e = k + 1 < starts.size() ? starts[k + 1] : text.size();
        return std::make_pair(starts[k], e - starts[k]);
      };
      const auto [a0, an] = line(pick(rng, starts.size()));
      const auto [b0, bn] = line(pick(rng, starts.size()));
      const std::string la = text.substr(a0, an), lb = text.substr(b0, bn);
      const size_t what = pick(rng, 3);
      if (what == 0)
        text.erase(a0, an);
      else if (what == 1)
        text.insert(a0, la);
      else if (a0 < b0)
        text = text.substr(0, a0) + lb + text.substr(a0 + an, b0 - a0 - an) + la +
               text.substr(b0 + bn);
      break;
    }
    case 3:  // truncated
      text.resize(pick(rng, text.size()));
      break;
    case 4:  // bytes flipped
      for (size_t i = 0, n = 1 + pick(rng, 16); i < n; ++i)
        text[pick(rng, text.size())] = static_cast<char>(pick(rng, 256));
      break;
    default:  // garbage inserted
    {
      std::string junk(1 + pick(rng, 32), ' ');
      for (char& c : junk) c = static_cast<char>(pick(rng, 256));
      text.insert(pick(rng, text.size()), junk);
    }
  }
  return text;
}

// ---- the property every outcome must have ---------------------------------------------------

/// "" if `r` is a clean outcome of `what`; else what is wrong with it.
std::string judge(const CliResult& r) {
  if (r.code == 124 || r.code == 137) return "timed out (60 s) or was killed";
  if (r.code < 0) return "died from a signal";
  if (r.code != 0 && r.code != 1) return fmt::format("exit code {}", r.code);
  std::vector<std::string> errors;
  for (const std::string& l : r.err_lines())
    if (l.rfind("error:", 0) == 0) errors.push_back(l);
  if (r.code == 0) return errors.empty() ? "" : "exit 0 with an error line";
  if (errors.size() != 1) return fmt::format("{} error lines (one wanted)", errors.size());
  const std::string& e = errors[0];
  if (e.size() > 1500) return "an error line of more than 1500 characters";
  // Bare library messages name neither file nor key.
  static const std::regex bare(
      R"(^error: (std::|vector::|basic_string|stoi|stol|stoul|stod|map::at|bad_alloc|unknown internal|Assertion|CGAL ERROR|PETSC ERROR|\[json\.exception))");
  if (std::regex_search(e, bare)) return "a bare library message";
  if (e.find("check '") != std::string::npos) return "an internal check failed";
  return "";
}

struct FuzzStats {
  int cases = 0, accepted = 0, refused = 0, runs = 0, failures = 0;
};

fs::path failures_dir() {
  return fs::current_path() / "fuzz_failures";
}

/// Run one case and check its outcome; on failure keep the input (and its mesh files).
void check_case(const fs::path& dir, const std::string& args, const fs::path& input,
                const std::string& label, FuzzStats& st, bool& accepted) {
  const CliResult r = run_tetfsi(dir, args, k_limits);
  const std::string why = judge(r);
  accepted = r.code == 0;
  if (why.empty()) return;
  ++st.failures;
  fs::create_directories(failures_dir());
  std::string tag = label;
  for (char& c : tag)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  const fs::path keep = failures_dir() / fmt::format("{}_{}", tag, input.filename().string());
  std::error_code ec;
  fs::copy_file(input, keep, fs::copy_options::overwrite_existing, ec);
  const auto lines = r.err_lines();
  FAIL_CHECK(label, ": `tetfsi ", args, "`: ", why, " (input kept as ", keep.string(),
             ")\n  last stderr line: ", lines.empty() ? std::string() : lines.back());
}

struct SceneBase {
  fs::path file;
  json scene;
};

std::vector<SceneBase> scene_bases() {
  std::vector<SceneBase> b;
  for (const fs::path& p :
       {k_src / "data/scenes/toy.json", k_src / "data/scenes/sheet_sag.json",
        k_src / "tests/scenes/two_tets.json", k_src / "tests/scenes/axial_bar.json",
        k_src / "tests/scenes/soft_box_in_water.json",
        k_src / "tests/scenes/robustness/two_boxes_in_water.json",
        k_src / "tests/scenes/robustness/water_shell_in_water.json"}) {
    b.push_back({p, json::parse(read_text(p))});
  }
  return b;
}

/// `n` mutated scenes through validate; a two-step run of each one validate accepts (every
/// `run_every`-th): it must not fail at step 0, which validate has checked.
FuzzStats fuzz_scenes(const fs::path& dir, std::uint64_t seed, int n, int run_every) {
  Rng rng(seed);
  const std::vector<SceneBase> bases = scene_bases();
  fs::copy_file(k_src / "tests/scenes/two_tets.msh", dir / "two_tets.msh",
                fs::copy_options::overwrite_existing);
  FuzzStats st;
  for (int i = 0; i < n; ++i) {
    const SceneBase& base = bases[pick(rng, bases.size())];
    const fs::path file = dir / fmt::format("scene_{}_{}.json", seed, i);
    write_file(file, mutate_scene(base.scene, rng));
    ++st.cases;
    bool ok = false;
    const std::string label =
        fmt::format("scene {} (seed {}, from {})", i, seed, base.file.filename().string());
    check_case(dir, fmt::format("validate '{}' --log-level warn", file.string()), file, label, st,
               ok);
    (ok ? st.accepted : st.refused) += 1;
    if (ok && run_every > 0 && st.accepted % run_every == 0) {
      ++st.runs;
      const CliResult r =
          run_tetfsi(dir,
                     fmt::format("run '{}' --log-level warn --progress off --steps 2 --out run_out",
                                 file.string()),
                     k_limits);
      const std::string why = judge(r);
      const bool step0 = r.err.find("step 0 (t = 0 s) failed") != std::string::npos;
      if (!why.empty() || step0) {
        ++st.failures;
        fs::create_directories(failures_dir());
        fs::copy_file(file, failures_dir() / file.filename(), fs::copy_options::overwrite_existing);
        FAIL_CHECK(label,
                   ": validate said ok but `run --steps 2`: ", step0 ? "failed at step 0" : why,
                   "\n", r.err);
      }
      fs::remove_all(dir / "run_out");
    }
    fs::remove(file);
  }
  return st;
}

struct MeshBase {
  fs::path file;
  bool surface = false;  ///< meshed by CGAL (mesh.surface) rather than read (mesh.file)
};

/// The mesh bases: every reader's format, plus binary VTUs written by tetfsi itself.
std::vector<MeshBase> mesh_bases(const fs::path& dir) {
  std::vector<MeshBase> b = {{k_src / "data/meshes/bar_v2.msh"},
                             {k_src / "data/meshes/bar_v4.msh"},
                             {k_src / "data/meshes/bar.node"},
                             {k_src / "data/meshes/bar.ele"},
                             {k_src / "data/meshes/bar.vtu"},
                             {k_src / "data/meshes/cube.obj", true},
                             {k_src / "data/meshes/cube.stl", true},
                             {k_src / "data/meshes/cube_binary.stl", true},
                             {k_src / "data/meshes/icosphere.off", true}};
  for (const char* c : {"lz4", "zlib", "none"}) {
    const CliResult r = run_tetfsi(
        dir, fmt::format("run '{}' --steps 1 --progress off --log-level warn --out gen_{} "
                         "--set output.compression={}",
                         (k_src / "tests/scenes/two_tets.json").string(), c, c));
    REQUIRE(r.code == 0);
    b.push_back({dir / fmt::format("gen_{}", c) / "pair" / "pair_000001.vtu"});
  }
  return b;
}

/// `n` mutated mesh files, each through a scene that reads it (validate) and, for a .vtu,
/// through `tetfsi quality`.
FuzzStats fuzz_meshes(const fs::path& dir, std::uint64_t seed, int n) {
  Rng rng(seed);
  const std::vector<MeshBase> bases = mesh_bases(dir);
  FuzzStats st;
  for (int i = 0; i < n; ++i) {
    const MeshBase& base = bases[pick(rng, bases.size())];
    std::string ext = base.file.extension().string();
    const std::string stem = fmt::format("mesh_{}_{}", seed, i);
    const fs::path file = dir / (stem + ext);
    write_file(file, mutate_mesh_text(read_text(base.file), rng));
    // TetGen comes in pairs: the other file of the pair unchanged.
    std::string mesh_name = file.filename().string();
    if (ext == ".node" || ext == ".ele") {
      const std::string other = ext == ".node" ? ".ele" : ".node";
      fs::copy_file(base.file.parent_path() / (base.file.stem().string() + other),
                    dir / (stem + other), fs::copy_options::overwrite_existing);
      mesh_name = stem + ".node";
    }
    json scene = {{"time", {{"dt", 0.01}, {"steps", 1}}},
                  {"bodies", json::array({{{"name", "b"}, {"mesh", json::object()}}})}};
    if (base.surface)
      scene["bodies"][0]["mesh"] = {{"surface", mesh_name}, {"cell_size", 0.3}};
    else
      scene["bodies"][0]["mesh"] = {{"file", mesh_name}};
    const fs::path scene_file = dir / (stem + ".json");
    write_file(scene_file, scene.dump(2));
    const std::string label =
        fmt::format("mesh {} (seed {}, from {})", i, seed, base.file.filename().string());
    ++st.cases;
    bool ok = false;
    check_case(dir, fmt::format("validate '{}' --log-level warn", scene_file.string()), file, label,
               st, ok);
    (ok ? st.accepted : st.refused) += 1;
    if (ext == ".vtu")
      check_case(dir, fmt::format("quality '{}' --log-level warn", file.string()), file, label, st,
                 ok);
    for (const char* e : {".json", ".node", ".ele"}) fs::remove(dir / (stem + e));
    fs::remove(file);
  }
  return st;
}

/// The seed and counts, with the environment's overrides.
void configure(std::uint64_t& seed, int& scenes, int& meshes) {
  if (const char* s = std::getenv("TETFSI_FUZZ_SEED")) seed = std::strtoull(s, nullptr, 10);
  if (const char* c = std::getenv("TETFSI_FUZZ_CASES")) {
    const std::string v = c;
    const size_t comma = v.find(',');
    scenes = std::atoi(v.substr(0, comma).c_str());
    if (comma != std::string::npos) meshes = std::atoi(v.substr(comma + 1).c_str());
  }
}

void report(const char* what, std::uint64_t seed, const FuzzStats& s) {
  MESSAGE(
      fmt::format("fuzz {} (seed {}): {} cases, {} accepted, {} refused with one line, {} "
                  "two-step runs, {} failures",
                  what, seed, s.cases, s.accepted, s.refused, s.runs, s.failures));
}

void fuzz(const char* name, std::uint64_t seed, int scenes, int meshes, int run_every) {
  configure(seed, scenes, meshes);
  TempDir dir(name);
  const FuzzStats s = fuzz_scenes(dir.path, seed, scenes, run_every);
  report("scenes", seed, s);
  const FuzzStats m = fuzz_meshes(dir.path, seed + 1, meshes);
  report("meshes", seed + 1, m);
  CHECK(s.failures == 0);
  CHECK(m.failures == 0);
  // The mutations reach both outcomes: a fuzzer whose inputs all fail to parse tests little.
  CHECK(s.accepted > 0);
  CHECK(s.refused > 0);
  CHECK(m.refused > 0);
}

}  // namespace

TEST_CASE("fuzz: a short seeded sample of mutated scenes and mesh files, one-line errors only") {
  fuzz("fuzz_short", 20261203, 40, 40, 4);
}

TEST_CASE("fuzz: 2500 mutated scenes and 1000 mutated mesh files" * doctest::test_suite("long")) {
  fuzz("fuzz_long", 1, 2500, 1000, 10);
}
