// Steady problems (g0 M + g1 K + g2 K D K) u = f solved directly on a set of free
// vertices, every other vertex held at its given value. The matrix on the free set,
//     Kt_FF = g0 M_FF + g1 K_FF + g2 (K_SF)^T D_S K_SF,   S = F and its one-ring,
// is assembled from the stored K (K D K never appears whole) and factored once; solve()
// then costs two triangular sweeps per right-hand side, for any held values and any
// forcing. This is the path for interpolation, fairing and static drags, where
// Jacobi-CG's iteration count grows like h^-4 (see docs/solvers.md).
#pragma once

#include <unordered_map>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

/// Which solver steady problems use: Direct (SteadyDirectSolver, the default) or
/// Iterative (Jacobi-CG through PdeSession::solve_steady, no factorization memory).
enum class SteadySolver { Direct, Iterative };

class SteadyDirectSolver {
 public:
  /// Assembles and factors Kt_FF (+ diag(extra_diagonal) on the free rows, when
  /// given: #V non-negative values, e.g. a per-vertex foundation or the inertia of
  /// an implicit time step). Keeps references to mesh and ops.
  /// \throw InputError for a bad vertex; SolverError if a connected part of the free
  ///        set touches no held vertex (and g0 = 0): its values would be undetermined.
  SteadyDirectSolver(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients,
                     std::vector<int> free, SparseCholesky::Backend backend = SparseCholesky::Backend::Auto,
                     const Eigen::VectorXd& extra_diagonal = Eigen::VectorXd());

  /// Returns u with the free rows solved; the other rows of u are the held values.
  /// `f` (optional) is the load, #V x m like u.
  Field solve(const Field& u, const Field* f = nullptr) const;
  /// The free rows only (num_free() x m, in the order of the free list): reads u only
  /// at held neighbours, so the cost follows the region, not the mesh.
  Eigen::MatrixXd solve_free(const Field& u, const Field* f = nullptr) const;
  const std::vector<int>& free_vertices() const { return free_; }

  /// Relative residual |b - Kt_FF x| / |b| of the last solve (worst column), after
  /// iterative refinement.
  double last_relative_residual() const { return residual_; }
  /// Refinement steps the last solve took (0 when the first solve met refine_tolerance).
  int last_refinements() const { return refinements_; }

  /// Iterative refinement runs while the relative residual exceeds this (at most
  /// max_refinements steps, stopping early if the residual stops falling).
  double refine_tolerance = 1e-12;
  int max_refinements = 5;
  const SparseCholesky& factor() const { return chol_; }
  int num_free() const { return static_cast<int>(free_.size()); }

 private:
  const Mesh& mesh_;
  const FemOperators& ops_;
  PdeCoefficients c_;
  std::vector<int> free_;
  std::unordered_map<int, int> local_;  // vertex -> index in free_ (sized to the region, not the mesh)
  int local_index(int v) const {
    const auto it = local_.find(v);
    return it == local_.end() ? -1 : it->second;
  }
  Eigen::SparseMatrix<double> A_;
  SparseCholesky chol_;
  mutable double residual_ = 0;
  mutable int refinements_ = 0;
};

}  // namespace meshpde
