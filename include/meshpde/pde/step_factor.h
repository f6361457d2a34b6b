// A sparse Cholesky factor of PdeSession's step matrix on one free set F,
//
//     At_FF = (alpha + b1 dt) M_FF + (b2 + dt) dt Kt_FF,   Kt = g0 M + g1 K + g2 K D K
//
// (pde_session.h), so that a step on exactly that free set costs two triangular sweeps
// instead of a CG solve: the same work every step, whatever the right-hand side, which
// is what a servo with a hard deadline needs (apps/haptics.h). At_FF is assembled as
// steady_direct.h's Kt_FF with the coefficients (b2 + dt) dt g, the foundation g0 one
// plus alpha + b1 dt. Built from the mesh, operators and coefficients alone (no session
// state), so another thread can build the next one while a session keeps stepping.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/coefficients.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

class StepFactor {
 public:
  /// Assembles and factors At_FF on `free` (rows in that order) for steps of size dt.
  /// \throw InputError for a bad vertex, a vertex without area (PdeSession never frees
  ///        one), a repeated vertex or dt <= 0; SolverError if At_FF does not factor.
  StepFactor(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients, std::vector<int> free,
             double dt);

  /// The free set, in the factor's row order.
  const std::vector<int>& vertices() const { return free_; }
  double dt() const { return dt_; }
  const PdeCoefficients& coefficients() const { return c_; }
  /// X = At_FF^-1 B, rows of B and X in the order of vertices(). \throw SolverError if
  /// B's row count is not the factor's.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const { return chol_.solve(B); }
  double factor_nonzeros() const { return chol_.factor_nonzeros(); }
  /// Wall time of the assembly and factorization (s).
  double build_seconds() const { return seconds_; }

 private:
  std::vector<int> free_;
  double dt_;
  PdeCoefficients c_;
  SparseCholesky chol_;
  double seconds_ = 0;
};

}  // namespace meshpde
