#include "solver_threads.h"

#include <dlfcn.h>

#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

namespace meshpde::detail {

void set_blas_threads(int n) {
  using Fn = void (*)(int);
  static const Fn fn = reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (fn) fn(n);
}

int blas_threads_for(Eigen::Index n) {
  constexpr Eigen::Index kOneBlasThreadBelow = 60000;
  return n < kOneBlasThreadBelow ? 1 : max_threads();
}

#ifdef MESHPDE_HAVE_OPENMP
OpenMpActiveLevels::OpenMpActiveLevels(int levels) : saved_(omp_get_max_active_levels()) {
  omp_set_max_active_levels(levels);
}
OpenMpActiveLevels::~OpenMpActiveLevels() {
  omp_set_max_active_levels(saved_);
}
#else
OpenMpActiveLevels::OpenMpActiveLevels(int) {}
OpenMpActiveLevels::~OpenMpActiveLevels() = default;
#endif

}  // namespace meshpde::detail
