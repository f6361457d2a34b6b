// The CHOLMOD side of the direct solvers (solvers/direct.h), behind plain Eigen types so
// that only cholmod_factors.cpp includes CHOLMOD. Without CHOLMOD the build compiles
// cholmod_missing.cpp instead: cholmod_built() is false and the constructors throw, so
// direct.cpp asks cholmod_built() before it makes one. Internal to the solver layer.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

namespace meshpde::detail {

/// Whether meshpde was built with CHOLMOD.
bool cholmod_built();

/// CHOLMOD's supernodal LL^T with its own fill-reducing ordering (METIS or AMD): the
/// Cholmod backend of SparseCholesky. Sets the BLAS and OpenMP threads itself
/// (solver_threads.h).
class CholmodFactor {
 public:
  /// \throw SolverError without CHOLMOD.
  CholmodFactor();
  ~CholmodFactor();
  CholmodFactor(const CholmodFactor&) = delete;
  CholmodFactor& operator=(const CholmodFactor&) = delete;

  /// Symbolic analysis of A's pattern (compressed, symmetric, both triangles stored),
  /// in CHOLMOD's order, or in `order` (a permutation of A's rows, order[k] eliminated
  /// k-th) when given: then with coarser supernodes than CHOLMOD's unless
  /// coarse_supernodes is false. \throw SolverError if CHOLMOD rejects the order.
  void analyze(const Eigen::SparseMatrix<double>& A, const std::vector<int>* order = nullptr,
               bool coarse_supernodes = true);
  /// Numeric factorization with the last analysis. Returns false if A is not positive
  /// definite.
  bool factorize(const Eigen::SparseMatrix<double>& A);
  /// X = A^-1 B. With `written_out`, one to four columns go through meshpde's own
  /// sweeps (supernodal_sweeps.h), more through cholmod_solve. \pre B has the factor's
  /// row count (SparseCholesky::solve checks it).
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B, bool written_out) const;
  double nonzeros() const;     ///< nonzeros of L in the analysis in use
  double pivot_ratio() const;  ///< smallest over largest squared diagonal entry of L; 0 if unknown
  /// The analysis's fill-reducing order (CHOLMOD's, or the given one postordered):
  /// order[k] is the row eliminated k-th; empty before an analysis.
  std::vector<int> order() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// CHOLMOD's supernodal LL^T of a matrix in the order it is given (no fill-reducing
/// permutation, no postordering), with the sweeps and the trailing block the
/// leading-block and split factors need. The caller sets the BLAS and OpenMP threads.
class CholmodInOrder {
 public:
  /// \throw SolverError without CHOLMOD.
  CholmodInOrder();
  ~CholmodInOrder();
  CholmodInOrder(const CholmodInOrder&) = delete;
  CholmodInOrder& operator=(const CholmodInOrder&) = delete;

  /// Analyzes and factors A (compressed, symmetric; the lower triangle is read).
  /// Returns false if A is not positive definite. \throw SolverError if the analysis
  /// fails or reorders A.
  bool factorize(const Eigen::SparseMatrix<double>& A);
  void forward(Eigen::MatrixXd& Y);   ///< Y = L^-1 Y, all columns in one sweep
  void backward(Eigen::MatrixXd& Y);  ///< Y = L^-T Y
  /// The trailing s x s block of L (lower triangular, dense).
  Eigen::MatrixXd trailing_block(Eigen::Index s) const;
  double nonzeros() const;  ///< nonzeros of L

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The lower triangle of C C^T for a lower triangular C (its upper part zero); the
/// strict upper triangle of the result is not meant to be read. With the BLAS CHOLMOD
/// links, dsyrk: for the 225-row separator of the bench's 10k drag region 0.3 ms
/// against 1.0 ms for Eigen's triangular product (compiled for any x86-64, where
/// OpenBLAS picks its kernels for the machine it runs on).
Eigen::MatrixXd lower_gram(const Eigen::MatrixXd& C);

}  // namespace meshpde::detail
