/// @file plot.cpp
/// `tetfsi plot`: runs scripts/plot_stats.py on a run's stats.csv (plot.hpp).
#include "render/plot.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/output.hpp"
#include "render/headless_display.hpp"

#ifndef TETFSI_SOURCE_DIR
#define TETFSI_SOURCE_DIR "."
#endif

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// The scene's name from scene.resolved.json ("" if unreadable).
std::string scene_name(const fs::path& out_dir) {
  try {
    std::ifstream f(out_dir / "scene.resolved.json");
    if (!f) return "";
    return nlohmann::json::parse(f).value("name", "");
  } catch (const std::exception&) {
    return "";
  }
}

/// Run `args` (args[0] a path) with stdout captured into `out_text` and stderr into
/// `err_text`; returns the exit code (−1 if it did not exit normally).
int run_captured(std::vector<std::string> args, std::string& out_text, std::string& err_text) {
  char out_name[] = "/tmp/tetfsi_plot_out_XXXXXX", err_name[] = "/tmp/tetfsi_plot_err_XXXXXX";
  const int out_fd = mkstemp(out_name), err_fd = mkstemp(err_name);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    if (out_fd >= 0) dup2(out_fd, 1);
    if (err_fd >= 0) dup2(err_fd, 2);
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  const bool waited = pid > 0 && waitpid(pid, &status, 0) == pid;
  auto slurp = [](const char* name) {
    std::ifstream f(name);
    return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  };
  out_text = slurp(out_name);
  err_text = slurp(err_name);
  if (out_fd >= 0) close(out_fd);
  if (err_fd >= 0) close(err_fd);
  unlink(out_name);
  unlink(err_name);
  return waited && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

fs::path plot_script_path() {
  if (const char* env = std::getenv("TETFSI_PLOT_SCRIPT"); env && *env) return env;
  return fs::path(TETFSI_SOURCE_DIR) / "scripts" / "plot_stats.py";
}

int plot_command(const fs::path& out_dir, fs::path png, std::ostream& out) {
  std::error_code ec;
  if (!fs::is_directory(out_dir, ec))
    throw InputError(fmt::format(
        "no such output folder '{}': give the folder a run wrote (`tetfsi run SCENE --out {}`)",
        out_dir.string(), out_dir.string()));
  const fs::path stats = out_dir / "stats.csv";
  if (!fs::exists(stats, ec))
    throw InputError(
        fmt::format("{}: missing; '{}' holds no run (give the folder `tetfsi run "
                    "SCENE --out OUT` wrote)",
                    stats.string(), out_dir.string()));
  if (png.empty()) png = out_dir / "stats.png";
  // Debian's python (its matplotlib); another python3 on the PATH may not have it.
  std::string python = access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "";
  if (python.empty()) python = find_program("python3");
  if (python.empty())
    throw InputError(
        "tetfsi plot needs python3 with matplotlib: run scripts/setup.sh (Debian packages "
        "python3-matplotlib, python3-numpy)");
  const fs::path script = plot_script_path();
  if (!fs::exists(script, ec))
    throw InputError(
        fmt::format("the plotting script '{}' is missing (tetfsi looks for it in "
                    "the source tree it was built from; set TETFSI_PLOT_SCRIPT to "
                    "its path)",
                    script.string()));
  std::string text, err;
  const int code = run_captured(
      {python, script.string(), stats.string(), "-o", png.string(), "--title", scene_name(out_dir)},
      text, err);
  if (code != 0) {
    // The script's own `error: ...` line, else the last line it printed.
    std::string line, last, error;
    std::istringstream lines(err);
    while (std::getline(lines, line)) {
      if (line.rfind("error: ", 0) == 0) error = line.substr(7);
      if (!line.empty()) last = line;
    }
    throw InputError(one_line(!error.empty() ? error
                                             : fmt::format("{} {} failed (exit code {}): {}",
                                                           python, script.string(), code,
                                                           last.empty() ? "no message" : last)));
  }
  out << text;
  out.flush();
  return 0;
}

}  // namespace tetfsi::app
