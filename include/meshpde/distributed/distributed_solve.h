// Distributed steady solves over MPI with PETSc (target meshpde::distributed): each
// process holds one part of a partitioned mesh (distributed/partition.h), K and M
// are assembled in parallel from the triangles around its own vertices, K D K is
// applied across processes without being assembled, and CG runs with a shell
// preconditioner K_c^-1 M K_c^-1 whose two Laplacian solves are one V-cycle of hypre's
// BoomerAMG each (PETSc's GAMG when PETSc lacks hypre). K_c is K with the constrained
// rows and columns replaced by the identity.
#pragma once

#include <mpi.h>

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/apps/interpolation.h"
#include "meshpde/distributed/partition.h"

namespace meshpde {

/// Starts PETSc (and MPI when it is not running) for the scope's life; a no-op when
/// PETSc is running already. What a front end creates first in main().
class PetscScope {
 public:
  PetscScope(int* argc, char*** argv);
  ~PetscScope();
  PetscScope(const PetscScope&) = delete;
  PetscScope& operator=(const PetscScope&) = delete;

 private:
  bool started_ = false;
};

struct DistributedSolveParams {
  double g1 = 0;              ///< Laplacian weight, as InterpolationParams
  double g2 = 1;              ///< bi-Laplacian weight
  double tolerance = 1e-12;   ///< CG's relative residual (preconditioned norm)
  int max_iterations = 5000;  ///< CG's limit
};

/// One process's share of the report (gathered on rank 0 by the front end).
struct RankReport {
  int rank = 0;
  int owned = 0, ghosts = 0;
  double ghost_fraction = 0;  ///< ghosts / owned
  double setup_seconds = 0;   ///< reading, assembly, preconditioner set-up
  double solve_seconds = 0;
  double peak_rss_mb = 0;  ///< the process's peak resident memory
};

struct DistributedResult {
  Eigen::MatrixXd values;        ///< one row per owned vertex of the part (its local order), one column a component
  int iterations = 0;            ///< CG's, the most over the components
  double relative_residual = 0;  ///< true residual |b - A x| / |b| after the solve, the worst component
  std::string preconditioner;    ///< "hypre-boomeramg" or "gamg"
  RankReport rank;
};

/// Scalar interpolation (g1 K + g2 K D K) u = 0 with u held at the constraints,
/// collectively over `comm` (every process passes its own part and the same
/// constraints, in the input mesh's numbering). Cotangent operators.
/// \throw InputError for a constraint on a vertex out of range, SolverError when CG
///        fails; a throw on one process only leaves the others waiting: callers agree
///        on failure first (front ends check every rank's part before solving).
DistributedResult distributed_interpolate(const MeshPart& part, const std::vector<InterpolationConstraint>& constraints,
                                          const DistributedSolveParams& params, MPI_Comm comm);

/// Fairing, as `meshpde fair` without --regularize: the free vertices' positions solve
/// the membrane (order 1: K x = 0) or thin plate (order 2: K D K x = 0) with the `fixed`
/// vertices held, collectively over `comm`. `fixed`: the selections a part can evaluate
/// on its own, "boundary", "halfspace:NX,NY,NZ:D" and "all" (others name vertices or
/// distances that need the whole mesh). values: #owned x 3 positions. Of `params`, the
/// tolerance and iteration limit are used (order sets g1 and g2).
/// \throw InputError for a bad order or selection (on every process alike), SolverError.
DistributedResult distributed_fair(const MeshPart& part, const std::vector<std::string>& fixed, int order,
                                   const DistributedSolveParams& params, MPI_Comm comm);

}  // namespace meshpde
