// Preconditioned conjugate gradients for symmetric positive definite operators given
// as functions, on several right-hand sides at once (one CG per column sharing each
// operator application: x, y, z of a displacement). The one CG kernel of the library:
// the time step's Jacobi-CG, the surface multigrid's and the global bi-Laplacian's
// outer iterations and the refinement of direct solves all run block_pcg.
//
// Tolerance is on the relative residual |b - A x| / |b| per column; a column that
// meets it stops moving while the others go on. Non-convergence is a status, not an
// exception. A non-positive curvature p'Ap <= 0 on a column still iterating (the
// operator is not SPD on the free set, e.g. a floating component with no constraint
// under a pure stiffness operator) or a residual that is not finite stops with status
// Breakdown and a message in words.
#pragma once

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/field.h"

namespace meshpde {

struct CgOptions {
  double tolerance = 1e-8;     ///< relative residual |b - A x| / |b| per column
  int max_iterations = 20000;  ///< iteration cap
  /// Stop with status Deadline (keeping the current iterate) once this time has passed;
  /// the default (epoch) means no deadline. Used by real-time loops.
  std::chrono::steady_clock::time_point deadline{};
  /// Iterations always run before the deadline is looked at: a step that starts
  /// late still makes progress instead of returning its starting guess.
  int min_iterations = 0;
  /// Past the deadline, stop only once the relative residual is at most this.
  /// Real-time loops set it (HapticParams: 1e-2): an overrun costs one late step,
  /// an inaccurate implicit step can feed energy into the surface, step after step.
  double late_tolerance = std::numeric_limits<double>::infinity();
  /// Above this many rows the vector loops (dot products, updates) run on every thread
  /// (core/parallel.h); up to it they stay on the calling thread and allocate nothing
  /// after the first solve. Dot products are summed in chunks of this many rows, added
  /// in order: the same bits on any number of threads.
  std::ptrdiff_t parallel_rows = 5000;
  /// The workspace's r holds b - A x for the starting x on entry (a caller that has
  /// it saves one product).
  bool residual_given = false;
};

/// A tolerance a user gives (`--tolerance`, Python `tolerance=`): a relative residual
/// strictly between 0 and 1 (0 or less is never reached, so CG would run to its cap;
/// 1 or more is met by the starting guess). \throw InputError naming `name` otherwise.
inline void check_tolerance(double tolerance, const char* name = "tolerance") {
  if (!(tolerance > 0 && tolerance < 1))
    throw InputError(
        fmt::format("{}: {:g} is not a relative residual between 0 and 1 (for example 1e-10)", name, tolerance));
}

enum class CgStatus { Converged, MaxIterations, Breakdown, Deadline, Stopped };

struct CgResult {
  CgStatus status = CgStatus::Converged;
  int iterations = 0;
  double relative_residual = 0;  ///< worst column (of the recurrence's residual)
  std::string message;           ///< set when not converged
  bool converged() const { return status == CgStatus::Converged; }
};

const char* to_string(CgStatus s);

/// Work buffers kept between solves so repeated small solves allocate nothing.
struct CgWorkspace {
  Field r, z, p, q;
  std::vector<double> partial;  ///< per-chunk column sums (CgOptions::parallel_rows)
};

/// The Jacobi preconditioner z_i = inverse_diagonal_i r_i. block_pcg fuses it into its
/// vector loops (the haptic steps' solves are small and frequent).
struct JacobiPreconditioner {
  const Eigen::VectorXd& inverse_diagonal;  ///< 1 / A_ii, one per row
};

/// The default monitor of block_pcg: never stops a solve.
struct NoCgMonitor {
  bool operator()(int, double) const { return true; }
};

namespace detail {

// acc[k * m + c] summed over the rows by body(begin, end, acc), chunk by chunk of
// opt.parallel_rows rows (the chunks on every thread when there are several), the
// chunks' sums added in chunk order into out: the same bits on any number of threads.
template <int M, int K, class Body>
void cg_reduce(Eigen::Index n, Eigen::Index m, const CgOptions& opt, std::vector<double>& partial, double* out,
               Body&& body) {
  const std::ptrdiff_t chunk = std::max<std::ptrdiff_t>(opt.parallel_rows, 1);
  const std::ptrdiff_t chunks = (n + chunk - 1) / chunk;
  for_row_ranges(chunks, 2, [&](std::ptrdiff_t first, std::ptrdiff_t last, int) {
    for (std::ptrdiff_t c = first; c < last; ++c) {
      double* dst = partial.data() + static_cast<std::size_t>(c) * K * m;
      const std::ptrdiff_t begin = c * chunk, end = std::min<std::ptrdiff_t>(n, begin + chunk);
      if constexpr (M > 0) {
        std::array<double, K * M> acc{};  // in registers: the loops are short and frequent
        body(begin, end, acc.data());
        std::copy(acc.begin(), acc.end(), dst);
      } else {
        std::fill(dst, dst + K * m, 0.0);
        body(begin, end, dst);
      }
    }
  });
  std::fill(out, out + K * m, 0.0);
  for (std::ptrdiff_t c = 0; c < chunks; ++c)
    for (Eigen::Index k = 0; k < K * m; ++k) out[k] += partial[static_cast<std::size_t>(c) * K * m + k];
}

// The kernel on n x m row-major blocks; M > 0 fixes the column count at compile time
// so the per-column accumulators live in registers (M = 0: any count, read from b).
template <int M, class Apply, class Precondition, class Monitor>
CgResult block_pcg_impl(Apply& apply, Precondition& precondition, const Field& b, Field& x, const CgOptions& opt,
                        CgWorkspace& w, Monitor& monitor) {
  constexpr bool kJacobi = std::is_same_v<std::remove_cvref_t<Precondition>, JacobiPreconditioner>;
  const Eigen::Index n = b.rows();
  const Eigen::Index m = M > 0 ? M : b.cols();
  CgResult res;
  if (n == 0) return res;
  if (x.rows() != n || x.cols() != m) x = Field::Zero(n, m);
  for (Field* f : {&w.z, &w.p, &w.q}) f->resize(n, m);
  const auto chunks = static_cast<std::size_t>((n + std::max<std::ptrdiff_t>(opt.parallel_rows, 1) - 1) /
                                               std::max<std::ptrdiff_t>(opt.parallel_rows, 1));
  if (w.partial.size() < chunks * 2 * static_cast<std::size_t>(m)) w.partial.resize(chunks * 2 * m);
  // Column sums: [0, m) and [m, 2m) of one pass.
  std::vector<double> heap;
  std::array<double, 2 * (M > 0 ? M : 1)> stack{};
  if constexpr (M == 0) heap.assign(static_cast<std::size_t>(2 * m), 0.0);
  double* sums = M > 0 ? stack.data() : heap.data();
  std::array<double, (M > 0 ? 5 * M : 1)> stack_cols{};
  std::vector<double> heap_cols;
  if constexpr (M == 0) heap_cols.assign(static_cast<std::size_t>(5 * m), 0.0);
  double* cols = M > 0 ? stack_cols.data() : heap_cols.data();
  double* bnorm = cols;
  double* rz = cols + m;
  double* alpha = cols + 2 * m;
  double* beta = cols + 3 * m;
  double* active = cols + 4 * m;  // 1 while the column iterates

  const double* B = b.data();
  double* X = x.data();
  cg_reduce<M, 1>(n, m, opt, w.partial, sums, [&](std::ptrdiff_t begin, std::ptrdiff_t end, double* acc) {
    for (std::ptrdiff_t i = begin; i < end; ++i)
      for (Eigen::Index c = 0; c < m; ++c) acc[c] += B[i * m + c] * B[i * m + c];
  });
  for (Eigen::Index c = 0; c < m; ++c) {
    bnorm[c] = std::sqrt(sums[c]);
    if (bnorm[c] == 0)
      for (Eigen::Index i = 0; i < n; ++i) X[i * m + c] = 0;  // the exact solution of an SPD system
  }
  if (!opt.residual_given) {
    w.r.resize(n, m);
    if (x.isZero(0)) {
      w.r = b;  // a zero start needs no product
    } else {
      apply(x, w.q);
      w.r = b - w.q;
    }
  }
  double* R = w.r.data();
  double* Z = w.z.data();
  double* P = w.p.data();
  double* Q = w.q.data();

  // Sets `active` from the residual norms rr (m values); false when no column iterates
  // or the residual is not finite (then status Breakdown).
  auto update_active = [&](const double* rr) {
    bool any = false;
    res.relative_residual = 0;
    for (Eigen::Index c = 0; c < m; ++c) {
      const double rel = bnorm[c] > 0 ? std::sqrt(rr[c]) / bnorm[c] : 0.0;
      if (!std::isfinite(rel)) {
        res.status = CgStatus::Breakdown;
        res.message = "the residual became NaN or infinite (non-finite input or operator)";
        return false;
      }
      res.relative_residual = std::max(res.relative_residual, rel);
      active[c] = rel > opt.tolerance ? 1.0 : 0.0;
      any |= active[c] != 0;
    }
    return any;
  };
  // One pass over the rows: with `step`, x += alpha p and r -= alpha q first; then the
  // sums r'r into sums[0, m), and for Jacobi z = D^-1 r and r'z into sums[m, 2m) in
  // the same pass (the haptic steps' solves are small and frequent).
  auto sweep = [&](bool step) {
    constexpr int K = kJacobi ? 2 : 1;
    const double* Dinv = nullptr;
    if constexpr (kJacobi) Dinv = precondition.inverse_diagonal.data();
    cg_reduce<M, K>(n, m, opt, w.partial, sums, [&](std::ptrdiff_t begin, std::ptrdiff_t end, double* acc) {
      for (std::ptrdiff_t i = begin; i < end; ++i)
        for (Eigen::Index c = 0; c < m; ++c) {
          const Eigen::Index k = i * m + c;
          if (step) {
            X[k] += alpha[c] * P[k];
            R[k] -= alpha[c] * Q[k];
          }
          acc[c] += R[k] * R[k];
          if constexpr (kJacobi) {
            Z[k] = Dinv[i] * R[k];
            acc[m + c] += R[k] * Z[k];
          }
        }
    });
  };
  // Any other preconditioner: z = M^-1 r, then r'z into sums[m, 2m).
  auto precondition_rz = [&] {
    if constexpr (!kJacobi) {
      precondition(w.r, w.z);
      cg_reduce<M, 1>(n, m, opt, w.partial, sums + m, [&](std::ptrdiff_t begin, std::ptrdiff_t end, double* acc) {
        for (std::ptrdiff_t i = begin; i < end; ++i)
          for (Eigen::Index c = 0; c < m; ++c) acc[c] += R[i * m + c] * Z[i * m + c];
      });
    }
  };

  sweep(false);
  if (!update_active(sums)) return res;
  if (!monitor(0, res.relative_residual)) {
    res.status = CgStatus::Stopped;
    res.message = fmt::format("stopped by its caller (relative residual {:.3g})", res.relative_residual);
    return res;
  }
  precondition_rz();
  for (Eigen::Index c = 0; c < m; ++c) rz[c] = sums[m + c];
  for_row_ranges(n, opt.parallel_rows, [&](std::ptrdiff_t begin, std::ptrdiff_t end, int) {
    std::copy(Z + begin * m, Z + end * m, P + begin * m);
  });
  const bool timed = opt.deadline != std::chrono::steady_clock::time_point{};
  for (int it = 0; it < opt.max_iterations; ++it) {
    if (timed && it >= opt.min_iterations && res.relative_residual <= opt.late_tolerance &&
        std::chrono::steady_clock::now() > opt.deadline) {
      res.status = CgStatus::Deadline;
      res.message =
          fmt::format("deadline reached after {} iterations (relative residual {:.3g})", it, res.relative_residual);
      return res;
    }
    apply(w.p, w.q);
    res.iterations = it + 1;
    cg_reduce<M, 1>(n, m, opt, w.partial, sums, [&](std::ptrdiff_t begin, std::ptrdiff_t end, double* acc) {
      for (std::ptrdiff_t i = begin; i < end; ++i)
        for (Eigen::Index c = 0; c < m; ++c) acc[c] += P[i * m + c] * Q[i * m + c];
    });
    for (Eigen::Index c = 0; c < m; ++c) {
      alpha[c] = 0;
      if (active[c] == 0) continue;
      if (!(sums[c] > 0)) {
        res.status = CgStatus::Breakdown;
        res.message = fmt::format(
            "the system is not positive definite on the free vertices (p'Ap = {:.3g} in component {}); "
            "is there a connected part with no constrained vertex?",
            sums[c], c);
        return res;
      }
      alpha[c] = rz[c] / sums[c];
    }
    sweep(true);
    if (!update_active(sums)) break;
    if (!monitor(res.iterations, res.relative_residual)) {
      res.status = CgStatus::Stopped;
      res.message = fmt::format("stopped by its caller after {} iterations (relative residual {:.3g})", res.iterations,
                                res.relative_residual);
      return res;
    }
    precondition_rz();
    for (Eigen::Index c = 0; c < m; ++c) {
      beta[c] = active[c] != 0 && rz[c] != 0 ? sums[m + c] / rz[c] : 0.0;
      rz[c] = sums[m + c];
    }
    for_row_ranges(n, opt.parallel_rows, [&](std::ptrdiff_t begin, std::ptrdiff_t end, int) {
      for (std::ptrdiff_t i = begin; i < end; ++i)
        for (Eigen::Index c = 0; c < m; ++c) {
          const Eigen::Index k = i * m + c;
          P[k] = active[c] != 0 ? Z[k] + beta[c] * P[k] : 0.0;
        }
    });
  }
  if (res.status == CgStatus::Breakdown) return res;
  if (res.relative_residual <= opt.tolerance) {
    res.status = CgStatus::Converged;
    return res;
  }
  res.status = CgStatus::MaxIterations;
  res.message = fmt::format("no convergence in {} iterations (relative residual {:.3g} > {:.3g})", opt.max_iterations,
                            res.relative_residual, opt.tolerance);
  return res;
}

}  // namespace detail

/// Solves A x = b by preconditioned CG. `apply(P, Q)` writes Q = A P and
/// `precondition(R, Z)` writes Z = M^-1 R, both on n x m blocks (M symmetric positive
/// definite; a JacobiPreconditioner is fused into the vector loops). `x` holds the
/// starting guess (resized to zero when its shape is not b's). `monitor(iterations,
/// relative_residual)` is called with the starting residual and after every iteration
/// that has not converged; false stops the solve with status Stopped.
template <class Apply, class Precondition, class Monitor = NoCgMonitor>
CgResult block_pcg(Apply&& apply, Precondition&& precondition, const Field& b, Field& x, const CgOptions& opt,
                   CgWorkspace& w, Monitor&& monitor = {}) {
  switch (b.cols()) {
    case 1:
      return detail::block_pcg_impl<1>(apply, precondition, b, x, opt, w, monitor);
    case 3:
      return detail::block_pcg_impl<3>(apply, precondition, b, x, opt, w, monitor);
    default:
      return detail::block_pcg_impl<0>(apply, precondition, b, x, opt, w, monitor);
  }
}

/// Jacobi-preconditioned CG: `inv_diag` (length n) is 1 / A_ii; otherwise as block_pcg.
template <class Apply>
CgResult pcg(Apply&& apply, const Eigen::VectorXd& inv_diag, const Field& b, Field& x, const CgOptions& opt,
             CgWorkspace& w) {
  return block_pcg(apply, JacobiPreconditioner{inv_diag}, b, x, opt, w);
}

inline const char* to_string(CgStatus s) {
  switch (s) {
    case CgStatus::Converged:
      return "converged";
    case CgStatus::MaxIterations:
      return "max_iterations";
    case CgStatus::Breakdown:
      return "breakdown";
    case CgStatus::Deadline:
      return "deadline";
    case CgStatus::Stopped:
      return "stopped";
  }
  return "unknown";
}

}  // namespace meshpde
