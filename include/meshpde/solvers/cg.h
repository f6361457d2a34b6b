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
#include <cmath>
#include <string>
#include <vector>

namespace meshpde {

using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct CgOptions {
  double tolerance = 1e-8;     ///< relative residual |b - A x| / |b| per column
  int max_iterations = 20000;  ///< iteration cap
};

enum class CgStatus { Converged, MaxIterations, Breakdown };

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
  Block r, z, p, q;
};

/// Solves A x = b. `apply(P, Q)` must write Q = A P for n x m blocks; `inv_diag`
/// (length n) is the Jacobi preconditioner 1 / A_ii. `x` holds the initial guess.
template <class Apply>
CgResult pcg(Apply&& apply, const Eigen::VectorXd& inv_diag, const Block& b, Block& x, const CgOptions& opt,
             CgWorkspace& w) {
  const Eigen::Index n = b.rows(), m = b.cols();
  CgResult res;
  if (n == 0) return res;
  Eigen::VectorXd bnorm = b.colwise().norm().transpose();
  w.r.resize(n, m);
  w.z.resize(n, m);
  w.p.resize(n, m);
  w.q.resize(n, m);
  for (Eigen::Index c = 0; c < m; ++c)
    if (bnorm[c] == 0) x.col(c).setZero();  // exact solution of an SPD system
  apply(x, w.q);
  w.r = b - w.q;
  w.z = inv_diag.asDiagonal() * w.r;
  w.p = w.z;
  Eigen::VectorXd rz = (w.r.cwiseProduct(w.z)).colwise().sum().transpose();
  std::vector<char> active(m);
  auto residual = [&](Eigen::Index c) { return bnorm[c] > 0 ? w.r.col(c).norm() / bnorm[c] : 0.0; };
  auto update_active = [&]() {
    bool any = false;
    res.relative_residual = 0;
    for (Eigen::Index c = 0; c < m; ++c) {
      const double rr = residual(c);
      if (!std::isfinite(rr)) {
        res.status = CgStatus::Breakdown;
        res.message = "the residual became NaN or infinite (non-finite input or operator)";
        return false;
      }
      res.relative_residual = std::max(res.relative_residual, rr);
      active[c] = rr > opt.tolerance;
      any |= active[c] != 0;
    }
    return any;
  };
  if (!update_active()) return res;
  for (int it = 0; it < opt.max_iterations; ++it) {
    apply(w.p, w.q);
    res.iterations = it + 1;
    for (Eigen::Index c = 0; c < m; ++c) {
      if (!active[c]) continue;
      const double pq = w.p.col(c).dot(w.q.col(c));
      if (!(pq > 0)) {
        res.status = CgStatus::Breakdown;
        res.message = fmt::format(
            "the system is not positive definite on the free vertices (p'Ap = {:.3g} in component {}); "
            "is there a connected part with no constrained vertex?",
            pq, c);
        return res;
      }
      const double alpha = rz[c] / pq;
      x.col(c) += alpha * w.p.col(c);
      w.r.col(c) -= alpha * w.q.col(c);
    }
    if (!update_active()) {
      if (res.status == CgStatus::Breakdown) return res;
      res.status = CgStatus::Converged;
      return res;
    }
    for (Eigen::Index c = 0; c < m; ++c) {
      if (!active[c]) continue;
      w.z.col(c) = inv_diag.cwiseProduct(w.r.col(c));
      const double rz_new = w.r.col(c).dot(w.z.col(c));
      const double beta = rz_new / rz[c];
      rz[c] = rz_new;
      w.p.col(c) = w.z.col(c) + beta * w.p.col(c);
    }
    for (Eigen::Index c = 0; c < m; ++c)
      if (!active[c]) w.p.col(c).setZero();
  }
  res.status = CgStatus::MaxIterations;
  res.message = fmt::format("no convergence in {} iterations (relative residual {:.3g} > {:.3g})", opt.max_iterations,
                            res.relative_residual, opt.tolerance);
  return res;
}

inline const char* to_string(CgStatus s) {
  switch (s) {
    case CgStatus::Converged:
      return "converged";
    case CgStatus::MaxIterations:
      return "max_iterations";
    case CgStatus::Breakdown:
      return "breakdown";
  }
  return "unknown";
}

}  // namespace meshpde
