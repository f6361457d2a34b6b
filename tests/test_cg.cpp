// solvers/cg.h: Jacobi-PCG on several right-hand sides.
#include <gtest/gtest.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <limits>
#include <queue>
#include <random>
#include <unordered_set>

#include "../src/core/index_map.h"
#include "meshpde/apps/editor_session.h"
#include "meshpde/apps/fairing.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/refinement.h"
#include "meshpde/solvers/surface_multigrid.h"
#include "solver_problems.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using namespace meshpde::test;

TEST(Cg, SolvesSpdWithSeveralRightHandSides) {
  const int n = 50;
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, n);
  A = A * A.transpose() + n * Eigen::MatrixXd::Identity(n, n);
  const Field b = Field::Random(n, 3);
  Field x = Field::Zero(n, 3);
  CgWorkspace w;
  const Eigen::VectorXd inv = A.diagonal().cwiseInverse();
  const CgResult r = pcg([&](const Field& p, Field& y) { y = A * p; }, inv, b, x, CgOptions{.tolerance = 1e-12}, w);
  EXPECT_TRUE(r.converged());
  EXPECT_LE((A * x - b).norm() / b.norm(), 1e-11);
}

TEST(Cg, ReportsBreakdownAndIterationCapInWords) {
  const int n = 10;
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n);
  A(3, 3) = -1;  // indefinite
  const Field b = Field::Ones(n, 1);
  Field x = Field::Zero(n, 1);
  CgWorkspace w;
  const CgResult r = pcg([&](const Field& p, Field& y) { y = A * p; }, Eigen::VectorXd::Ones(n), b, x, CgOptions{}, w);
  EXPECT_EQ(r.status, CgStatus::Breakdown);
  EXPECT_NE(r.message.find("not positive definite"), std::string::npos);

  Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, n);
  B = B * B.transpose() + 1e-3 * Eigen::MatrixXd::Identity(n, n);
  x.setZero();
  const CgResult c = pcg([&](const Field& p, Field& y) { y = B * p; }, Eigen::VectorXd::Ones(n), b, x,
                         CgOptions{.max_iterations = 2}, w);
  EXPECT_EQ(c.status, CgStatus::MaxIterations);
  EXPECT_NE(c.message.find("no convergence in 2 iterations"), std::string::npos);
}
