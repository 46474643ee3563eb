#pragma once
/// @file vtk_messages.hpp
/// tetfsi's one way of handling VTK's own messages: they never reach stderr as VTK's
/// multi-line dumps; a failure reaches the user as one `error: ...` line (a tetfsi::Error).
/// Three pieces, used by every reader and writer that touches VTK (mesh/io, io/output,
/// render/):
///  - route_vtk_messages_to_log: VTK's messages go to tetfsi's logger at debug level, for good;
///  - VtkMessageCapture: for a scope, the first message is kept instead (one thread at a time);
///  - VtkErrorObserver: the first error event of one VTK object (safe from many threads, one
///    object each).
/// VTK stays inside vtk_messages.cpp: the header only forward-declares vtkObject.
#include <memory>
#include <string>

class vtkObject;

namespace tetfsi::mesh {

/// From now on, VTK's output window writes to tetfsi's logger at debug level (one line per
/// message) and VTK's own logger is silent on stderr. Idempotent; thread-safe.
void route_vtk_messages_to_log();

/// Keeps the first error event `object` reports (VTK sends an object's errors to its
/// observers instead of the output window when it has one). Attach before the object runs.
class VtkErrorObserver {
 public:
  explicit VtkErrorObserver(vtkObject* object);
  ~VtkErrorObserver();
  VtkErrorObserver(const VtkErrorObserver&) = delete;
  VtkErrorObserver& operator=(const VtkErrorObserver&) = delete;
  /// The first error, reduced to one line (one_line_vtk_message); empty if none.
  std::string first_message() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// While alive, VTK's output window keeps messages here instead of printing them, and VTK's
/// logger is silent on stderr; both are restored on destruction. VTK's output window and
/// logger are globals: use from one thread at a time.
class VtkMessageCapture {
 public:
  VtkMessageCapture();
  ~VtkMessageCapture();
  VtkMessageCapture(const VtkMessageCapture&) = delete;
  VtkMessageCapture& operator=(const VtkMessageCapture&) = delete;

  /// The first error or warning VTK reported since construction, reduced to one line
  /// (see one_line_vtk_message); empty if none.
  std::string first_message() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// "ERROR: In file.cxx, line 12\nvtkClass (0x1234): message\n\n" → "message" on one line.
std::string one_line_vtk_message(std::string message);

}  // namespace tetfsi::mesh
