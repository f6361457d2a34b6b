// Two pieces of work at the same time, one on each of two OpenMP threads (one after the
// other without OpenMP or under set_max_threads(1)). An exception may not leave an
// OpenMP region: each side's is kept and rethrown once both have finished (the first
// side's first).
#pragma once

#include <algorithm>
#include <exception>

#include "meshpde/core/parallel.h"

namespace meshpde::detail {

template <class F0, class F1>
void run_both(F0&& f0, F1&& f1) {
  std::exception_ptr e0, e1;
  auto guarded = [](auto& f, std::exception_ptr& e) {
    try {
      f();
    } catch (...) {
      e = std::current_exception();
    }
  };
#ifdef MESHPDE_HAVE_OPENMP
  const int threads = std::min(2, max_threads());
#pragma omp parallel sections num_threads(threads)
  {
#pragma omp section
    guarded(f0, e0);
#pragma omp section
    guarded(f1, e1);
  }
#else
  guarded(f0, e0);
  guarded(f1, e1);
#endif
  if (e0) std::rethrow_exception(e0);
  if (e1) std::rethrow_exception(e1);
}

}  // namespace meshpde::detail
