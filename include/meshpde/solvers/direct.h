// Sparse Cholesky factorization for symmetric positive definite systems.
//
// Backend: CHOLMOD (SuiteSparse, supernodal; the fill-reducing ordering given by the
// caller, or CHOLMOD's choice of METIS or AMD) when meshpde was built with it, else Eigen's simplicial
// LDL^T with AMD ordering. The symbolic analysis is kept: factorize() with a matrix of
// the same pattern only redoes the numeric part, and one factor serves any number of
// right-hand sides (x, y, z of a displacement, several frames).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <memory>
#include <string>
#include <vector>

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
  /// \throw SolverError if B's row count is not the factor's.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;

  /// How solve() sweeps a CHOLMOD factor. WrittenOut (the default): meshpde's own loops
  /// over the supernodes, the right-hand sides interleaved, two subtrees of the
  /// elimination tree on two threads for large factors, one to four
  /// columns (more go to cholmod_solve); 1.5-2x faster than cholmod_solve on surface
  /// meshes (docs/solvers-measurements.md). Cholmod: cholmod_solve, the
  /// baseline the bench compares with. Both give the same answer to rounding; the
  /// Eigen backend ignores this.
  enum class Sweeps { WrittenOut, Cholmod };
  void set_sweeps(Sweeps sweeps);
  /// The fill-reducing order of the next analyses: order[k] is the row eliminated k-th
  /// (a permutation of 0..n-1, e.g. mesh_nested_dissection of the rows' vertices);
  /// empty (the default): CHOLMOD chooses (AMD, METIS when AMD's fill is high). A
  /// changed order makes the next factorize() analyze afresh; the same order and
  /// pattern are analyzed once. With the order's top level given (its first part1
  /// rows and next part2 rows uncoupled, the rest their separator), the CHOLMOD
  /// backend factors the two parts on two threads (SplitCholesky below; every
  /// factorize() then analyzes, and pivot_ratio() is 0). One CHOLMOD factor in a given
  /// order has coarser supernodes than CHOLMOD's default (a faster factorization, slower
  /// sweeps: docs/solvers-measurements.md) unless coarse_supernodes is false. The Eigen backend
  /// ignores all of it (AMD). \throw SolverError if order is not a permutation or the
  /// parts leave no separator; factorize() throws when its size is not the matrix's.
  void set_order(std::vector<int> order, std::size_t part1 = 0, std::size_t part2 = 0, bool coarse_supernodes = true);

  const char* backend_name() const;
  /// The fill-reducing order of the last analysis, order[k] the row eliminated k-th:
  /// CHOLMOD's choice, or the given order (as CHOLMOD postordered it; as given for a
  /// split factor); empty before a factorization and for the Eigen backend.
  std::vector<int> order() const;
  /// The given order's two top-level parts when the last factor was split in them
  /// (CHOLMOD backend), else {0, 0}.
  std::array<std::size_t, 2> split_parts() const;
  /// Nonzeros of the factor L of the last factorization (memory: about 12 bytes each).
  double factor_nonzeros() const;
  /// Smallest over largest pivot of the last factorization (D of LDL^T, the squared
  /// diagonal of L for LL^T), in (0, 1]: a singular matrix can factor with a pivot
  /// that rounding left tiny and positive, which this shows (about 1e-16 and below).
  /// 0 before a successful factorize().
  double pivot_ratio() const;
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
/// Backend: CHOLMOD's supernodal LL^T when meshpde was built with it (Cholmod; Auto from
/// 700 unknowns, as SparseCholesky), else Eigen's simplicial LL^T. Every factorize()
/// makes a new analysis: the pattern of a drag region changes whenever the region does.
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

/// Cholesky factor of a matrix whose rows fall into two uncoupled parts and a separator
/// (the top level of a nested dissection), in that order:
///
///     A = [A11 0 A1S; 0 A22 A2S; AS1 AS2 ASS]   (part 1, part 2, separator),
///
/// factored on two threads. CHOLMOD factors M1 = A on (part 1, separator) and M2 = A on
/// (part 2, separator) at the same time, each in the order given. The trailing blocks
/// C1, C2 of their factors satisfy C_i C_i^T = ASS - AS_i A_ii^-1 A_iS, so the
/// separator's Schur complement is C1 C1^T + C2 C2^T - ASS, a small dense matrix
/// (about 2 sqrt(n) rows for a disc of K D K) factored by Eigen. A solve sweeps the two
/// parts' factors at the same time and joins them through the separator. Each part
/// repeats the separator's rows, so the gain is short of 2x: on the 10k-vertex drag
/// region 11-13 ms against 15 ms for one CHOLMOD factor of all of A (docs/solvers-measurements.md).
/// Needs CHOLMOD (available()).
class SplitCholesky {
 public:
  SplitCholesky();
  ~SplitCholesky();
  SplitCholesky(SplitCholesky&&) noexcept;
  SplitCholesky& operator=(SplitCholesky&&) noexcept;

  /// Whether meshpde was built with CHOLMOD (which this factor needs).
  static bool available() { return SparseCholesky::cholmod_available(); }

  /// Factors A (symmetric; its lower triangle is read) whose first `part1` rows and next
  /// `part2` rows are not coupled. \throw SolverError (in words) if CHOLMOD is missing,
  /// the sizes do not leave a separator, the parts are coupled, or A is not finite or
  /// not positive definite.
  void factorize(const Eigen::SparseMatrix<double>& A, Eigen::Index part1, Eigen::Index part2);
  /// The same for A in its own numbering, eliminated in `order` (order[k]: the row of A
  /// eliminated k-th; its first part1 rows and next part2 rows the uncoupled parts),
  /// without a permuted copy of A: each part's matrix is gathered from A directly (its
  /// lower triangle). solve() then takes and returns rows in the order's numbering.
  /// \throw SolverError as above, or if order is not a permutation of A's rows.
  void factorize(const Eigen::SparseMatrix<double>& A, const std::vector<int>& order, Eigen::Index part1,
                 Eigen::Index part2);
  /// X = A^-1 B (B has size() rows). \pre factorize() succeeded.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;

  Eigen::Index size() const { return size_; }
  double factor_nonzeros() const;  ///< both parts' factors and the dense separator block

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Eigen::Index size_ = 0;
};

}  // namespace meshpde
