// A progress bar on stderr for long runs: redrawn in place on a terminal, one line
// per 10 % otherwise (logs, CI).
#pragma once

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace meshpde::cli {

class Progress {
 public:
  Progress(long long total, std::string what, bool enabled = true)
      : total_(total),
        what_(std::move(what)),
        enabled_(enabled && total >= 20),
        tty_(isatty(fileno(stderr))),
        start_(std::chrono::steady_clock::now()) {}
  void update(long long done) {
    if (!enabled_) return;
    const int pct = static_cast<int>(100 * done / total_);
    if (tty_) {
      if (pct == last_ && done != total_) return;
      const int w = 30, fill = w * pct / 100;
      fmt::print(stderr, "\r{} [{}{}] {:3d}% {}/{} {:.1f} s", what_, std::string(fill, '='), std::string(w - fill, ' '),
                 pct, done, total_, seconds());
      if (done == total_) fmt::print(stderr, "\n");
    } else if (pct / 10 != last_ / 10 || done == total_) {
      fmt::print(stderr, "{}: {}% ({}/{}, {:.1f} s)\n", what_, pct, done, total_, seconds());
    }
    last_ = pct;
  }

 private:
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }
  long long total_;
  std::string what_;
  bool enabled_, tty_;
  int last_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace meshpde::cli
