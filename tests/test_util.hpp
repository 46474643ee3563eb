#pragma once
/// @file test_util.hpp
/// Helpers shared by the doctest executables: the message of an expected exception, temporary
/// folders, reading files, and (in executables that define TETFSI_EXE) running the CLI.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
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

/// What a CLI run left: exit code (−1 if it did not exit normally), stdout, stderr.
struct CliResult {
  int code = -1;
  std::string out;
  std::string err;
  std::vector<std::string> err_lines() const { return lines_of(err); }
};

#ifdef TETFSI_EXE
/// Run `tetfsi <args>` in folder `cwd`, capturing stdout and stderr. `limits` is a shell
/// prefix (e.g. "ulimit -v 4000000;") for runs that must not take the machine down.
inline CliResult run_tetfsi(const std::filesystem::path& cwd, const std::string& args,
                            const std::string& limits = "") {
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

}  // namespace tetfsi::test
