#pragma once
/// @file run_compare.hpp
/// Two output folders of `tetfsi run` compared bit for bit: the restart tests
/// (test_restart.cpp) and the thread-count tests (test_threads.cpp) rest on it.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "tests/test_util.hpp"

namespace tetfsi::test {

/// stats.csv's seconds columns (they differ between any two runs); so does every column whose
/// name ends in "_s" (is_timing_column), as scripts/compare_runs.py tells them.
inline const std::set<std::string> k_timing = {"assemble",
                                               "solve",
                                               "update",
                                               "output",
                                               "total",
                                               "remesh",
                                               "transfer",
                                               "forces",
                                               "pressure_assembly",
                                               "pressure_solve",
                                               "coupled_assembly",
                                               "coupled_solve",
                                               "solid",
                                               "remesh_s"};

inline bool is_timing_column(const std::string& name) {
  return k_timing.count(name) > 0 ||
         (name.size() > 2 && name.compare(name.size() - 2, 2, "_s") == 0);
}

inline std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> f;
  std::string cur;
  for (const char c : line) {
    if (c == ',') {
      f.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  f.push_back(cur);
  return f;
}

/// The columns that say how the remesh built its mesh (incremental update or full rebuild),
/// not what it built: a resumed run's first remesh is always a full rebuild (the
/// triangulation is not in the checkpoint), the same mesh bit for bit.
inline const std::set<std::string> k_remesh_path = {"remesh_incremental", "vertices_removed",
                                                    "vertices_inserted"};

/// Every difference between two output folders: stats.csv's non-timing fields as text (17
/// digits: equal text is equal bits), the collections and every frame file byte for byte.
/// `remesh_path` false skips k_remesh_path's columns (a resumed run against a straight one).
inline std::vector<std::string> differences(const std::filesystem::path& a,
                                            const std::filesystem::path& b,
                                            bool remesh_path = true) {
  std::vector<std::string> d;
  const auto la = lines_of(read_text(a / "stats.csv")), lb = lines_of(read_text(b / "stats.csv"));
  if (la.size() != lb.size())
    d.push_back(fmt::format("stats.csv: {} vs {} lines", la.size(), lb.size()));
  if (la.empty() || lb.empty()) return d;
  const auto header = split_csv_line(la[0]);
  if (la[0] != lb[0]) d.push_back("stats.csv: headers differ");
  for (size_t i = 1; i < std::min(la.size(), lb.size()); ++i) {
    const auto fa = split_csv_line(la[i]), fb = split_csv_line(lb[i]);
    for (size_t k = 0; k < header.size() && k < fa.size() && k < fb.size(); ++k)
      if (!is_timing_column(header[k]) && (remesh_path || !k_remesh_path.count(header[k])) &&
          fa[k] != fb[k])
        d.push_back(fmt::format("stats.csv row {} {}: {} vs {}", i, header[k], fa[k], fb[k]));
  }
  std::set<std::string> files;
  for (const std::filesystem::path& root : {a, b})
    for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
      const std::string ext = e.path().extension().string();
      // The renderer export's PLY meshes and manifest too (a .vdb holds a random file id;
      // export.json holds its grids' summaries: names, active voxels, ranges, bounds).
      if (ext == ".vtu" || ext == ".vtp" || ext == ".vti" || ext == ".pvd" || ext == ".ply" ||
          e.path().filename() == "export.json")
        files.insert(std::filesystem::relative(e.path(), root).string());
    }
  for (const std::string& f : files) {
    if (!std::filesystem::exists(a / f) || !std::filesystem::exists(b / f))
      d.push_back(fmt::format("{}: only in {}", f, std::filesystem::exists(a / f) ? "A" : "B"));
    else if (read_text(a / f) != read_text(b / f))
      d.push_back(fmt::format("{}: differs", f));
  }
  return d;
}

/// Check that two output folders hold the same run (differences()), naming the first few
/// differences if not.
inline void check_same_runs(const std::filesystem::path& a, const std::filesystem::path& b,
                            bool remesh_path = true) {
  const std::vector<std::string> diffs = differences(a, b, remesh_path);
  std::string first;
  for (size_t i = 0; i < std::min<size_t>(diffs.size(), 5); ++i) first += diffs[i] + "; ";
  CHECK_MESSAGE(diffs.empty(), first);
}

}  // namespace tetfsi::test
