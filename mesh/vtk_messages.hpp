#pragma once
/// @file vtk_messages.hpp
/// Keep VTK's own error and warning messages off stderr while tetfsi reads or writes a file
/// with VTK, so that a failure reaches the user as one `error: ...` line (a tetfsi::Error)
/// instead of VTK's multi-line dumps. Used by the mesh readers and by tools/ (quality, PNG).
/// VTK stays inside vtk_messages.cpp.
#include <memory>
#include <string>

namespace tetfsi::mesh {

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
