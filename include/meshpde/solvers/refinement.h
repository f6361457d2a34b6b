// Iterative refinement of a direct solve: x += A^-1 (b - A x) while the relative
// residual exceeds a tolerance and keeps falling. On badly shaped meshes K D K is
// ill-conditioned enough that one pair of triangular sweeps leaves a visible residual;
// each step costs one product with A and one solve and shrinks it by about cond * eps.
// Used by SteadyDirectSolver (CHOLMOD or Eigen factors) and DragSession (leading-block
// solves).
#pragma once

#include <Eigen/Core>
#include <algorithm>

namespace meshpde {

struct RefinedSolve {
  Eigen::MatrixXd x;             ///< the refined answer
  Eigen::MatrixXd residual;      ///< b - A x for that answer
  double relative_residual = 0;  ///< worst column of |b - A x| / |b|
  int steps = 0;                 ///< refinement steps taken (the last may have been rejected)
};

/// solve(R) applies A^-1 to the columns of R, multiply(X) applies A. At most
/// max_steps steps; a step that does not lower the residual is rejected and ends it.
template <class Solve, class Multiply>
RefinedSolve refined_solve(const Eigen::MatrixXd& b, Solve&& solve, Multiply&& multiply, double tolerance,
                           int max_steps) {
  auto worst = [&](const Eigen::MatrixXd& r) {
    double w = 0;
    for (Eigen::Index c = 0; c < b.cols(); ++c)
      if (const double bn = b.col(c).norm(); bn > 0) w = std::max(w, r.col(c).norm() / bn);
    return w;
  };
  RefinedSolve out;
  out.x = solve(b);
  out.residual = b - multiply(out.x);
  out.relative_residual = worst(out.residual);
  while (out.relative_residual > tolerance && out.steps < max_steps) {
    Eigen::MatrixXd x_new = out.x + solve(out.residual);
    Eigen::MatrixXd r_new = b - multiply(x_new);
    const double res_new = worst(r_new);
    ++out.steps;
    if (!(res_new < out.relative_residual)) break;  // stagnated: keep the better iterate
    out.x = std::move(x_new);
    out.residual = std::move(r_new);
    out.relative_residual = res_new;
  }
  return out;
}

}  // namespace meshpde
