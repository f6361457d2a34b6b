// Sparse Cholesky factorization for symmetric positive definite systems.
//
// Backend: CHOLMOD (SuiteSparse, supernodal; CHOLMOD chooses the fill-reducing
// ordering, METIS or AMD) when meshpde was built with it, else Eigen's simplicial
// LDL^T with AMD ordering. The symbolic analysis is kept: factorize() with a matrix of
// the same pattern only redoes the numeric part, and one factor serves any number of
// right-hand sides (x, y, z of a displacement, several frames).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <string>

namespace meshpde {

class SparseCholesky {
 public:
  enum class Backend { Auto, Cholmod, Eigen };

  /// \throw SolverError when Cholmod is asked for but meshpde was built without it.
  explicit SparseCholesky(Backend backend = Backend::Auto);
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;

  /// Analyzes A's pattern if it is new, then factors its values.
  /// \throw SolverError (in words) if A is not square, not finite, or not positive definite.
  void factorize(const Eigen::SparseMatrix<double>& A);
  /// X = A^-1 B for one or more columns. \pre factorize() succeeded.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;

  const char* backend_name() const;
  /// Nonzeros of the factor L of the last factorization (memory: about 12 bytes each).
  double factor_nonzeros() const;
  int analyses() const { return analyses_; }       ///< symbolic analyses performed
  int factorizations() const { return factors_; }  ///< numeric factorizations performed
  static bool cholmod_available();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int analyses_ = 0, factors_ = 0;
};

}  // namespace meshpde
