// How many threads meshpde may use.
//
// Whole-mesh operator applies (K, K D K over tens of thousands of rows and more) run
// on OpenMP threads when meshpde was built with OpenMP, and CHOLMOD's supernodal
// factorizations run on the threads of the BLAS (OpenBLAS). Both follow this limit.
// Small row sets (an active domain of a haptic probe, a drag region) stay on the
// calling thread: below about 20k rows waking a second thread costs more than it saves.
#pragma once

namespace meshpde {

/// Limits the threads of meshpde's parallel loops and of the BLAS under CHOLMOD.
/// n <= 0 restores the default: every core (std::thread::hardware_concurrency()).
void set_max_threads(int n);
/// The current limit (at least 1).
int max_threads();
/// Whether meshpde was built with OpenMP (else its loops run on one thread).
bool openmp_available();

/// Caps max_threads() for the calling thread only, while it lives: a background worker
/// that must leave the other cores to a real-time thread (the haptic servo's factor
/// builder, apps/haptics.h) runs meshpde's parallel loops on itself alone.
class ThreadLimit {
 public:
  explicit ThreadLimit(int n);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  int saved_;
};

}  // namespace meshpde
