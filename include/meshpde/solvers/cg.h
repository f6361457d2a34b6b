// Jacobi-preconditioned conjugate gradient for symmetric positive definite
// operators given as a function, on several right-hand sides at once (one CG per
// column sharing each operator application: x, y, z of a displacement).
//
// Tolerance is on the relative residual |b - A x| / |b| per column; non-convergence
// is a status, not an exception. A non-positive curvature p'Ap <= 0 (the operator
// is not SPD on the free set, e.g. a floating component with no constraint under
// a pure stiffness operator) stops with status Breakdown and a message in words.
#pragma once

#include <fmt/format.h>

#include <Eigen/Core>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

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
};

enum class CgStatus { Converged, MaxIterations, Breakdown, Deadline };

struct CgResult {
  CgStatus status = CgStatus::Converged;
  int iterations = 0;
  double relative_residual = 0;  ///< worst column
  std::string message;           ///< set when not converged
  bool converged() const { return status == CgStatus::Converged; }
};

const char* to_string(CgStatus s);

/// Work buffers kept between solves so repeated small solves allocate nothing.
struct CgWorkspace {
  Field r, z, p, q;
};

namespace detail {

/// CG on n x M blocks; M > 0 fixes the column count at compile time so the per-column
/// accumulators live in registers (M = 0: any count, read from b).
template <int M, class Apply>
CgResult pcg_impl(Apply&& apply, const Eigen::VectorXd& inv_diag, const Field& b, Field& x, const CgOptions& opt,
                  CgWorkspace& w) {
  // Flat loops over the row-major n x m blocks: the solves are small and frequent
  // (haptic steps), so per-iteration overhead matters more than vectorized width.
  const Eigen::Index n = b.rows();
  const Eigen::Index m = M > 0 ? M : b.cols();
  CgResult res;
  if (n == 0) return res;
  w.r.resize(n, m);
  w.z.resize(n, m);
  w.p.resize(n, m);
  w.q.resize(n, m);
  constexpr int kMax = M > 0 ? M : 1;
  using Acc = std::conditional_t<(M > 0), std::array<double, kMax>, std::vector<double>>;
  using Flags = std::conditional_t<(M > 0), std::array<char, kMax>, std::vector<char>>;
  Acc bnorm{}, rz{}, rr{}, pq{}, alpha{}, beta{}, rz_new{};
  Flags active{};
  if constexpr (M == 0) {
    for (auto* v : {&bnorm, &rz, &rr, &pq, &alpha, &beta, &rz_new}) v->assign(m, 0.0);
    active.assign(m, 1);
  } else {
    active.fill(1);
  }
  const double* B = b.data();
  double* X = x.data();
  double* R = w.r.data();
  double* Z = w.z.data();
  double* P = w.p.data();
  double* Q = w.q.data();
  const double* Dinv = inv_diag.data();
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index c = 0; c < m; ++c) bnorm[c] += B[i * m + c] * B[i * m + c];
  for (Eigen::Index c = 0; c < m; ++c) bnorm[c] = std::sqrt(bnorm[c]);
  for (Eigen::Index c = 0; c < m; ++c)
    if (bnorm[c] == 0)
      for (Eigen::Index i = 0; i < n; ++i) X[i * m + c] = 0;  // exact solution of an SPD system
  apply(x, w.q);
  for (Eigen::Index c = 0; c < m; ++c) rz[c] = rr[c] = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index c = 0; c < m; ++c) {
      const Eigen::Index k = i * m + c;
      R[k] = B[k] - Q[k];
      Z[k] = Dinv[i] * R[k];
      P[k] = Z[k];
      rz[c] += R[k] * Z[k];
      rr[c] += R[k] * R[k];
    }
  auto update_active = [&]() {
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
      active[c] = rel > opt.tolerance;
      any |= active[c] != 0;
    }
    return any;
  };
  if (!update_active()) return res;
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
    for (Eigen::Index c = 0; c < m; ++c) pq[c] = 0;
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index c = 0; c < m; ++c) pq[c] += P[i * m + c] * Q[i * m + c];
    for (Eigen::Index c = 0; c < m; ++c) {
      if (!active[c]) {
        alpha[c] = 0;
        continue;
      }
      if (!(pq[c] > 0)) {
        res.status = CgStatus::Breakdown;
        res.message = fmt::format(
            "the system is not positive definite on the free vertices (p'Ap = {:.3g} in component {}); "
            "is there a connected part with no constrained vertex?",
            pq[c], c);
        return res;
      }
      alpha[c] = rz[c] / pq[c];
    }
    for (Eigen::Index c = 0; c < m; ++c) rr[c] = rz_new[c] = 0;
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index c = 0; c < m; ++c) {
        const Eigen::Index k = i * m + c;
        X[k] += alpha[c] * P[k];
        R[k] -= alpha[c] * Q[k];
        Z[k] = Dinv[i] * R[k];
        rr[c] += R[k] * R[k];
        rz_new[c] += R[k] * Z[k];
      }
    if (!update_active()) {
      if (res.status == CgStatus::Breakdown) return res;
      res.status = CgStatus::Converged;
      return res;
    }
    for (Eigen::Index c = 0; c < m; ++c) {
      beta[c] = active[c] ? rz_new[c] / rz[c] : 0.0;
      rz[c] = rz_new[c];
    }
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index c = 0; c < m; ++c) {
        const Eigen::Index k = i * m + c;
        P[k] = active[c] ? Z[k] + beta[c] * P[k] : 0.0;
      }
  }
  res.status = CgStatus::MaxIterations;
  res.message = fmt::format("no convergence in {} iterations (relative residual {:.3g} > {:.3g})", opt.max_iterations,
                            res.relative_residual, opt.tolerance);
  return res;
}

}  // namespace detail

/// Solves A x = b. `apply(P, Q)` must write Q = A P for n x m blocks; `inv_diag`
/// (length n) is the Jacobi preconditioner 1 / A_ii. `x` holds the initial guess.
template <class Apply>
CgResult pcg(Apply&& apply, const Eigen::VectorXd& inv_diag, const Field& b, Field& x, const CgOptions& opt,
             CgWorkspace& w) {
  switch (b.cols()) {
    case 1:
      return detail::pcg_impl<1>(apply, inv_diag, b, x, opt, w);
    case 3:
      return detail::pcg_impl<3>(apply, inv_diag, b, x, opt, w);
    default:
      return detail::pcg_impl<0>(apply, inv_diag, b, x, opt, w);
  }
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
  }
  return "unknown";
}

}  // namespace meshpde
