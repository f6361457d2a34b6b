// solvers/cg.h: the block PCG kernel (Jacobi and any preconditioner, several right-hand sides).
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
#include "meshpde/apps/fairing.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/editor/editor_session.h"
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

namespace {

// A sparse SPD test matrix: a 1-D Laplacian with a diagonal shift, n x n.
Eigen::SparseMatrix<double, Eigen::RowMajor> shifted_laplacian(int n, double shift) {
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 2.0 + shift * (1 + i % 7));
    if (i > 0) t.emplace_back(i, i - 1, -1.0);
    if (i + 1 < n) t.emplace_back(i, i + 1, -1.0);
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

}  // namespace

TEST(Cg, AnyPreconditionerConvergesToTheDirectAnswer) {
  const int n = 300;
  const auto A = shifted_laplacian(n, 1e-3);
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> exact(A);
  // An inexact preconditioner: the factor of A with a larger shift.
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> inexact(shifted_laplacian(n, 0.05));
  for (int m : {1, 3, 5}) {
    const Field b = Field::Random(n, m);
    const Eigen::MatrixXd want = exact.solve(Eigen::MatrixXd(b));
    CgWorkspace w;
    Field x;
    const CgResult r = block_pcg([&](const Field& p, Field& y) { y = A * p; },
                                 [&](const Field& r0, Field& z) { z = inexact.solve(Eigen::MatrixXd(r0)); }, b, x,
                                 CgOptions{.tolerance = 1e-13}, w);
    EXPECT_TRUE(r.converged()) << m << " columns: " << r.message;
    EXPECT_LE((Eigen::MatrixXd(x) - want).cwiseAbs().maxCoeff() / want.cwiseAbs().maxCoeff(), 1e-10) << m;
    // The exact inverse as the preconditioner: one step.
    Field y;
    const CgResult one = block_pcg([&](const Field& p, Field& q) { q = A * p; },
                                   [&](const Field& r0, Field& z) { z = exact.solve(Eigen::MatrixXd(r0)); }, b, y,
                                   CgOptions{.tolerance = 1e-10}, w);
    EXPECT_EQ(one.iterations, 1) << m;
  }
}

TEST(Cg, AColumnStopsOnItsOwnAndAMonitorCanStopTheSolve) {
  const int n = 200;
  const auto A = shifted_laplacian(n, 1e-4);
  Field b = Field::Random(n, 3);
  b.col(1).setZero();  // the exact answer of this column is zero, from any start
  Field x = Field::Ones(n, 3);
  CgWorkspace w;
  std::vector<int> seen;
  const CgResult r = pcg([&](const Field& p, Field& y) { y = A * p; }, Eigen::VectorXd::Constant(n, 0.5), b, x,
                         CgOptions{.tolerance = 1e-12}, w);
  EXPECT_TRUE(r.converged());
  EXPECT_EQ(x.col(1).cwiseAbs().maxCoeff(), 0.0);
  x.setZero();
  const CgResult stopped =
      block_pcg([&](const Field& p, Field& y) { y = A * p; }, JacobiPreconditioner{Eigen::VectorXd::Constant(n, 0.5)},
                b, x, CgOptions{.tolerance = 1e-12}, w,
                [&](int iterations, double) {
                  seen.push_back(iterations);
                  return iterations < 3;
                });
  EXPECT_EQ(stopped.status, CgStatus::Stopped);
  EXPECT_EQ(stopped.iterations, 3);
  EXPECT_EQ(seen, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_NE(stopped.message.find("stopped by its caller after 3 iterations"), std::string::npos) << stopped.message;
}

TEST(Cg, AGivenResidualOrAZeroStartSavesTheFirstProduct) {
  const int n = 100;
  const auto A = shifted_laplacian(n, 1e-2);
  const Field b = Field::Random(n, 1);
  const Eigen::VectorXd inv = Eigen::VectorXd::Constant(n, 1.0 / 2.01);
  int products = 0;
  auto apply = [&](const Field& p, Field& y) {
    ++products;
    y = A * p;
  };
  CgWorkspace w;
  Field x = Field::Zero(n, 1);
  CgResult r = pcg(apply, inv, b, x, CgOptions{.tolerance = 1e-10}, w);
  EXPECT_EQ(products, r.iterations);  // from zero: no product for the starting residual
  products = 0;
  x = Field::Constant(n, 1, 0.1);
  r = pcg(apply, inv, b, x, CgOptions{.tolerance = 1e-10}, w);
  EXPECT_EQ(products, r.iterations + 1);
  const Field start = Field::Constant(n, 1, 0.1);
  products = 0;
  x = start;
  w.r = b - A * start;
  r = pcg(apply, inv, b, x, CgOptions{.tolerance = 1e-10, .residual_given = true}, w);
  EXPECT_EQ(products, r.iterations);
  EXPECT_LE((A * x - b).norm() / b.norm(), 1e-9);
}

TEST(Cg, LargeSolvesGiveTheSameBitsOnOneThreadAndTwo) {
  if (!openmp_available()) GTEST_SKIP() << "built without OpenMP: every solve runs on one thread";
  const int n = 30000;
  const auto A = shifted_laplacian(n, 1e-3);
  const Field b = Field::Random(n, 3);
  Field x1, x2;
  CgWorkspace w;
  const CgOptions options{.tolerance = 1e-10, .parallel_rows = 1000};
  auto apply = [&](const Field& p, Field& y) { y = A * p; };
  const Eigen::VectorXd inv = A.diagonal().cwiseInverse();
  set_max_threads(1);
  const CgResult one = pcg(apply, inv, b, x1, options, w);
  set_max_threads(2);
  const CgResult two = pcg(apply, inv, b, x2, options, w);
  set_max_threads(0);
  EXPECT_TRUE(one.converged());
  EXPECT_EQ(one.iterations, two.iterations);
  EXPECT_EQ(one.relative_residual, two.relative_residual);
  EXPECT_TRUE(x1 == x2) << "largest difference " << (x1 - x2).cwiseAbs().maxCoeff();
}
