/// @file test_stats_columns.cpp
/// stats.csv's columns are declared once (io/stats_columns.hpp): the header, the rows, the
/// checkpoint's records and the manual's reference (docs/user/output.md) all come from the
/// tables, and a test fails when the manual and the tables differ.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "io/stats_columns.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;

namespace {

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The text between "<!-- stats:begin -->\n" and "<!-- stats:end -->" of `text`.
std::string stats_block(const std::string& text) {
  const std::string begin = "<!-- stats:begin -->\n", end = "<!-- stats:end -->";
  const auto a = text.find(begin);
  const auto b = text.find(end);
  REQUIRE_MESSAGE(a != std::string::npos, "docs/user/output.md has no <!-- stats:begin -->");
  REQUIRE_MESSAGE(b != std::string::npos, "docs/user/output.md has no <!-- stats:end -->");
  REQUIRE(b > a);
  return text.substr(a + begin.size(), b - a - begin.size());
}

template <class R>
std::vector<std::string> records(const std::vector<StatsColumn<R>>& table) {
  std::vector<std::string> names;
  R r{};
  visit_records(table, r, [&](const char* name, auto&) { names.emplace_back(name); });
  return names;
}

}  // namespace

TEST_CASE("docs/user/output.md's stats.csv columns are the generated ones") {
  const fs::path doc = fs::path(TETFSI_SOURCE_DIR) / "docs" / "user" / "output.md";
  const std::string block = stats_block(read_text(doc));
  CHECK_MESSAGE(block == stats_columns_markdown(),
                "docs/user/output.md's stats.csv columns differ from io/stats_columns.cpp; "
                "replace the block between its stats markers with `build/cli/tetfsi columns`:\n"
                    << stats_columns_markdown());
}

TEST_CASE("every stats.csv column is named once and documented") {
  const std::vector<std::string> cols = StatsWriter::columns(true, true, {"b"}, true, true);
  const std::set<std::string> unique(cols.begin(), cols.end());
  CHECK(unique.size() == cols.size());
  const std::string doc = stats_columns_markdown();
  for (std::string c : cols) {
    if (c.rfind("b_", 0) == 0) c = "<b>" + c.substr(1);  // the per-body columns' pattern
    CHECK_MESSAGE(doc.find("`" + c + "`") != std::string::npos, c << " is not documented");
  }
  // One-way and two-way runs time different phases; each is documented.
  for (const auto& p : StatsWriter::phase_columns(true, false))
    CHECK(doc.find("`" + p + "`") != std::string::npos);
}

TEST_CASE("the checkpoint keeps the last step's figures under their records' names") {
  // Checkpoints written before the tables existed hold these records: they must still load.
  CHECK(records(fluid_mesh_columns()) ==
        std::vector<std::string>{"cells", "vertices", "steiner_points", "recovery_rounds",
                                 "remesh_incremental", "vertices_removed", "vertices_inserted",
                                 "remesh_s"});
  CHECK(records(fluid_step_columns()) ==
        std::vector<std::string>{"pressure_iterations", "pressure_residual", "divergence_before",
                                 "divergence", "fluid_kinetic_energy", "smoke_mass", "inflow_flux",
                                 "outflow_flux", "solid_flux", "max_speed", "cfl",
                                 "traces_clamped"});
  CHECK(records(coupled_columns()) ==
        std::vector<std::string>{"iterations", "residual", "interface_power", "total_energy",
                                 "enclosed_volume", "enclosed_volume_drift"});
}

TEST_CASE("a row prints each column in its form, a missing record as nan") {
  CoupledStepStats c;
  c.iterations = 7;
  c.residual = 1.0 / 3.0;
  c.interface_power = 1.0 / 3.0;
  std::string line;
  append_stats(line, coupled_columns(), c);
  // Integer, 6 digits (residual), 17 digits (power), ...
  CHECK(line.rfind(",7,0.333333,0.33333333333333331,", 0) == 0);
  std::string nan;
  append_nan(nan, coupled_columns());
  CHECK(nan == std::string(",nan").append(",nan,nan,nan,nan,nan,nan"));
}
