/// @file vtk_messages.cpp
/// VTK's messages: routed to the logger, captured for a scope, observed per object.
#include "mesh/vtk_messages.hpp"

#include <algorithm>
#include <cctype>

#include <vtkCommand.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>

#include "core/log.hpp"

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

/// Routes VTK's messages to the tetfsi logger at debug level, one line each.
class LoggerOutputWindow : public vtkOutputWindow {
 public:
  static LoggerOutputWindow* New();
  vtkTypeMacro(LoggerOutputWindow, vtkOutputWindow);
  void DisplayText(const char* text) override {
    std::string s = text ? text : "";
    std::replace(s.begin(), s.end(), '\n', ' ');
    logger().debug("VTK: {}", s);
  }
};
vtkStandardNewMacro(LoggerOutputWindow);

/// Keeps the first error event's text.
class ErrorCollector : public vtkCommand {
 public:
  static ErrorCollector* New() { return new ErrorCollector; }
  void Execute(vtkObject*, unsigned long, void* data) override {
    if (data && message.empty()) message = static_cast<const char*>(data);
  }
  std::string message;
};

}  // namespace

void route_vtk_messages_to_log() {
  static const bool done = [] {
    vtkNew<LoggerOutputWindow> w;
    vtkOutputWindow::SetInstance(w);
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);  // VTK 9's loguru on stderr
    return true;
  }();
  (void)done;
}

struct VtkErrorObserver::Impl {
  vtkNew<ErrorCollector> collector;
};

VtkErrorObserver::VtkErrorObserver(vtkObject* object) : m_impl(std::make_unique<Impl>()) {
  object->AddObserver(vtkCommand::ErrorEvent, m_impl->collector);
}

VtkErrorObserver::~VtkErrorObserver() = default;

std::string VtkErrorObserver::first_message() const {
  return one_line_vtk_message(m_impl->collector->message);
}

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
