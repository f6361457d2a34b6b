// Internal: turns VTK's printed errors into exceptions that name the file.
//
// VTK reports problems by printing through vtkOutputWindow and carrying on. For
// the lifetime of a VtkErrorCapture, everything VTK would print is collected
// instead, and check() throws InputError with the first error if any was seen.
#pragma once

#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkLogger.h>
#include <vtkObject.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>
#include <vtkStringOutputWindow.h>

#include <string>

namespace meshpde::detail {

class VtkErrorCapture {
 public:
  VtkErrorCapture()
      : previous_(vtkOutputWindow::GetInstance()), window_(vtkSmartPointer<vtkStringOutputWindow>::New()) {
    vtkOutputWindow::SetInstance(window_);
    // VTK 9 also logs errors through loguru straight to stderr; quiet it meanwhile.
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
  }
  ~VtkErrorCapture() {
    vtkOutputWindow::SetInstance(previous_.Get());
    vtkLogger::SetStderrVerbosity(previous_verbosity_);
  }
  VtkErrorCapture(const VtkErrorCapture&) = delete;
  VtkErrorCapture& operator=(const VtkErrorCapture&) = delete;

  /// Also listen to `object`'s ErrorEvent (its own errors stop being printed).
  void watch(vtkObject* object) {
    auto cb = vtkSmartPointer<vtkCallbackCommand>::New();
    cb->SetClientData(this);
    cb->SetCallback([](vtkObject*, unsigned long, void* self, void* data) {
      auto* me = static_cast<VtkErrorCapture*>(self);
      if (me->first_error_.empty() && data) me->first_error_ = static_cast<const char*>(data);
    });
    object->AddObserver(vtkCommand::ErrorEvent, cb);
  }

  /// The first error seen, or the printed text when it holds an ERROR line.
  std::string error() const {
    if (!first_error_.empty()) return tidy(first_error_);
    const std::string text = window_->GetOutput();
    const auto at = text.find("ERROR");
    if (at == std::string::npos) return {};
    return tidy(text.substr(at));
  }

 private:
  // VTK messages start with a source location and object address; keep the last
  // line, which says what went wrong.
  static std::string tidy(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    const auto nl = s.rfind('\n');
    if (nl != std::string::npos) s = s.substr(nl + 1);
    return s;
  }

  vtkLogger::Verbosity previous_verbosity_ = vtkLogger::GetCurrentVerbosityCutoff();
  vtkSmartPointer<vtkOutputWindow> previous_;  // kept alive while replaced
  vtkSmartPointer<vtkStringOutputWindow> window_;
  std::string first_error_;
};

}  // namespace meshpde::detail
