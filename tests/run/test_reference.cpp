/// @file test_reference.cpp
/// Stored reference figures (tests/reference/, described in its README.md): short runs of
/// small scenes through the run loop of `tetfsi run` (in-process), one per coupling scheme plus a
/// fluid-only and a solid-only scene, whose non-timing stats.csv columns are compared with the
/// stored ones, column by column and step by step, within the tolerances of
/// tests/reference/manifest.json. A change meant to alter results regenerates the stored
/// files with scripts/update_reference.sh (TETFSI_UPDATE_REFERENCE=1 here: the cases then
/// write the CSVs instead of comparing).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/output.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using tetfsi::test::lines_of;
using tetfsi::test::read_text;
using tetfsi::test::TempDir;

namespace {

const fs::path kRefDir = fs::path(TETFSI_SOURCE_DIR) / "tests" / "reference";

/// The cases of this file, one TEST_CASE each; the manifest must name exactly these.
const std::vector<std::string> kCases = {"simultaneous", "splitting", "bfgs",     "modified_newton",
                                         "newton",       "smoke_jet", "sheet_sag"};

/// A CSV file as text: the header's names and the rows' fields (no quoting: stats.csv).
struct Table {
  std::vector<std::string> names;
  std::vector<std::vector<std::string>> rows;
};

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ss(line);
  for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

/// Parse CSV text; REQUIREs a header and the header's field count in every row.
Table parse_table(const std::string& text, const std::string& what) {
  INFO(what);
  const std::vector<std::string> lines = lines_of(text);
  REQUIRE(!lines.empty());
  Table t;
  t.names = split_csv(lines[0]);
  for (size_t i = 1; i < lines.size(); ++i) {
    t.rows.push_back(split_csv(lines[i]));
    INFO("row " << i);
    REQUIRE(t.rows.back().size() == t.names.size());
  }
  return t;
}

std::string table_text(const Table& t) {
  std::string s;
  const auto line = [&](const std::vector<std::string>& f) {
    for (size_t k = 0; k < f.size(); ++k) s += (k ? "," : "") + f[k];
    s += '\n';
  };
  line(t.names);
  for (const auto& r : t.rows) line(r);
  return s;
}

/// A wall-clock column of stats.csv: a phase (StatsWriter::phase_columns of any run kind) or
/// a name ending in "_s" (remesh_s), as scripts/compare_runs.py tells them.
bool is_timing(const std::string& name) {
  for (bool fluid : {false, true})
    for (bool coupled : {false, true}) {
      const auto& p = tetfsi::app::StatsWriter::phase_columns(fluid, coupled);
      if (std::find(p.begin(), p.end(), name) != p.end()) return true;
    }
  return name.size() > 2 && name.compare(name.size() - 2, 2, "_s") == 0;
}

/// The table without its timing columns (the fields kept verbatim).
Table without_timings(const Table& t) {
  Table r;
  std::vector<size_t> keep;
  for (size_t k = 0; k < t.names.size(); ++k)
    if (!is_timing(t.names[k])) keep.push_back(k);
  for (size_t k : keep) r.names.push_back(t.names[k]);
  for (const auto& row : t.rows) {
    r.rows.emplace_back();
    for (size_t k : keep) r.rows.back().push_back(row[k]);
  }
  return r;
}

/// |new − stored| ≤ atol + rtol · max(|stored|, |new|) passes (and equal text, two NaNs).
struct Tolerance {
  double rtol = 0.0;
  double atol = 0.0;
};

/// The tolerance of `column`: the manifest's "tolerance" (the default), then its
/// "columns" entry for that name, then the case's own "columns" entry (each may give rtol,
/// atol or both).
Tolerance tolerance_of(const nlohmann::json& manifest, const nlohmann::json& c,
                       const std::string& column) {
  Tolerance t;
  const auto apply = [&](const nlohmann::json& j) {
    t.rtol = j.value("rtol", t.rtol);
    t.atol = j.value("atol", t.atol);
  };
  apply(manifest.at("tolerance"));
  for (const nlohmann::json* scope : {&manifest, &c})
    if (scope->contains("columns") && scope->at("columns").contains(column))
      apply(scope->at("columns").at(column));
  return t;
}

bool parse_number(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

bool within(const std::string& stored, const std::string& fresh, const Tolerance& tol) {
  if (stored == fresh) return true;
  double a = 0.0, b = 0.0;
  if (!parse_number(stored, a) || !parse_number(fresh, b)) return false;
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::abs(a - b) <= tol.atol + tol.rtol * std::max(std::abs(a), std::abs(b));
}

/// Every difference of `fresh` from `stored` beyond tolerance, one line each naming the
/// case, the column, the step (the row's "step" field), the stored and the new value; also
/// a different row count and a column only one of them has (regenerate when intended).
std::vector<std::string> compare_tables(
    const std::string& name, const Table& stored, const Table& fresh,
    const std::function<Tolerance(const std::string&)>& tolerance) {
  std::vector<std::string> diffs;
  const std::string fix = "(if intended: scripts/update_reference.sh)";
  for (const auto& n : stored.names)
    if (std::find(fresh.names.begin(), fresh.names.end(), n) == fresh.names.end())
      diffs.push_back(fmt::format(
          "reference {}: column {} is stored but not in the new stats.csv {}", name, n, fix));
  for (const auto& n : fresh.names)
    if (std::find(stored.names.begin(), stored.names.end(), n) == stored.names.end())
      diffs.push_back(fmt::format("reference {}: column {} is new (not stored) {}", name, n, fix));
  if (stored.rows.size() != fresh.rows.size())
    diffs.push_back(fmt::format("reference {}: {} rows stored, {} new {}", name, stored.rows.size(),
                                fresh.rows.size(), fix));
  const size_t step_col = static_cast<size_t>(
      std::find(stored.names.begin(), stored.names.end(), "step") - stored.names.begin());
  for (size_t k = 0; k < stored.names.size(); ++k) {
    const auto it = std::find(fresh.names.begin(), fresh.names.end(), stored.names[k]);
    if (it == fresh.names.end()) continue;
    const size_t j = static_cast<size_t>(it - fresh.names.begin());
    const Tolerance tol = tolerance(stored.names[k]);
    for (size_t i = 0; i < std::min(stored.rows.size(), fresh.rows.size()); ++i) {
      const std::string &a = stored.rows[i][k], &b = fresh.rows[i][j];
      if (within(a, b, tol)) continue;
      const std::string step =
          step_col < stored.names.size() ? stored.rows[i][step_col] : std::to_string(i + 1);
      diffs.push_back(
          fmt::format("reference {}: column {}, step {}: stored {}, new {} (rtol {:g}, atol {:g})",
                      name, stored.names[k], step, a, b, tol.rtol, tol.atol));
    }
  }
  return diffs;
}

nlohmann::json load_manifest() {
  const fs::path p = kRefDir / "manifest.json";
  const std::string text = read_text(p);
  INFO("manifest " << p);
  REQUIRE(!text.empty());
  nlohmann::json m;
  REQUIRE_NOTHROW(m = nlohmann::json::parse(text));  // doctest prints the parser's message
  return m;
}

const nlohmann::json& case_of(const nlohmann::json& manifest, const std::string& name) {
  const nlohmann::json& cases = manifest.at("cases");
  const auto it = std::find_if(cases.begin(), cases.end(),
                               [&](const nlohmann::json& c) { return c.at("name") == name; });
  INFO("tests/reference/manifest.json: case '" << name << "'");
  REQUIRE(it != cases.end());
  return *it;
}

/// The case's run, in-process as `tetfsi run SCENE --steps N --set ...` does it (as
/// test_coupled_run.cpp; a process per case would add ~1 s of library loading each): its
/// stats.csv, written in `dir`.
Table run_case(const nlohmann::json& c, const fs::path& dir) {
  const fs::path scene = fs::path(TETFSI_SOURCE_DIR) / c.at("scene").get<std::string>();
  std::vector<std::string> sets;
  for (const auto& s : c.value("set", nlohmann::json::array()))
    sets.push_back(s.get<std::string>());
  tetfsi::app::RunOptions opt;
  opt.out_dir = dir / "o";
  opt.progress = tetfsi::app::ProgressMode::Off;
  opt.steps = c.at("steps").get<int>();
  const tetfsi::app::RunResult r =
      tetfsi::app::run_scene(tetfsi::app::load_scene(scene, sets), opt);
  INFO("scene " << scene.string() << ", run error: " << r.error);
  REQUIRE(r.completed);
  return parse_table(read_text(opt.out_dir / "stats.csv"),
                     "stats.csv of case " + c.at("name").get<std::string>());
}

/// Run the case and compare with its stored CSV, or (TETFSI_UPDATE_REFERENCE=1) store it.
void check_case(const std::string& name) {
  const nlohmann::json manifest = load_manifest();
  const nlohmann::json& c = case_of(manifest, name);
  TempDir dir("reference_" + name);
  const Table fresh = without_timings(run_case(c, dir.path));
  REQUIRE(fresh.rows.size() == c.at("steps").get<size_t>());
  const fs::path stored_path = kRefDir / (name + ".csv");
  const char* update = std::getenv("TETFSI_UPDATE_REFERENCE");
  if (update && std::string(update) == "1") {
    std::ofstream out(stored_path, std::ios::binary);
    out << table_text(fresh);
    INFO("cannot write " << stored_path.string());
    REQUIRE(out.flush());
    MESSAGE("wrote " << stored_path.string());
    return;
  }
  const std::string text = read_text(stored_path);
  INFO("stored figures " << stored_path.string() << " (make them: scripts/update_reference.sh)");
  REQUIRE(!text.empty());
  const auto diffs =
      compare_tables(name, parse_table(text, stored_path.string()), fresh,
                     [&](const std::string& col) { return tolerance_of(manifest, c, col); });
  for (const auto& d : diffs) FAIL_CHECK(d);  // one line each
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("reference: simultaneous") {
    check_case("simultaneous");
  }
  TEST_CASE("reference: splitting") {
    check_case("splitting");
  }
  TEST_CASE("reference: bfgs") {
    check_case("bfgs");
  }
  TEST_CASE("reference: modified_newton") {
    check_case("modified_newton");
  }
  TEST_CASE("reference: newton") {
    check_case("newton");
  }
  TEST_CASE("reference: smoke_jet") {
    check_case("smoke_jet");
  }
  TEST_CASE("reference: sheet_sag") {
    check_case("sheet_sag");
  }

  TEST_CASE("reference manifest: names the cases above with tolerances and stored CSVs") {
    const nlohmann::json m = load_manifest();
    REQUIRE(m.contains("tolerance"));
    // every tolerance entry: rtol / atol >= 0 (and a "why"), nothing misspelt
    const auto check_entry = [](const std::string& where, const nlohmann::json& e) {
      INFO(where);
      REQUIRE(e.is_object());
      for (const auto& [key, value] : e.items()) {
        CAPTURE(key);
        CHECK((key == "rtol" || key == "atol" || key == "why"));
        if (key != "why") CHECK((value.is_number() && value.get<double>() >= 0.0));
      }
    };
    check_entry("tolerance", m.at("tolerance"));
    const nlohmann::json columns = m.value("columns", nlohmann::json::object());
    for (const auto& [col, e] : columns.items()) check_entry("columns." + col, e);
    std::set<std::string> names;
    for (const auto& c : m.at("cases")) {
      const std::string n = c.at("name");
      INFO("case " << n);
      CHECK(names.insert(n).second);
      CHECK(fs::exists(fs::path(TETFSI_SOURCE_DIR) / c.at("scene").get<std::string>()));
      CHECK(c.at("steps").get<int>() >= 1);
      const nlohmann::json case_columns = c.value("columns", nlohmann::json::object());
      for (const auto& [col, e] : case_columns.items())
        if (col != "why") check_entry(n + ".columns." + col, e);
      CHECK(fs::exists(kRefDir / (n + ".csv")));
    }
    CHECK(names == std::set<std::string>(kCases.begin(), kCases.end()));
    // no stored CSV without a case
    for (const auto& e : fs::directory_iterator(kRefDir))
      if (e.path().extension() == ".csv") CHECK(names.count(e.path().stem().string()) == 1);
  }

  TEST_CASE("reference comparator: a perturbed value fails naming case/column/step/values") {
    const nlohmann::json m = load_manifest();
    const nlohmann::json& c = case_of(m, "simultaneous");
    const Table stored = parse_table(read_text(kRefDir / "simultaneous.csv"), "simultaneous.csv");
    const auto tol = [&](const std::string& col) { return tolerance_of(m, c, col); };
    REQUIRE(stored.rows.size() >= 2);
    CHECK(compare_tables("simultaneous", stored, stored, tol).empty());

    // kinetic_energy of the second row, moved by 10 rtol: one difference, fully named
    const auto col = std::find(stored.names.begin(), stored.names.end(), "kinetic_energy");
    REQUIRE(col != stored.names.end());
    const size_t k = static_cast<size_t>(col - stored.names.begin());
    Table moved = stored;
    const double v = std::stod(stored.rows[1][k]), rtol = tol("kinetic_energy").rtol;
    REQUIRE(v != 0.0);
    REQUIRE(rtol > 0.0);
    moved.rows[1][k] = fmt::format("{:.17g}", v * (1 + 10 * rtol));
    auto diffs = compare_tables("simultaneous", stored, moved, tol);
    REQUIRE(diffs.size() == 1);
    const std::string step = stored.rows[1][0];
    CHECK(diffs[0] == fmt::format("reference simultaneous: column kinetic_energy, step {}: stored "
                                  "{}, new {} (rtol {:g}, atol 0)",
                                  step, stored.rows[1][k], moved.rows[1][k], rtol));
    // within tolerance (a tenth of rtol): no difference
    moved.rows[1][k] = fmt::format("{:.17g}", v * (1 + 0.1 * rtol));
    CHECK(compare_tables("simultaneous", stored, moved, tol).empty());
    // a NaN where a number was, a missing row, a dropped and an added column
    moved = stored;
    moved.rows[0][k] = "nan";
    CHECK(compare_tables("simultaneous", stored, moved, tol).size() == 1);
    moved = stored;
    moved.rows.pop_back();
    diffs = compare_tables("simultaneous", stored, moved, tol);
    REQUIRE(diffs.size() == 1);
    CHECK(diffs[0].find(fmt::format("{} rows stored, {} new", stored.rows.size(),
                                    stored.rows.size() - 1)) != std::string::npos);
    moved = stored;
    moved.names[k] = "kinetic_energy_renamed";
    diffs = compare_tables("simultaneous", stored, moved, tol);
    REQUIRE(diffs.size() == 2);
    CHECK(diffs[0].find("column kinetic_energy is stored but not in the new") != std::string::npos);
    CHECK(diffs[1].find("column kinetic_energy_renamed is new") != std::string::npos);

    // the stored figures: timing columns left out, the rest kept verbatim
    CHECK(is_timing("total"));
    CHECK(is_timing("coupled_solve"));
    CHECK(is_timing("pressure_solve"));
    CHECK(is_timing("remesh_s"));
    CHECK_FALSE(is_timing("kinetic_energy"));
    CHECK_FALSE(is_timing("q_slivers"));
    const Table t = parse_table("step,total,kinetic_energy,remesh_s\n1,0.25,1.5e-3,0.1\n", "t");
    const Table r = without_timings(t);
    CHECK(r.names == std::vector<std::string>{"step", "kinetic_energy"});
    CHECK(r.rows == std::vector<std::vector<std::string>>{{"1", "1.5e-3"}});
    CHECK(table_text(r) == "step,kinetic_energy\n1,1.5e-3\n");
  }
}
