// Steady bi-Laplacian problems on whole (large) meshes by preconditioned CG:
//
//     (g1 K + g2 K D K)_FF u_F = -(Kt u_held)_F
//
// Two preconditioners, and a rule to choose between them (docs/solvers-measurements.md has the
// measured tables):
//  - Auto (the default): the multigrid first; from `probe_iterations` on, its recent
//    rate predicts the iterations it needs, and once that is more than
//    `max_multigrid_iterations` (a mesh with badly shaped triangles, where its coarse
//    spaces are weak) the solve goes on from the multigrid's iterate with the Laplacian
//    factor. On well-shaped meshes this is the multigrid's speed; on the others it
//    costs the multigrid's set-up and a few of its iterations on top of the factor's
//    solve, and the peak memory is the larger of the two (the hierarchy is released
//    before the factor is built).
//  - LaplacianFactor: P^-1 = K_FF^-1 M_FF K_FF^-1 / g2, the bi-Laplacian written as the
//    square of the Laplacian (K D K = K M^-1 K), with one sparse Cholesky factor of
//    K_FF (about as sparse as K itself, where a factor of K D K has three times the
//    fill). Few iterations, but each costs four triangular sweeps over a factor that
//    grows like n log n, and the factorization like n^1.5. The g1 term is left out of
//    this preconditioner (a lower-order perturbation of g2 K D K). Robust on any mesh.
//  - Multigrid: one W-cycle of the geometric surface multigrid of
//    solvers/surface_multigrid.h per iteration, its coarsest level (12,000 unknowns by
//    default) factored; a problem of at most that size is one factorization. Setup and
//    iterations cost O(#F). On well-shaped meshes the iteration count stays nearly
//    flat (14, 16, 20, 23 at 41k, 164k, 655k, 2.6M) and the solve is 2-4x faster than
//    with the factor; on real meshes with obtuse triangles its coarse spaces are weak
//    and it is slower (fertility subdivided to 1.15M: 167 iterations against 39).
// Jacobi-CG's iteration count grows like h^-2 under refinement; both of these stay
// nearly flat.
#pragma once

#include <memory>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/surface_multigrid.h"

