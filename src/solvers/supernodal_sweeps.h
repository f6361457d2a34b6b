// Triangular sweeps with a supernodal Cholesky factor L (A = P^T L L^T P), written out
// here instead of calling CHOLMOD's cholmod_solve. Internal to the solver layer.
//
// Why: cholmod_solve (CHOLMOD 3) makes one or two BLAS calls per supernode, and the
// factors of surface meshes have many small supernodes (167k for the 1.15M-vertex
// Laplacian), so the calls' overhead, not the memory traffic, sets its speed. Here the
// right-hand sides are interleaved (row-major, so one gather serves every column),
// each supernode's diagonal block is solved in place, and the rows below it are summed
// densely column by column and scattered once (gathered once going back). 164k-vertex
// Laplacian factor (9.9M nonzeros), three columns: 24 ms against 52 ms for
// cholmod_solve; K D K factor (27M): 66 against 90 ms (docs/solvers-measurements.md). From five
// columns on cholmod_solve's BLAS-3 calls are as fast, and SparseCholesky uses them.
//
// Both cores: after the supernodes are postordered, every subtree of the elimination
// tree is a contiguous range of supernodes. The sweeps take the first node of the
// tree's root chain with two or more children, split its children into two contiguous
// groups of about equal work, and sweep the groups on two threads. In the forward
// sweep a group's supernodes update rows of their own group and of the group's
// ancestors (all after both groups); the latter go to a per-thread buffer added in
// afterwards, so the result does not depend on the thread count. The backward sweep
// only reads ancestors, which are final before the groups start.
#pragma once

#include <Eigen/Core>
#include <cstddef>

namespace meshpde::detail {

/// A supernodal LL^T factor in CHOLMOD's layout (nothing copied): supernode k holds
/// columns super[k] .. super[k+1]-1; its row indices are s[pi[k] .. pi[k+1]) (its own
/// columns first, in order); its values are the nsrow x nscol column-major block at
/// x + px[k], the diagonal block's lower triangle on top. perm: row perm[i] of A is row
/// i of L.
struct SupernodalFactorView {
  Eigen::Index n = 0;
  Eigen::Index nsuper = 0;
  const int* super = nullptr;
  const int* pi = nullptr;
  const int* px = nullptr;
  const int* s = nullptr;
  const double* x = nullptr;
  const int* perm = nullptr;
};

class SupernodalSweeps {
 public:
  SupernodalSweeps() = default;
  /// Keeps the view (the factor must outlive this) and finds the two-thread split.
  explicit SupernodalSweeps(const SupernodalFactorView& L);
  bool empty() const { return L_.x == nullptr; }
  /// X = A^-1 B, B of n rows and one to four columns (SparseCholesky sends more to
  /// cholmod_solve, whose BLAS-3 calls are as fast there). \throw SolverError otherwise.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;
  /// Supernodes before `group_begin` and from `group_end` on run on one thread; the two
  /// groups [group_begin, split) and [split, group_end) on two (tests, docs).
  Eigen::Index group_begin() const { return group_begin_; }
  Eigen::Index split() const { return split_; }
  Eigen::Index group_end() const { return group_end_; }

 private:
  SupernodalFactorView L_;
  Eigen::Index group_begin_ = 0, split_ = 0, group_end_ = 0;
  double work_ = 0;  // nonzeros of L, to decide whether a second thread pays
};

}  // namespace meshpde::detail
