// Smoothed-aggregation algebraic multigrid (Vanek, Mandel and Brezina 1996) for
// symmetric positive definite Laplacian-like systems, used as a preconditioner.
//
// One V-cycle z = V(r) approximates A^-1 r at the cost of a few sparse products per
// level (each level has about a sixth of the unknowns of the one above), so its cost
// and memory grow linearly with the mesh, where a Cholesky factor of a surface
// Laplacian grows like n^1.3 in memory and n^1.5 in time. V is symmetric and positive
// definite (Chebyshev smoothing, the same polynomial before and after the coarse
// correction), so it can precondition CG.
//
// Levels: aggregates of strongly connected unknowns (|a_ij| >= theta sqrt(a_ii a_jj)),
// a piecewise-constant tentative prolongator (the near-nullspace of a Laplacian is the
// constant) smoothed by one damped Jacobi step, Galerkin coarse matrices P^T A P, and a
// sparse Cholesky factorization at the coarsest level. Written here because Debian
// packages no algebraic multigrid library that does not bring MPI along (hypre,
// PETSc, Trilinos).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

namespace meshpde {

struct MultigridOptions {
  double strength_threshold = 0.08;  ///< theta of the strong-connection test
  int coarse_size = 1500;            ///< below this many unknowns: a direct solve
  int max_levels = 25;
  int smoother_degree = 2;  ///< Chebyshev polynomial degree of each pre- and post-smoothing
  /// Chebyshev smoothing targets the eigenvalues of D^-1 A in [lambda_max / ratio, lambda_max].
  double smoother_ratio = 4;
};

class AlgebraicMultigrid {
 public:
  /// Builds the hierarchy of A (square, symmetric positive definite; only its values
  /// are read, both triangles). \throw SolverError if A is not square, has a
  /// non-positive diagonal entry, or its coarsest level cannot be factored.
  explicit AlgebraicMultigrid(const Eigen::SparseMatrix<double>& A, const MultigridOptions& options = {});
  ~AlgebraicMultigrid();
  AlgebraicMultigrid(AlgebraicMultigrid&&) noexcept;
  AlgebraicMultigrid& operator=(AlgebraicMultigrid&&) noexcept;

  /// One V-cycle from a zero initial guess for every column of R: Z ~ A^-1 R.
  Eigen::MatrixXd apply(const Eigen::MatrixXd& R) const;

  int levels() const;
  std::vector<Eigen::Index> level_sizes() const;  ///< unknowns per level, finest first
  /// Nonzeros of all level matrices over those of A (memory and work of a V-cycle
  /// relative to one product with A; about 1.3-1.6 for surface Laplacians).
  double operator_complexity() const;
  std::size_t bytes() const;  ///< memory held by the hierarchy

 private:
  struct Level;
  std::vector<Level> levels_;
  struct Coarse;
  std::unique_ptr<Coarse> coarse_;
  MultigridOptions options_;
  Eigen::MatrixXd cycle(std::size_t level, const Eigen::MatrixXd& b) const;
};

}  // namespace meshpde
