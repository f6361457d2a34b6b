// Geometric surface multigrid for the steady bi-Laplacian
//
//     A = g1 K_FF + g2 (K D K)_FF          (#F x #F, SPD once a vertex is held)
//
// on the free vertices F of a mesh (everything else held), used as a preconditioner:
// one symmetric W-cycle per conjugate-gradient iteration (block_pcg, solvers/cg.h).
// Units follow K and D (fem_operators.h): A has units length^-2 for g2 = 1.
//
// A fourth-order operator needs coarse spaces with linear precision (O(h^2)
// interpolation), which piecewise-constant algebraic aggregation lacks; this hierarchy
// has it by construction (Wiersma et al., "A fast geometric multigrid method for curved
// surfaces", SIGGRAPH 2023):
//
//   - coarse vertices: a maximal independent set of the level's graph (about 1 in 4);
//     every other vertex belongs to its nearest adjacent coarse vertex, and two coarse
//     vertices are neighbours when their cells touch;
//   - prolongation: barycentric coordinates of a fine vertex's projection onto the
//     tangent plane of its cell's coarse vertex, in the fan of that vertex's coarse
//     neighbours (outside the fan: the smallest weights that reproduce constants and
//     the tangent plane's linear functions), so linear functions are reproduced;
//   - held vertices stay in the hierarchy as coarse vertices of value zero;
//   - Galerkin coarse operators (A_1 = (K P)^T (g2 D) (K P) + g1 P^T K P, then
//     A_{l+1} = P^T A_l P): every level is SPD and the cycle an SPD preconditioner;
//   - smoothing: Chebyshev polynomials in the Jacobi-scaled operator on
//     [lambda_max / smoothing_range, lambda_max] (lambda_max by Lanczos, times 1.1),
//     or symmetric Gauss-Seidel;
//   - W-cycles (a V-cycle's iteration count grows with the number of levels on a
//     fourth-order problem);
//   - the coarsest level (at most coarsest_unknowns) is solved by sparse Cholesky.
//
// The finest level is applied as two sparse products with K on the free vertices and
// their one-ring (nothing of K D K is assembled there), on every thread above 20k
// rows. Cost and memory follow the free set, not the mesh.
//
// On well-shaped meshes the iteration count stays flat under refinement; on real
// scanned and modelled meshes with slivers and obtuse triangles it does not (the
// coarse spaces miss low-energy modes there), which is why the global solver's Auto
// watches the rate and hands such meshes on to the Laplacian factor
// (pde/global_bilaplacian.h). Figures and what was tried:
// docs/solvers-measurements.md, "A geometric surface multigrid".
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

struct SurfaceMultigridParams {
  /// Stop coarsening at or below this many unknowns and solve that level by sparse
  /// Cholesky (SparseCholesky: CHOLMOD with meshpde's own sweeps). 0 (the default):
  /// default_coarsest_unknowns(). A problem of at most this size gets no coarse levels:
  /// its operator is assembled and factored, and CG converges in one iteration.
  int coarsest_unknowns = 0;
  /// 12,000 when meshpde has CHOLMOD (a factor of that size costs about as much as one
  /// more level's set-up and solves faster than cycling through three more levels),
  /// else 2,000 (Eigen's simplicial factor is several times slower).
  static int default_coarsest_unknowns();
  int max_levels = 20;              ///< at most this many levels (the finest included)
  int smoothing_degree = 2;         ///< Chebyshev degree of each pre- and post-smoothing (coarse levels)
  int finest_smoothing_degree = 1;  ///< the same on the finest level (each degree costs one apply there)
  int cycle_index = 2;              ///< coarse corrections per level: 1 V-cycle, 2 W-cycle
  double smoothing_range = 6;       ///< Chebyshev interval [lambda_max / range, lambda_max]
  /// GaussSeidel: symmetric Gauss-Seidel (a forward sweep before the coarse correction,
  /// a backward one after, `smoothing_degree` sweeps each), on one core, with the finest
  /// level assembled; robust on meshes with obtuse and sliver triangles.
  /// Chebyshev: polynomial smoothing (matrix-free on the finest level, both cores).
  enum class Smoother { Chebyshev, GaussSeidel };
  Smoother smoother = Smoother::Chebyshev;
};

struct MultigridSolveResult {
  int iterations = 0;
  double relative_residual = 0;  ///< worst column, |b - A x| / |b|
  bool converged = false;
};

class BilaplacianMultigrid {
 public:
  /// Builds the hierarchy for A = g1 K_FF + g2 (K D K)_FF on the listed free vertices.
  /// \throw InputError for an invalid or repeated free vertex, g2 <= 0 or g1 < 0;
  ///        SolverError if the coarsest level is not positive definite (a part of the
  ///        free set that touches no held vertex).
  BilaplacianMultigrid(const Mesh& mesh, const FemOperators& ops, std::span<const int> free, double g1, double g2,
                       const SurfaceMultigridParams& params = {});
  ~BilaplacianMultigrid();
  BilaplacianMultigrid(BilaplacianMultigrid&&) noexcept;
  BilaplacianMultigrid& operator=(BilaplacianMultigrid&&) noexcept;

  /// Number of free vertices (rows of A); blocks are indexed in the order of `free`.
  int unknowns() const;
  /// Y = A X for an unknowns() x m block (row-major).
  void apply(const Field& X, Field& Y) const;
  /// Z = B R, one cycle (W by default; B approximates A^-1, symmetric positive definite).
  void precondition(const Field& R, Field& Z) const;
  /// Conjugate gradient on A X = B preconditioned by the cycle, from the given X
  /// (every column its own step lengths, one apply and one cycle for all columns).
  /// `keep_going(iterations, relative_residual)`, when given, is called with the
  /// starting residual (iterations 0) and after every iteration that has not converged;
  /// returning false stops the solve there (X holds the iterate, `converged` is false).
  MultigridSolveResult solve(const Field& B, Field& X, double tolerance, int max_iterations = 500,
                             const std::function<bool(int, double)>& keep_going = {}) const;

  /// Free unknowns on each level, finest first.
  std::vector<int> level_unknowns() const;
  /// Bytes held by the hierarchy (matrices, prolongations, the coarsest factor, the
  /// cycle's work blocks for `columns` right-hand sides).
  double bytes(int columns = 3) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace meshpde
