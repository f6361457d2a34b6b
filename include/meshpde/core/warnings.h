// Warnings: input the library accepts but that is probably not what was meant (a point
// typed far from the surface it should pick a vertex of, ...), as a message for the user.
//
// A warning goes to the innermost WarningCollector alive on the calling thread; with
// none, it is printed to stderr as "warning: MESSAGE" (the command line's form). The
// Python module collects them around a call and gives each as a UserWarning.
#pragma once

#include <string>
#include <vector>

namespace meshpde {

/// Gives `message` (one sentence naming what it is about) to the innermost collector on
/// this thread, or prints it to stderr.
void warn(const std::string& message);

/// Collects the warnings given on this thread while it is alive (collectors nest: the
/// innermost takes them).
class WarningCollector {
 public:
  WarningCollector();
  ~WarningCollector();
  WarningCollector(const WarningCollector&) = delete;
  WarningCollector& operator=(const WarningCollector&) = delete;
  /// The warnings collected so far, in the order given; the collector is emptied.
  std::vector<std::string> take();

 private:
  friend void warn(const std::string& message);
  std::vector<std::string> messages_;
  WarningCollector* outer_;
};

}  // namespace meshpde
