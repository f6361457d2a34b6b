// Steady bi-Laplacian problems on whole (large) meshes by preconditioned CG:
//
//     (g1 K + g2 K D K)_FF u_F = -(Kt u_held)_F
//
// preconditioned by P^-1 = K_FF^-1 M_FF K_FF^-1 / g2, i.e. the bi-Laplacian written as
// the square of the Laplacian (K D K = K M^-1 K), with one sparse Cholesky factor of
// K_FF (about as sparse as K itself, where a factor of K D K has three times the
// fill). K D K is applied matrix-free on both cores. Jacobi-CG's iteration count grows
// like h^-2 under refinement; this one stays nearly flat (10, 13, 17, 20, 27 at 10k,
// 41k, 164k, 655k, 2.6M vertices; docs/solvers.md). The g1 term is left out of the
// preconditioner (it is a lower-order perturbation of g2 K D K).
#pragma once

#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

struct GlobalBilaplacianParams {
  double g1 = 0;            ///< Laplacian weight
  double g2 = 1;            ///< bi-Laplacian weight (> 0)
  double tolerance = 1e-8;  ///< relative residual per component
  int max_iterations = 1000;
};

struct GlobalBilaplacianResult {
  Field values;  ///< u with the free rows solved
  int iterations = 0;
  double relative_residual = 0;  ///< worst component
  bool converged = false;
  double setup_seconds = 0;    ///< assembly and factorization of K_FF
  double solve_seconds = 0;    ///< the iterations
  double factor_nonzeros = 0;  ///< nonzeros of the Cholesky factor of K_FF
  /// Memory of the solve per vertex: the factor (12 bytes a nonzero), K_FF, and the
  /// iteration's blocks (free rows x components: x, r, z, p, q; whole-mesh work fields).
  double bytes_per_vertex = 0;
};

/// \throw InputError for bad vertices or g2 <= 0; SolverError if K_FF cannot be factored
///        (a part of the free set without a held vertex).
GlobalBilaplacianResult solve_global_bilaplacian(const Mesh& mesh, const FemOperators& ops,
                                                 const std::vector<int>& free, const Field& u,
                                                 const GlobalBilaplacianParams& params = {});

}  // namespace meshpde
