// Internal: the free block of the bi-Laplacian, A_FF = g2 (K D K)_FF, inverted through a
// factor of the Laplacian's free block K_FF instead of a factor of A_FF (the mixed form
// of Ciarlet and Raviart, as Jacobson, Tosun, Sorkine and Zorin use it for surface
// modelling).
//
// Let C be the held vertices of positive mass (D is 0 elsewhere, and those rows drop
// out of K D K). For x zero on C, A_FF x = g2 b is the pair
//     M v = K x,   (K v)_F = b        (v = D K x).
// The second holds for v = [y; 0] + N lambda with y = K_FF^-1 b and N = [N_F; I],
// N_F = -K_FF^-1 K_FC: a column per held vertex, the discrete harmonic function that is
// 1 there and 0 at the other held vertices. The first's rows on F give
//     x = K_FF^-1 M_F (y + N_F lambda),
// and its rows on C (with K_CF K_FF^-1 = -N_F^T) the |C| x |C| system
//     (M_C + N_F^T M_F N_F) lambda = -N_F^T M_F y.
// So each solve is two solves with the Laplacian's factor and a rank-|C| correction;
// N_F is solved once. K_FF's factor has a fraction of K D K's fill (a one-ring stencil
// against a two-ring one), so it is made faster, a solve through it (four sweeps)
// costs about one pair of sweeps of K D K's factor, and its rounding is the
// Laplacian's, not its square's, so fewer answers need refinement (measured:
// docs/solvers-measurements.md, "Painting"). The price is |C| kept columns, which
// limits it to few held vertices: scattered-data interpolation (InterpolationSolver).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/ordering.h"

namespace meshpde::detail {

class MixedBilaplacianSolver {
 public:
  /// Factors K_FF (CHOLMOD's order, or `order` when given: reuse_ordering of an earlier
  /// factor's vertex_order()) and solves the |C| harmonic columns N_F. References mesh
  /// and ops. \throw InputError for g2 <= 0 or a bad vertex; SolverError if a part of
  /// the free set touches no held vertex or K_FF does not factor.
  MixedBilaplacianSolver(const Mesh& mesh, const FemOperators& ops, double g2, std::vector<int> free,
                         const NestedDissection* order = nullptr);

  int num_free() const { return laplacian_.num_free(); }
  const std::vector<int>& free_vertices() const { return laplacian_.free_vertices(); }
  /// Row of vertex v in the free list, or -1 when v is held.
  int free_index(int v) const { return laplacian_.free_index(v); }
  /// Held vertices of positive mass (|C|: the columns kept).
  int num_held() const { return static_cast<int>(held_.size()); }
  /// -A_{F,v}: the right-hand side a unit value held at v puts on the free rows.
  Eigen::VectorXd coupling(int v) const;
  /// A_FF^-1 B (num_free() x m), without refinement: two sweeps of K_FF's factor per
  /// column and the rank-|C| correction.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;
  /// The same, refined while the relative residual |B - A_FF X| / |B| (through the
  /// products K_FF, K_CF, never an assembled A_FF) exceeds 1e-13 and falls (at most
  /// three steps). Not stopped at backward stability, which the plain solve already
  /// reaches: a column kept and combined into later answers carries its residual into
  /// theirs.
  Eigen::MatrixXd solve_rhs(const Eigen::MatrixXd& B) const;
  /// A_FF X through the products.
  Eigen::MatrixXd multiply(const Eigen::MatrixXd& X) const;
  /// K_FF's elimination order as mesh vertex ids (for reuse_ordering).
  NestedDissection vertex_order() const { return laplacian_.vertex_order(); }
  /// Nonzeros of K_FF's factor.
  double factor_nonzeros() const { return laplacian_.factor().factor_nonzeros(); }

 private:
  const Mesh& mesh_;
  const FemOperators& ops_;
  double g2_;
  SteadyDirectSolver laplacian_;                       // K_FF
  std::vector<int> held_;                              // C
  Eigen::SparseMatrix<double, Eigen::RowMajor> K_CF_;  // |C| x |F|
  Eigen::VectorXd mass_F_, inverse_mass_F_, inverse_mass_C_;
  Eigen::MatrixXd N_;              // N_F, |F| x |C|
  Eigen::LLT<Eigen::MatrixXd> G_;  // M_C + N_F^T M_F N_F
};

}  // namespace meshpde::detail
