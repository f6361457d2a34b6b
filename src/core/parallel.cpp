#include "meshpde/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <thread>
#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

namespace meshpde {

namespace {
std::atomic<int> g_limit{0};   // 0: every core
thread_local int t_limit = 0;  // 0: no cap on this thread (ThreadLimit)
}  // namespace

void set_max_threads(int n) {
  g_limit.store(std::max(0, n));
}

int max_threads() {
  const int limit = g_limit.load();
  const int all = limit > 0 ? limit : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return t_limit > 0 ? std::min(all, t_limit) : all;
}

ThreadLimit::ThreadLimit(int n) : saved_(t_limit) {
  t_limit = std::max(1, n);
}

ThreadLimit::~ThreadLimit() {
  t_limit = saved_;
}

namespace detail {

int run_row_ranges(std::ptrdiff_t n, int threads, void (*f)(void*, std::ptrdiff_t, std::ptrdiff_t, int),
                   void* context) {
#ifdef MESHPDE_HAVE_OPENMP
  int used = 1;
#pragma omp parallel num_threads(threads)
  {
    const std::ptrdiff_t t = omp_get_thread_num(), parts = omp_get_num_threads();
    if (t == 0) used = static_cast<int>(parts);
    f(context, n * t / parts, n * (t + 1) / parts, static_cast<int>(t));
  }
  return used;
#else
  (void)threads;
  f(context, 0, n, 0);
  return 1;
#endif
}

}  // namespace detail

bool openmp_available() {
#ifdef MESHPDE_HAVE_OPENMP
  return true;
#else
  return false;
#endif
}

}  // namespace meshpde
