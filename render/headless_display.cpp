/// @file headless_display.cpp
/// HeadlessDisplay: DISPLAY if it answers, else an Xvfb of our own (see the header).
#include "render/headless_display.hpp"

#include <X11/Xlib.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/log.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// True if an X server answers at `name`.
bool display_answers(const char* name) {
  if (name == nullptr || *name == '\0') return false;
  Display* d = XOpenDisplay(name);
  if (d == nullptr) return false;
  XCloseDisplay(d);
  return true;
}

/// The last non-empty line of a text file ("" if none).
std::string last_line(const fs::path& p) {
  std::ifstream f(p);
  std::string line, last;
  while (std::getline(f, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  return last;
}

/// Wait up to `timeout_s` for `pid` to end; true if it did.
bool wait_for_exit(pid_t pid, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (true) {
    int status = 0;
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid || (r < 0 && errno == ECHILD)) return true;
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

}  // namespace

std::string find_program(const std::string& name, bool fallback) {
  std::vector<std::string> dirs;
  if (const char* path = std::getenv("PATH")) {
    std::string p = path;
    for (size_t start = 0;;) {
      const size_t colon = p.find(':', start);
      dirs.push_back(
          p.substr(start, colon == std::string::npos ? std::string::npos : colon - start));
      if (colon == std::string::npos) break;
      start = colon + 1;
    }
  }
  if (fallback) dirs.insert(dirs.end(), {"/usr/bin", "/bin"});
  for (const std::string& d : dirs) {
    if (d.empty()) continue;
    const std::string file = d + "/" + name;
    if (access(file.c_str(), X_OK) == 0 && !fs::is_directory(file)) return file;
  }
  return "";
}

HeadlessDisplay::HeadlessDisplay() {
  const char* old = std::getenv("DISPLAY");
  m_had_display = old != nullptr;
  if (old) m_old_display = old;
  if (display_answers(old)) {
    m_display = old;
    return;
  }
  const std::string xvfb = find_program("Xvfb", true);  // Debian's, whatever the PATH
  if (xvfb.empty())
    throw InputError(fmt::format(
        "rendering needs an X display (Debian's VTK draws through X) and {}; Xvfb is not "
        "installed: run scripts/setup.sh (Debian package xvfb)",
        m_had_display ? fmt::format("DISPLAY '{}' does not answer", m_old_display)
                      : std::string("DISPLAY is not set")));

  // Xvfb writes its display number to `fds[1]` once it accepts connections.
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    throw InputError(fmt::format("cannot start Xvfb: pipe: {}", std::strerror(errno)));
  char log_name[] = "/tmp/tetfsi_xvfb_XXXXXX";
  const int log_fd = mkostemp(log_name, O_CLOEXEC);
  const int null_fd = open("/dev/null", O_RDWR | O_CLOEXEC);
  const std::string fd_arg = std::to_string(fds[1]);
  std::vector<std::string> args = {xvfb, "-displayfd",   fd_arg,      "-screen",
                                   "0",  "1280x1024x24", "-nolisten", "tcp"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid == 0) {
    // The child: only async-signal-safe calls until exec.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(127);
    fcntl(fds[1], F_SETFD, 0);  // keep the display-number pipe across exec
    if (null_fd >= 0) dup2(null_fd, 0), dup2(null_fd, 1);
    if (log_fd >= 0) dup2(log_fd, 2);
    setsid();  // a Ctrl-C meant for tetfsi reaches Xvfb through the death signal only
    execv(argv[0], argv.data());
    _exit(127);
  }
  close(fds[1]);
  if (null_fd >= 0) close(null_fd);
  if (log_fd >= 0) close(log_fd);
  if (pid < 0) {
    close(fds[0]);
    unlink(log_name);
    throw InputError(fmt::format("cannot start Xvfb: fork: {}", std::strerror(errno)));
  }

  std::string number;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  bool eof = false;
  while (number.find('\n') == std::string::npos && !eof) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) break;
    pollfd p{fds[0], POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(left)) <= 0) continue;
    char buf[32];
    const ssize_t n = read(fds[0], buf, sizeof buf);
    if (n <= 0) eof = true;
    if (n > 0) number.append(buf, static_cast<size_t>(n));
  }
  close(fds[0]);
  while (!number.empty() && (number.back() == '\n' || number.back() == ' ')) number.pop_back();
  if (number.empty() || number.find_first_not_of("0123456789") != std::string::npos) {
    kill(pid, SIGKILL);
    wait_for_exit(pid, 2.0);
    const std::string why = last_line(log_name);
    unlink(log_name);
    throw InputError(fmt::format("{} did not start{}{}; check that the xvfb package works ({})",
                                 xvfb, why.empty() ? "" : ": ", why,
                                 eof ? "it exited" : "no display within 10 s"));
  }
  unlink(log_name);
  m_pid = pid;
  m_display = ":" + number;
  setenv("DISPLAY", m_display.c_str(), 1);
  logger().debug("started {} on display {} (pid {})", xvfb, m_display, pid);
}

HeadlessDisplay::~HeadlessDisplay() {
  if (m_pid <= 0) return;
  kill(m_pid, SIGTERM);
  if (!wait_for_exit(m_pid, 3.0)) {
    kill(m_pid, SIGKILL);
    wait_for_exit(m_pid, 1.0);
  }
  if (m_had_display)
    setenv("DISPLAY", m_old_display.c_str(), 1);
  else
    unsetenv("DISPLAY");
}

}  // namespace tetfsi::app
