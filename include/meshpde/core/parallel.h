// How many threads meshpde may use.
//
// Whole-mesh operator applies (K, K D K over tens of thousands of rows and more) run
// on OpenMP threads when meshpde was built with OpenMP, and CHOLMOD's supernodal
// factorizations run on the threads of the BLAS (OpenBLAS). Both follow this limit.
// Small row sets (an active domain of a haptic probe, a drag region) stay on the
// calling thread: below about 20k rows waking a second thread costs more than it saves.
#pragma once

#include <cstddef>
#include <type_traits>

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

namespace detail {
// The OpenMP side of for_row_ranges (parallel.cpp): f(context, begin, end, part) on
// every thread's range; returns the number of parts.
int run_row_ranges(std::ptrdiff_t n, int threads, void (*f)(void*, std::ptrdiff_t, std::ptrdiff_t, int), void* context);
}  // namespace detail

/// Runs f(begin, end, part) on [0, n) cut into one contiguous range per thread, part
/// 0, 1, ... in order, when n >= min_rows and max_threads() > 1 (and OpenMP is there);
/// else f(0, n, 0) on the calling thread, which allocates nothing. Returns the number of
/// parts. The same n and thread limit always give the same cut, so sums taken per part
/// and added in part order give the same bits every time.
template <class F>
int for_row_ranges(std::ptrdiff_t n, std::ptrdiff_t min_rows, F&& f) {
  if (n < min_rows || !openmp_available()) {
    f(std::ptrdiff_t{0}, n, 0);
    return 1;
  }
  const int threads = max_threads();
  if (threads < 2) {
    f(std::ptrdiff_t{0}, n, 0);
    return 1;
  }
  using Body = std::remove_reference_t<F>;
  return detail::run_row_ranges(
      n, threads,
      [](void* context, std::ptrdiff_t begin, std::ptrdiff_t end, int part) {
        (*static_cast<Body*>(context))(begin, end, part);
      },
      const_cast<void*>(static_cast<const void*>(&f)));
}

}  // namespace meshpde
