#pragma once
/// @file test_util.hpp
/// Helpers shared by the doctest executables: the message of an expected exception, temporary
/// folders, reading files, and (in executables that define TETFSI_EXE) running the CLI.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace tetfsi::test {

/// Message of the exception of type E that `f` throws ("" if it throws none).
template <class E, class F>
std::string message_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

/// A fresh folder `<tmp>/tetfsi_test_<name>_<pid>`, removed with everything in it on
/// destruction.
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& name) {
    path =
        std::filesystem::temp_directory_path() / fmt::format("tetfsi_test_{}_{}", name, getpid());
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

/// The whole file as text ("" if it cannot be read).
inline std::string read_text(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) lines.push_back(l);
  return lines;
}

/// A CSV file with a header line (stats.csv) as columns: name → one value per row.
/// @throws std::runtime_error naming the row if its field count differs from the header's.
inline std::map<std::string, std::vector<double>> read_csv_columns(const std::filesystem::path& p) {
  const std::vector<std::string> lines = lines_of(read_text(p));
  auto split = [](const std::string& line) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    return f;
  };
  std::map<std::string, std::vector<double>> cols;
  if (lines.empty()) return cols;
  const std::vector<std::string> names = split(lines[0]);
  for (const std::string& n : names) cols[n];
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> f = split(lines[i]);
    if (f.size() != names.size())
      throw std::runtime_error(fmt::format("{}: row {} has {} fields, the header {}", p.string(), i,
                                           f.size(), names.size()));
    for (size_t k = 0; k < f.size(); ++k) cols[names[k]].push_back(std::stod(f[k]));
  }
  return cols;
}

/// Whether a JSON value (nlohmann::json, or any type with is_number and get<double>) is a
/// positive finite number.
template <class Json>
bool positive_finite(const Json& v) {
  return v.is_number() && std::isfinite(v.template get<double>()) && v.template get<double>() > 0;
}

/// Whether `s` contains `part`.
inline bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

/// What a CLI run left: exit code (−1 if it did not exit normally), stdout, stderr.
struct CliResult {
  int code = -1;
  std::string out;
  std::string err;
  std::vector<std::string> err_lines() const { return lines_of(err); }
};

#ifdef TETFSI_SOURCE_DIR
/// A scene shipped with tetfsi: data/scenes/<name> (name with its ".json").
inline std::filesystem::path shipped_scene(const std::string& name) {
  return std::filesystem::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / name;
}
#endif

#ifdef TETFSI_EXE
/// Run `tetfsi <args>` in folder `cwd`, capturing stdout and stderr. `limits` is a shell
/// prefix (e.g. "ulimit -v 4000000;") for runs that must not take the machine down.
inline CliResult run_tetfsi(const std::filesystem::path& cwd, const std::string& args,
                            std::string limits = "") {
#ifdef TETFSI_SANITIZED
  // ASan reserves terabytes of address space for its shadow: no `ulimit -v` under it.
  if (limits.rfind("ulimit -v", 0) == 0) limits = limits.substr(limits.find(';') + 1);
#endif
  const std::filesystem::path out = cwd / "cli_stdout.txt", err = cwd / "cli_stderr.txt";
  const std::string cmd = fmt::format("cd '{}' && {} '{}' {} >'{}' 2>'{}'", cwd.string(), limits,
                                      TETFSI_EXE, args, out.string(), err.string());
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}
#endif

#if defined(DOCTEST_LIBRARY_INCLUDED) && defined(TETFSI_EXE) && defined(TETFSI_SOURCE_DIR)
/// `tetfsi run <the shipped scene> --out o --progress off <extra>` in `dir` under `limits`;
/// REQUIREs exit code 0 (stderr shown if not).
inline CliResult run_shipped_scene(const std::filesystem::path& dir, const std::string& scene,
                                   const std::string& extra, const std::string& limits) {
  const CliResult r = run_tetfsi(
      dir, fmt::format("run '{}' --out o --progress off {}", shipped_scene(scene).string(), extra),
      limits);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  return r;
}
#endif

#ifdef DOCTEST_LIBRARY_INCLUDED
/// Checks that a CLI run failed (exit code 1) with one line `error: ...` that holds every part.
inline void check_one_line_error(const CliResult& r, const std::vector<std::string>& parts) {
  INFO("stdout: " << r.out << "\nstderr: " << r.err);
  CHECK(r.code == 1);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(r.err_lines()[0].rfind("error: ", 0) == 0);
  for (const std::string& p : parts) CHECK(contains(r.err, p));
}
#endif

}  // namespace tetfsi::test
