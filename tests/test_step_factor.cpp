// pde/step_factor.h: the factor of the backward Euler matrix on a free set, against the
// matrix assembled from Eigen's products, and a session's steps with it against CG.
#include <gtest/gtest.h>

#include <Eigen/SparseCore>
#include <vector>

#include "meshpde/mesh/generators.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/pde/step_factor.h"
#include "test_support.h"

using namespace meshpde;

TEST(StepFactor, SolvesTheAssembledStepMatrixAndStepsAsCgDoes) {
  const Mesh mesh = test::make(icosphere(3));
  const FemOperators ops = build_cotan_operators(mesh);
  const PdeCoefficients c{.alpha = 1.0, .b1 = 0.5, .b2 = 0.01, .g0 = 0.1, .g1 = 0.3, .g2 = 0.2};
  const double dt = 1e-2;
  std::vector<int> free;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.3) free.push_back(v);
  const auto factor = std::make_shared<const StepFactor>(mesh, ops, c, free, dt);
  ASSERT_EQ(factor->vertices().size(), free.size());
  // At = (alpha + b1 dt) M + (b2 + dt) dt (g0 M + g1 K + g2 K D K), its free block.
  const Eigen::SparseMatrix<double> K = stiffness_matrix(mesh, ops), M = mass_matrix(ops);
  Eigen::SparseMatrix<double> D(mesh.num_vertices(), mesh.num_vertices());
  for (int i = 0; i < mesh.num_vertices(); ++i) D.insert(i, i) = ops.D(i);
  const Eigen::SparseMatrix<double> At =
      (c.alpha + c.b1 * dt) * M + (c.b2 + dt) * dt * (c.g0 * M + c.g1 * K + c.g2 * (K * D * K));
  const int n = static_cast<int>(factor->vertices().size());
  Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 3);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, 3);
  for (int r = 0; r < n; ++r)
    for (int s = 0; s < n; ++s)
      b.row(r) +=
          At.coeff(factor->vertices()[static_cast<std::size_t>(r)], factor->vertices()[static_cast<std::size_t>(s)]) *
          x.row(s);
  EXPECT_LT((factor->solve(b) - x).cwiseAbs().maxCoeff(), 1e-10 * x.cwiseAbs().maxCoeff());
  // Two sessions, one stepping with the factor, one with CG to 1e-13: the same steps.
  PdeSession with(mesh, ops, 1, c), without(mesh, ops, 1, c);
  without.cg_options.tolerance = 1e-13;
  for (PdeSession* s : {&with, &without}) s->activate(free);
  with.set_step_factor(factor);
  ASSERT_TRUE(with.step_factor_applies(dt));
  Field f = Field::Zero(mesh.num_vertices(), 1);
  f(free[3], 0) = 1.0;
  for (int k = 0; k < 3; ++k) {
    const StepResult a = with.step(dt, &f), b2 = without.step(dt, &f);
    ASSERT_TRUE(b2.cg.converged());
    EXPECT_TRUE(a.factored);
    EXPECT_FALSE(b2.factored);
    EXPECT_LT((with.values() - without.values()).cwiseAbs().maxCoeff(), 1e-10 * without.values().cwiseAbs().maxCoeff());
  }
}
