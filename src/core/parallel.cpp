#include "meshpde/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <thread>

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

bool openmp_available() {
#ifdef MESHPDE_HAVE_OPENMP
  return true;
#else
  return false;
#endif
}

}  // namespace meshpde