namespace meshpde {

struct GlobalBilaplacianParams {
  double g1 = 0;            ///< Laplacian weight
  double g2 = 1;            ///< bi-Laplacian weight (> 0)
  double tolerance = 1e-8;  ///< relative residual per component
  int max_iterations = 1000;
  enum class Preconditioner { Auto, Multigrid, LaplacianFactor };
  Preconditioner preconditioner = Preconditioner::Auto;
  SurfaceMultigridParams multigrid{};  ///< for Multigrid and Auto
  /// Auto: multigrid iterations before its rate is first judged.
  int probe_iterations = 6;
  /// Auto: hand the solve on to the Laplacian factor once the multigrid's rate predicts
  /// more iterations in all than this (docs/solvers-measurements.md: icospheres need 15-26, real
  /// meshes with slivers 80-900, where the factor needs 7-38 iterations at 3-4x the cost).
  double max_multigrid_iterations = 50;
  /// Auto: once the probe judges the multigrid too slow, go on with the Laplacian factor
  /// (true, the default), or stop there and return unconverged with
  /// `multigrid_given_up` set (false: for a caller with a faster route on such meshes,
  /// as SteadySolver::Auto's direct solve).
  bool hand_on_to_factor = true;
};

struct GlobalBilaplacianResult {
  Field values;        ///< u with the free rows solved
  int iterations = 0;  ///< in all (Auto: the multigrid's, then the factor's)
  /// The preconditioner that finished the solve (Multigrid or LaplacianFactor).
  GlobalBilaplacianParams::Preconditioner used = GlobalBilaplacianParams::Preconditioner::LaplacianFactor;
  /// Iterations with the multigrid (all of them, or those before Auto handed on).
  int multigrid_iterations = 0;
  /// Auto: the iterations in all that the multigrid's rate last predicted (0 if it
  /// converged before `probe_iterations`).
  double multigrid_predicted_iterations = 0;
  double multigrid_seconds = 0;  ///< the multigrid's set-up and iterations
  /// Auto with hand_on_to_factor = false: the probe judged the multigrid too slow and
  /// the solve stopped there (values: the multigrid's iterate; converged: false).
  bool multigrid_given_up = false;
  double relative_residual = 0;  ///< worst component
  bool converged = false;
  double setup_seconds = 0;  ///< the right-hand side, the multigrid hierarchy and/or assembly and factorization of K_FF
  double solve_seconds = 0;  ///< the iterations (both preconditioners' for Auto)
  double factor_nonzeros = 0;       ///< LaplacianFactor: nonzeros of the Cholesky factor of K_FF
  std::vector<int> level_unknowns;  ///< Multigrid: free unknowns on each level, finest first
  /// Memory of the solve per vertex. Multigrid: the hierarchy (matrices, prolongations,
  /// coarsest factor, cycle blocks) and the iteration's blocks (x, r, z, p, q).
  /// LaplacianFactor: the factor (12 bytes a nonzero), K_FF, the iteration's blocks
  /// and whole-mesh work fields. Auto: the larger of the two it used.
  double bytes_per_vertex = 0;
};

/// The global solver for one free set, kept across solves: the preconditioner (the
/// multigrid hierarchy or the Cholesky factor of K_FF) is built by the first solve() and
/// reused by the next ones, whose held values (a new handle position, new constraint
/// values on the same vertices) and column count may differ. A later solve costs its
/// right-hand side and its iterations only (docs/solvers-measurements.md: at 164k 0.43-0.46 s
/// against 0.71-0.74 s for the first). Auto decides once: after it has handed a solve on to
/// the factor, the next solves start with the factor; while the multigrid converges,
/// each solve is judged as the first was. The mesh and operators are referenced and
/// must outlive the solver; the free set and parameters are copied.
class GlobalBilaplacianSolver {
 public:
  /// Checks the parameters and the free set (cost O(#F)); builds no preconditioner yet.
  /// \throw InputError for bad vertices or g2 <= 0; SolverError naming a vertex of a
  ///        connected part of the free set that touches no held vertex (its values
  ///        would be undetermined).
  GlobalBilaplacianSolver(const Mesh& mesh, const FemOperators& ops, std::vector<int> free,
                          const GlobalBilaplacianParams& params = {});
  ~GlobalBilaplacianSolver();
  GlobalBilaplacianSolver(GlobalBilaplacianSolver&&) noexcept;
  GlobalBilaplacianSolver& operator=(GlobalBilaplacianSolver&&) noexcept;

  /// Solves with the held rows of u (one row per vertex, any number of columns). The
  /// iterations start from zero, or with `warm_start` from the free rows of u (for
  /// example the previous answer with the handle moved on: a small move then needs few
  /// iterations); otherwise the free rows are not read. `setup_seconds` of the result
  /// counts the right-hand side and whatever preconditioner this call had to build.
  /// \throw InputError if u's row count is wrong or, with `warm_start`, a free value is
  ///        not finite; SolverError if a preconditioner fails.
  GlobalBilaplacianResult solve(const Field& u, bool warm_start = false);

  int multigrid_builds() const;  ///< multigrid hierarchies built so far
  int factorizations() const;    ///< Cholesky factors of K_FF built so far

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One solve: `GlobalBilaplacianSolver(mesh, ops, free, params).solve(u)`.
/// \throw as GlobalBilaplacianSolver and its solve().
GlobalBilaplacianResult solve_global_bilaplacian(const Mesh& mesh, const FemOperators& ops,
                                                 const std::vector<int>& free, const Field& u,
                                                 const GlobalBilaplacianParams& params = {});

/// The same on plain (V, F), on the operators of `laplacian` (build_mesh_operators; Auto
/// as in the (V, F) form of every solve).
inline GlobalBilaplacianResult solve_global_bilaplacian(const Positions& V, const Triangles& F,
                                                        const std::vector<int>& free, const Field& u,
                                                        const GlobalBilaplacianParams& params = {},
                                                        LaplacianKind laplacian = LaplacianKind::Auto) {
  const MeshOperators mo = build_mesh_operators(Mesh(V, F), laplacian);
  return solve_global_bilaplacian(mo.mesh, mo.ops, free, u, params);
}

}  // namespace meshpde
