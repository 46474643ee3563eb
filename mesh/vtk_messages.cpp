/// @file vtk_messages.cpp
/// VtkMessageCapture: a capturing vtkOutputWindow installed for a scope.
#include "mesh/vtk_messages.hpp"

#include <algorithm>
#include <cctype>

#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>

namespace tetfsi::mesh {

namespace {

/// An output window that keeps the first message instead of printing it.
class CapturingOutputWindow : public vtkOutputWindow {
 public:
  static CapturingOutputWindow* New();
  vtkTypeMacro(CapturingOutputWindow, vtkOutputWindow);
  void DisplayText(const char* text) override { keep(text); }
  void DisplayErrorText(const char* text) override { keep(text); }
  void DisplayWarningText(const char* text) override { keep(text); }
  void DisplayGenericWarningText(const char* text) override { keep(text); }
  void DisplayDebugText(const char*) override {}
  std::string first;

 private:
  void keep(const char* text) {
    if (first.empty() && text) first = text;
  }
};
vtkStandardNewMacro(CapturingOutputWindow);

}  // namespace

struct VtkMessageCapture::Impl {
  vtkNew<CapturingOutputWindow> window;
  vtkSmartPointer<vtkOutputWindow> previous;
  vtkLogger::Verbosity verbosity = vtkLogger::VERBOSITY_OFF;
};

VtkMessageCapture::VtkMessageCapture() : m_impl(std::make_unique<Impl>()) {
  m_impl->previous = vtkOutputWindow::GetInstance();
  m_impl->verbosity = vtkLogger::GetCurrentVerbosityCutoff();
  vtkOutputWindow::SetInstance(m_impl->window);
  vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
}

VtkMessageCapture::~VtkMessageCapture() {
  vtkOutputWindow::SetInstance(m_impl->previous);
  vtkLogger::SetStderrVerbosity(m_impl->verbosity);
}

std::string VtkMessageCapture::first_message() const {
  return one_line_vtk_message(m_impl->window->first);
}

std::string one_line_vtk_message(std::string msg) {
  if (msg.rfind("ERROR: In ", 0) == 0 || msg.rfind("Warning: In ", 0) == 0) {
    const auto nl = msg.find('\n');
    msg = nl == std::string::npos ? "" : msg.substr(nl + 1);
  }
  const auto obj = msg.find("): ");
  if (obj != std::string::npos && msg.find(" (0x") < obj) msg = msg.substr(obj + 3);
  std::replace(msg.begin(), msg.end(), '\n', ' ');
  std::replace(msg.begin(), msg.end(), '\r', ' ');
  while (!msg.empty() && std::isspace(static_cast<unsigned char>(msg.back()))) msg.pop_back();
  return msg;
}

}  // namespace tetfsi::mesh
