// Iterative refinement of a direct solve: x += A^-1 (b - A x) while the relative
// residual exceeds a tolerance and keeps falling. On badly shaped meshes K D K is
// ill-conditioned enough that one pair of triangular sweeps leaves a visible residual;
// each step costs one product with A and one solve and shrinks it by about cond * eps.
// A step is also skipped when the answer is already backward stable to working
// precision (normwise backward error <= 16 eps, the level a Cholesky solve reaches on
// a well-conditioned system): refining further changes x by less than its own
// rounding, at the price of a whole solve (LAPACK's xPORFS stops at eps likewise).
// Used by SteadyDirectSolver (CHOLMOD or Eigen factors) and DragSession (leading-block
// solves).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <limits>

namespace meshpde {

struct RefinedSolve {
  Eigen::MatrixXd x;             ///< the refined answer
  Eigen::MatrixXd residual;      ///< b - A x for that answer
  double relative_residual = 0;  ///< worst column of |b - A x| / |b|
  double backward_error = 0;     ///< worst column of |b - A x|_inf / (|A|_inf |x|_inf + |b|_inf)
  int steps = 0;                 ///< refinement steps taken (the last may have been rejected)
};

/// Normwise backward error below which refinement stops (Rigal and Gaches' measure).
inline constexpr double kStableBackwardError = 16 * std::numeric_limits<double>::epsilon();

/// solve(R) applies A^-1 to the columns of R, multiply(X) applies A, a_norm_inf is
/// |A|_inf. At most max_steps steps; a step that does not lower the residual is
/// rejected and ends it.
template <class Solve, class Multiply>
RefinedSolve refined_solve(const Eigen::MatrixXd& b, Solve&& solve, Multiply&& multiply, double a_norm_inf,
                           double tolerance, int max_steps) {
  auto measure = [&](RefinedSolve& s) {
    s.relative_residual = s.backward_error = 0;
    if (b.rows() == 0) return;  // no unknowns (a correction whose region is its handles): nothing to measure
    for (Eigen::Index c = 0; c < b.cols(); ++c) {
      if (const double bn = b.col(c).norm(); bn > 0)
        s.relative_residual = std::max(s.relative_residual, s.residual.col(c).norm() / bn);
      const double den = a_norm_inf * s.x.col(c).cwiseAbs().maxCoeff() + b.col(c).cwiseAbs().maxCoeff();
      if (den > 0) s.backward_error = std::max(s.backward_error, s.residual.col(c).cwiseAbs().maxCoeff() / den);
    }
  };
  RefinedSolve out;
  out.x = solve(b);
  out.residual = b - multiply(out.x);
  measure(out);
  while (out.relative_residual > tolerance && out.backward_error > kStableBackwardError && out.steps < max_steps) {
    RefinedSolve next;
    next.x = out.x + solve(out.residual);
    next.residual = b - multiply(next.x);
    measure(next);
    next.steps = ++out.steps;
    if (!(next.relative_residual < out.relative_residual)) break;  // stagnated: keep the better iterate
    out = std::move(next);
  }
  return out;
}

}  // namespace meshpde
