// Threads inside the direct solvers: how many BLAS threads a factorization gets, and
// keeping CHOLMOD's own OpenMP regions on the calling thread. Internal to the solver
// layer (direct.cpp and the CHOLMOD factors in cholmod_factors.cpp).
#pragma once

#include <Eigen/Core>

#include "../core/two_threads.h"

namespace meshpde::detail {

/// Measured on the 2-core development machine (docs/solvers-measurements.md), bi-Laplacian drag
/// regions: below about 700 unknowns Eigen's simplicial factorization beats CHOLMOD's
/// supernodal one (504: 0.79 against 0.88 ms; 1,140: 2.8 against 2.2 ms).
constexpr Eigen::Index kSimplicialBelow = 700;

/// Sets OpenBLAS's thread count (Debian's libopenblas0-pthread provides libblas.so.3
/// and exports openblas_set_num_threads); with another BLAS nothing is changed.
void set_blas_threads(int n);

/// BLAS threads for a factorization of n unknowns: below about 60,000 a second BLAS
/// thread does not pay (128k: 1.75 s on one or two), so one; else every core.
int blas_threads_for(Eigen::Index n);

/// CHOLMOD 3 (SuiteSparse 5.x) runs parts of its supernodal factorization (the scatter
/// of each supernode's update) in OpenMP regions whose thread count is fixed when
/// CHOLMOD is compiled (CHOLMOD_OMP_NUM_THREADS, 4 in Debian's build), whatever the
/// machine has. On two cores that is four threads forking and joining once per
/// supernode: measured on the 10k-vertex drag region's K D K (126 Mflop), 48 ms with
/// them and 13 ms without (docs/solvers-measurements.md). The parallel work that pays is the BLAS's
/// (its own threads, blas_threads_for), so CHOLMOD's regions run on the calling thread:
/// with no active parallel level allowed (OpenMpActiveLevels(0)), every OpenMP region is
/// one thread. Restored on leaving, so meshpde's own loops are not affected. Does
/// nothing without OpenMP.
class OpenMpActiveLevels {
 public:
  explicit OpenMpActiveLevels(int levels);
  ~OpenMpActiveLevels();
  OpenMpActiveLevels(const OpenMpActiveLevels&) = delete;
  OpenMpActiveLevels& operator=(const OpenMpActiveLevels&) = delete;

 private:
  [[maybe_unused]] int saved_ = 0;  // unused without OpenMP
};

/// Runs f0 and f1 at the same time, each on one core, with one BLAS thread each; CHOLMOD's
/// own OpenMP regions inside them stay on their thread (nested regions are inactive at
/// one active level). One thread under set_max_threads(1). Exceptions are rethrown after
/// both have finished.
template <class F0, class F1>
void on_two_threads(F0&& f0, F1&& f1) {
  set_blas_threads(1);
  const OpenMpActiveLevels levels(max_threads() > 1 ? 1 : 0);
  run_both(f0, f1);
}

}  // namespace meshpde::detail
