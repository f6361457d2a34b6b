// Iterative refinement of a direct solve: x += A^-1 (b - A x) while the relative
// residual exceeds a tolerance and keeps falling. On badly shaped meshes K D K is
// ill-conditioned enough that one pair of triangular sweeps leaves a visible residual;
// each step costs one product with A and one solve and shrinks it by about cond * eps.
// A step is also skipped when the answer is already backward stable to working
// precision (normwise backward error <= 16 eps, the level a Cholesky solve reaches on
// a well-conditioned system): refining further changes x by less than its own
// rounding, at the price of a whole solve (LAPACK's xPORFS stops at eps likewise).
// That holds where `multiply` is the matrix that was factored (DragSession's
// leading-block solves).
//
// pcg_refined_solve is the variant for a factor of an approximation of A: the assembled
// K D K, whose entries carry rounding of about eps |K|^T D |K| (large on meshes with
// slivers, where D = 1/mass is), while `multiply` applies A as the products it is made
// of. There the first answer is backward stable for the assembled matrix and still off
// (1.4e-6 relative on the camel head, against an extended-precision solve), and the
// plain step above can stall, as it contracts only by |I - A_^-1 A|; CG preconditioned
// by the factor, started from the first answer, does not (SteadyDirectSolver; test
// GlobalBilaplacian.EveryRealMeshInTheCoreFormatsMatchesTheDirectSolve).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <limits>

#include "meshpde/solvers/cg.h"

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

namespace detail {
// The relative residual and the normwise backward error of s (worst column).
inline void measure_refined(const Eigen::MatrixXd& b, double a_norm_inf, RefinedSolve& s) {
  s.relative_residual = s.backward_error = 0;
  if (b.rows() == 0) return;  // no unknowns (a correction whose region is its handles): nothing to measure
  for (Eigen::Index c = 0; c < b.cols(); ++c) {
    if (const double bn = b.col(c).norm(); bn > 0)
      s.relative_residual = std::max(s.relative_residual, s.residual.col(c).norm() / bn);
    const double den = a_norm_inf * s.x.col(c).cwiseAbs().maxCoeff() + b.col(c).cwiseAbs().maxCoeff();
    if (den > 0) s.backward_error = std::max(s.backward_error, s.residual.col(c).cwiseAbs().maxCoeff() / den);
  }
}
}  // namespace detail

/// solve(R) applies A^-1 to the columns of R, multiply(X) applies A, a_norm_inf is
/// |A|_inf. At most max_steps steps; a step that does not lower the residual is
/// rejected and ends it.
template <class Solve, class Multiply>
RefinedSolve refined_solve(const Eigen::MatrixXd& b, Solve&& solve, Multiply&& multiply, double a_norm_inf,
                           double tolerance, int max_steps) {
  auto measure = [&](RefinedSolve& s) { detail::measure_refined(b, a_norm_inf, s); };
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

/// CG on A x = b preconditioned by solve() (a factor of an approximation of A), started
/// from solve(b), each column on its own (block_pcg, solvers/cg.h): at most max_steps
/// steps (one solve and one product each, for all columns at once), until every
/// column's recurrence residual is at most `tolerance` relative to its b. The answer
/// is the last iterate: its true
/// residual, measured at the end as refined_solve measures, can stay above the
/// recurrence's, at the rounding of the product b - A x itself (5e-12 relative on the
/// aorta, whose answer CG still moves from 6.7e-9 to 7e-13 off an extended-precision
/// solve), so it cannot choose between iterates. `steps` counts the CG steps taken.
template <class Solve, class Multiply>
RefinedSolve pcg_refined_solve(const Eigen::MatrixXd& b, Solve&& solve, Multiply&& multiply, double a_norm_inf,
                               double tolerance, int max_steps) {
  RefinedSolve out;
  out.x = solve(b);
  out.residual = b - multiply(out.x);
  detail::measure_refined(b, a_norm_inf, out);
  if (out.relative_residual <= tolerance || max_steps <= 0) return out;
  CgOptions options;
  options.tolerance = tolerance;
  options.max_iterations = max_steps;
  options.residual_given = true;
  CgWorkspace w;
  w.r = out.residual;
  Field x = out.x;
  const CgResult cg =
      block_pcg([&](const Field& P, Field& Q) { Q = multiply(Eigen::MatrixXd(P)); },
                [&](const Field& R, Field& Z) { Z = solve(Eigen::MatrixXd(R)); }, Field(b), x, options, w);
  out.steps = cg.iterations;
  out.x = x;
  out.residual = b - multiply(out.x);
  detail::measure_refined(b, a_norm_inf, out);
  return out;
}

}  // namespace meshpde
