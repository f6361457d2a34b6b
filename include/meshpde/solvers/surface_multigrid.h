// Geometric surface multigrid for the steady bi-Laplacian
//
//     A = g1 K_FF + g2 (K D K)_FF          (#F x #F, SPD once a vertex is held)
//
// on the free vertices F of a mesh (everything else held at zero for the correction),
// used as a preconditioner: one symmetric W-cycle per conjugate-gradient iteration.
// Units follow K and D (fem_operators.h): A has units length^-2 for g2 = 1.
//
// Why geometric and not the algebraic multigrid of a Laplacian: an approximate K^-1
// squared around M (the Laplacian-squared preconditioner of global_bilaplacian.h) is
// not spectrally equivalent to the exact one, and smoothed aggregation on K D K builds
// its coarse spaces from piecewise constants, which approximate nothing in the
// bi-Laplacian's energy. Coarse spaces need linear precision (O(h^2) interpolation)
// for a fourth-order operator; this hierarchy has it by construction (Wiersma et al.,
// "A fast geometric multigrid method for curved surfaces", SIGGRAPH 2023, Gravo MG):
//
//   - coarse vertices: a maximal independent set of the level's graph (about 1 in 4);
//   - every other vertex belongs to its nearest adjacent coarse vertex (a Voronoi-like
//     cell); two coarse vertices are neighbours when their cells touch;
//   - prolongation: a fine vertex takes the barycentric coordinates of its projection
//     onto the tangent plane of its cell's coarse vertex c, in the triangle of c and
//     two angularly consecutive coarse neighbours that contains it; outside every
//     triangle of that fan (beyond a far edge, on an open side at a boundary) the
//     smallest weights over the whole fan that reproduce constants and the tangent
//     plane's linear functions. Linear functions of the tangent plane are reproduced
//     exactly, constants everywhere;
//   - held vertices stay in the hierarchy as coarse vertices of value zero (their
//     columns are dropped), so interpolation decays to the held region as the error
//     does;
//   - coarse operators are Galerkin: A_1 = (K P)^T (g2 D) (K P) + g1 P^T K P, then
//     A_{l+1} = P^T A_l P, so every level is SPD and the cycle is a symmetric
//     positive definite preconditioner;
//   - smoothing (Smoother::Chebyshev, the default): Chebyshev polynomials in D_A^-1 A (Jacobi-scaled) on
//     [lambda_max / smoothing_range, lambda_max], the same polynomial before and after
//     the coarse correction; lambda_max by eight Lanczos steps (times 1.1: a power
//     iteration's low estimate made the smoother amplify the top modes and CG stall);
//     or (Smoother::GaussSeidel) symmetric Gauss-Seidel on assembled rows;
//   - W-cycle (cycle_index 2): each coarse level is corrected twice. With V-cycles the
//     iteration count grew with the number of levels (22, 31, 43 at 10k, 41k, 164k;
//     a two-grid stays at 16-17, so the coarse spaces are right and the V-cycle is
//     what degrades, as it does for fourth-order problems), with W-cycles 17, 18, 19;
//   - the coarsest level (at most coarsest_unknowns, 12,000 by default with CHOLMOD) is
//     solved by sparse Cholesky (SparseCholesky: CHOLMOD and meshpde's own sweeps). A
//     coarse level that large costs one factorization (about 40 ms at 10k unknowns)
//     and replaces the W-cycle's deepest, most often visited levels by one exact solve:
//     at 164k (levels of 162k, 41k, 10k) 16 iterations of about 21 ms, where a
//     coarsest level of 2,000 (five levels) needed 19 of about 24 ms; at 655k 20
//     iterations against 22. A problem of at most that size is one factorization.
//
// Limits, measured (docs/solvers-measurements.md): on well-shaped meshes (icospheres, also with a
// coarsening that is not the nested one) the iteration count is flat and the solve
// is 2-4x faster than with the Laplacian factor. On real scanned and modelled meshes
// (angles from 1-5 to 167-177 degrees) it is not: with a coarsest level of 2,000,
// igea-134k 84 iterations, armadillo 107, cow 217, the camel head (open boundary) 912,
// fertility-4k subdivided to 1.15M 169, where the factor preconditioner needs 7-38
// (with the default coarsest level: igea 72, armadillo 71, fertility 1.15M 167; the
// cow and the camel head fit in one factor). Neither the intrinsic Delaunay
// operators, nor Gauss-Seidel, nor another coarse vertex order, nor the fan fit
// above brought these to the sphere's figures; even a two-grid with exact nested
// interpolation needs 55-83 iterations on subdivided fertility, and 76 on the cow with
// 16 Gauss-Seidel sweeps: the coarse spaces miss low-energy modes of the cotangent
// bi-Laplacian on such meshes. The weights are not the cause (a graph bi-Laplacian
// on fertility fails alike), and even the ideal, dense interpolation on the same
// coarse vertices needs 33 iterations there with degree-1 Chebyshev (11 with degree
// 8), losing most of that when cut to a few rings: such meshes need wide coarse basis
// functions and stronger smoothing. So the global solver's default hands them on to
// the factor preconditioner (Auto).
//
// The finest level is applied as two sparse products with K on the free vertices and
// their one-ring (nothing of K D K is assembled there), on both cores above 20k rows.
// Cost and memory follow the free set, not the mesh: a drag region of 10k vertices
// inside a 655k mesh builds a 10k hierarchy.
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
  /// more level's set-up and solves faster than cycling through three more levels;
  /// docs/solvers-measurements.md), else 2,000 (Eigen's simplicial factor is several times slower).
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
