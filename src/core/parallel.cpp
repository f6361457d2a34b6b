#include "meshpde/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <thread>

namespace meshpde {

namespace {
std::atomic<int> g_limit{0};  // 0: every core
}

void set_max_threads(int n) {
  g_limit.store(std::max(0, n));
}

int max_threads() {
  const int limit = g_limit.load();
  return limit > 0 ? limit : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

bool openmp_available() {
#ifdef MESHPDE_HAVE_OPENMP
  return true;
#else
  return false;
#endif
}

}  // namespace meshpde
