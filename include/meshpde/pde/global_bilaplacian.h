// Steady bi-Laplacian problems on whole (large) meshes by preconditioned CG:
//
//     (g1 K + g2 K D K)_FF u_F = -(Kt u_held)_F
//
// preconditioned by P^-1 = K_FF^-1 M_FF K_FF^-1 / g2, i.e. the bi-Laplacian written as
// the square of the Laplacian (K D K = K M^-1 K). K_FF^-1 is applied by a sparse
// Cholesky factor of K_FF (the default; about as sparse as K itself, where a factor of
// K D K has three times the fill) or by one algebraic multigrid V-cycle (memory linear
// in the mesh, but more iterations; see LaplacianInverse). Jacobi-CG's iteration count grows like h^-2 under
// refinement; this one stays nearly flat (tested on three resolutions). The g1 term is left out of the preconditioner
// (it is a lower-order perturbation of g2 K D K).
#pragma once

#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

/// How K_FF^-1 is applied inside the preconditioner.
enum class LaplacianInverse {
  Cholesky,   ///< a sparse Cholesky factor (default): iterations 10, 13, 17 at 10k, 41k, 164k
  Multigrid,  ///< one smoothed-aggregation V-cycle (solvers/multigrid.h): memory linear in the
              ///< mesh (about 190 bytes a vertex), but iterations grow about 2x per 4x vertices
              ///< (30, 49, 101 at 2.5k, 10k, 41k): an approximate K^-1 enters the
              ///< preconditioner twice, and its error is not uniform over the spectrum
};

struct GlobalBilaplacianParams {
  double g1 = 0;            ///< Laplacian weight
  double g2 = 1;            ///< bi-Laplacian weight (> 0)
  double tolerance = 1e-8;  ///< relative residual per component
  int max_iterations = 1000;
  LaplacianInverse inverse = LaplacianInverse::Cholesky;
};

struct GlobalBilaplacianResult {
  Field values;  ///< u with the free rows solved
  int iterations = 0;
  double relative_residual = 0;  ///< worst component
  bool converged = false;
  double setup_seconds = 0;              ///< assembly and factorization (or hierarchy) of K_FF
  double solve_seconds = 0;              ///< the iterations
  std::size_t preconditioner_bytes = 0;  ///< memory of the factor or the multigrid hierarchy
  int multigrid_levels = 0;              ///< 0 with the Cholesky inverse
};

/// \throw InputError for bad vertices or g2 <= 0; SolverError if K_FF cannot be factored
///        (a part of the free set without a held vertex).
GlobalBilaplacianResult solve_global_bilaplacian(const Mesh& mesh, const FemOperators& ops,
                                                 const std::vector<int>& free, const Field& u,
                                                 const GlobalBilaplacianParams& params = {});

}  // namespace meshpde
