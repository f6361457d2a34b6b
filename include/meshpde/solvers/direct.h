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

/// Sparse Cholesky factor of A in the order A is given: no fill-reducing reordering and
/// no postordering, so the factor of every leading block A(0:n, 0:n) is the leading
/// n x n block of L, and solve_leading() solves with any of them. The caller orders A:
/// the rows always in use first (in a fill-reducing order), rows that may be dropped
/// last. Used by local drags, whose region can shrink or grow by a ring without a new
/// factor (apps/local_drag.h).
///
/// Backend: CHOLMOD's supernodal LL^T when meshpde was built with it (Auto, Cholmod),
/// else Eigen's simplicial LL^T. Every call makes a new analysis: the pattern of a drag
/// region changes whenever the region does.
class LeadingBlockCholesky {
 public:
  /// \throw SolverError when Cholmod is asked for but meshpde was built without it.
  explicit LeadingBlockCholesky(SparseCholesky::Backend backend = SparseCholesky::Backend::Auto);
  ~LeadingBlockCholesky();
  LeadingBlockCholesky(LeadingBlockCholesky&&) noexcept;
  LeadingBlockCholesky& operator=(LeadingBlockCholesky&&) noexcept;

  /// Factors A (symmetric; both triangles stored, the lower one is read).
  /// \throw SolverError (in words) if A is not square, not finite or not positive definite.
  void factorize(const Eigen::SparseMatrix<double>& A);
  /// X = A(0:n, 0:n)^-1 B for n = B.rows() <= size(): a forward sweep with L, the rows
  /// beyond n zeroed, a backward sweep with L^T. \pre factorize() succeeded.
  Eigen::MatrixXd solve_leading(const Eigen::MatrixXd& B) const;

  Eigen::Index size() const { return size_; }  ///< rows of the factored matrix
  const char* backend_name() const;
  double factor_nonzeros() const;  ///< nonzeros of L (about 12 bytes each)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Eigen::Index size_ = 0;
};

}  // namespace meshpde
