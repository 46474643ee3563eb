#pragma once
/// @file headless_display.hpp
/// An X display for VTK's OpenGL renderer. Debian's VTK 9.1 renders only through X (its
/// vtkXOpenGLRenderWindow; no EGL or OSMesa build, docs/dev/architecture.md, measured facts), so
/// `tetfsi render` needs a display even off screen: the one in `DISPLAY` if it answers, else an
/// `Xvfb` server started here on a free display number (`-displayfd`) and stopped again when this
/// object goes away. Mesa's software rasteriser (llvmpipe, `libgl1-mesa-dri`) draws into it.
#include <sys/types.h>
#include <string>

namespace tetfsi::app {

class HeadlessDisplay {
 public:
  /// Use `DISPLAY` if an X server answers there; otherwise start `Xvfb :N -screen 0
  /// 1280x1024x24 -nolisten tcp` (N chosen by Xvfb) and point `DISPLAY` at it for this process.
  /// The server gets SIGTERM when the process dies, so it never outlives a crashed tetfsi.
  /// @throws InputError naming what to do if there is no display and `Xvfb` is not installed
  ///   (`scripts/setup.sh` installs Debian's `xvfb`) or if it does not start within 10 s.
  HeadlessDisplay();
  /// Stops the Xvfb started here (if any) and restores `DISPLAY`.
  ~HeadlessDisplay();
  HeadlessDisplay(const HeadlessDisplay&) = delete;
  HeadlessDisplay& operator=(const HeadlessDisplay&) = delete;

  /// ":N" in use.
  const std::string& display() const { return m_display; }
  /// True if this object started an Xvfb (false: an existing display answered).
  bool started_xvfb() const { return m_pid > 0; }

 private:
  std::string m_display;
  std::string m_old_display;  ///< DISPLAY before (to restore)
  bool m_had_display = false;
  pid_t m_pid = -1;
};

/// The first executable file `name` in PATH, else (`fallback`) in /usr/bin and /bin; "" if
/// none.
std::string find_program(const std::string& name, bool fallback = false);

}  // namespace tetfsi::app
