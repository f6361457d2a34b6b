#include "meshpde/core/warnings.h"

#include <fmt/format.h>

#include <cstdio>

namespace meshpde {

namespace {
thread_local WarningCollector* innermost = nullptr;
}  // namespace

WarningCollector::WarningCollector() : outer_(innermost) {
  innermost = this;
}

WarningCollector::~WarningCollector() {
  innermost = outer_;
}

std::vector<std::string> WarningCollector::take() {
  std::vector<std::string> out;
  out.swap(messages_);
  return out;
}

void warn(const std::string& message) {
  if (innermost)
    innermost->messages_.push_back(message);
  else
    fmt::print(stderr, "warning: {}\n", message);
}

}  // namespace meshpde
