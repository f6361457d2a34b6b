// pde/pde_session.h and pde/steady_direct.h: heat against spherical harmonics, steady
// solves against analytic and assembled answers, reaction forces.
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

// Heat equation u_t = lap u on the unit sphere: Y_l decays as exp(-l(l+1) t).
TEST(Heat, SphericalHarmonicsDecayAtTheAnalyticRate) {
  const Mesh m = make(icosphere(5));  // 10,242 vertices
  ASSERT_GE(m.num_vertices(), 10000);
  const FemOperators ops = build_operators(m);
  const auto& V = m.positions();
  for (int l = 1; l <= 3; ++l) {
    SCOPED_TRACE(l);
    Field u0(m.num_vertices(), 1);
    for (int i = 0; i < m.num_vertices(); ++i) {
      const double z = V(i, 2);
      u0(i, 0) = l == 1 ? z : (l == 2 ? 1.5 * z * z - 0.5 : 2.5 * z * z * z - 1.5 * z);  // Legendre P_l(z)
    }
    PdeSession s(m, ops, 1, PdeCoefficients{.alpha = 0, .b1 = 1, .b2 = 0, .g1 = 1, .g2 = 0});
    s.cg_options.tolerance = 1e-12;
    s.set_values(u0);
    s.activate_all();
    const double dt = 2.5e-4, t = 0.05;
    const int steps = static_cast<int>(std::lround(t / dt));
    for (int k = 0; k < steps; ++k) {
      ASSERT_TRUE(s.step(dt).cg.converged());
    }
    // Projection onto u0 in the mass inner product.
    const double ratio = (u0.cwiseProduct(ops.mass.asDiagonal() * s.values())).sum() /
                         (u0.cwiseProduct(ops.mass.asDiagonal() * u0)).sum();
    const double rate = -std::log(ratio) / t;
    EXPECT_NEAR(rate / (l * (l + 1)), 1.0, 0.01);
  }
}

TEST(Steady, BilaplacianReproducesLinearFieldsExactly) {
  const GeneratedMesh g = test::jittered_plane(16, 0.015, 11);
  const Mesh m = make(g);
  const FemOperators ops = build_operators(m);
  PdeSession s(m, ops, 1, PdeCoefficients{.alpha = 0, .b1 = 0, .b2 = 0, .g1 = 0, .g2 = 1},
               DomainOptions{.seed_rings = 0});
  s.cg_options.tolerance = 1e-13;
  auto linear = [&](int i) { return 0.3 + 2 * g.V(i, 0) - 5 * g.V(i, 1); };
  // Constrain two rings at the boundary (the bi-Laplacian's boundary data), free the rest.
  const double h = 1.0 / 16;
  int fixed = 0;
  for (int i = 0; i < m.num_vertices(); ++i) {
    const double d = std::min({g.V(i, 0), 1 - g.V(i, 0), g.V(i, 1), 1 - g.V(i, 1)});
    if (d < 1.5 * h) {
      const double v = linear(i);
      s.constrain(i, std::span<const double>(&v, 1));
      ++fixed;
    } else {
      s.activate(std::vector<int>{i});
    }
  }
  ASSERT_GT(s.domain().num_free(), 100);
  const StepResult r = s.solve_steady();
  ASSERT_TRUE(r.cg.converged()) << r.cg.message;
  for (int i = 0; i < m.num_vertices(); ++i) {
    EXPECT_NEAR(s.values()(i, 0), linear(i), 1e-9);
  }
}

TEST(Steady, HarmonicInterpolationObeysTheMaximumPrinciple) {
  const Mesh m = make(plane_grid(20, 20));  // right triangles: Delaunay, cotangent weights >= 0
  const FemOperators ops = build_operators(m);
  PdeSession s(m, ops, 1, PdeCoefficients{.alpha = 0, .b1 = 0, .b2 = 0, .g1 = 1, .g2 = 0},
               DomainOptions{.seed_rings = 0});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> val(-2, 3);
  double lo = 1e9, hi = -1e9;
  const auto& V = m.positions();
  for (int i = 0; i < m.num_vertices(); ++i) {
    const bool boundary = V(i, 0) == 0 || V(i, 0) == 1 || V(i, 1) == 0 || V(i, 1) == 1;
    if (boundary) {
      const double v = val(rng);
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      s.constrain(i, std::span<const double>(&v, 1));
    } else {
      s.activate(std::vector<int>{i});
    }
  }
  ASSERT_TRUE(s.solve_steady().cg.converged());
  for (int i = 0; i < m.num_vertices(); ++i) {
    EXPECT_GE(s.values()(i, 0), lo - 1e-9);
    EXPECT_LE(s.values()(i, 0), hi + 1e-9);
  }
}

TEST(Steady, ReactionForcesEqualAssembledRows) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_operators(m);
  const PdeCoefficients c{.alpha = 0, .b1 = 0, .b2 = 0, .g0 = 0.2, .g1 = 0.7, .g2 = 0.4};
  PdeSession s(m, ops, 3, c, DomainOptions{.seed_rings = 0});
  s.cg_options.tolerance = 1e-12;
  s.activate_all();
  const double a[3] = {0.1, -0.2, 0.05}, b[3] = {0, 0, 0.3}, z[3] = {0, 0, 0};
  s.constrain(0, a);
  s.constrain(100, b);
  s.constrain(400, z);
  ASSERT_TRUE(s.solve_steady().cg.converged());
  // Independent: Kt = g1 (-L) + g2 L M^-1 L assembled from the cotangent formula.
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
  Eigen::SparseMatrix<double> D(m.num_vertices(), m.num_vertices());
  for (int i = 0; i < m.num_vertices(); ++i) D.insert(i, i) = ops.D(i);
  const Eigen::SparseMatrix<double> Kt = c.g0 * mass_matrix(ops) + c.g1 * K + c.g2 * (K * D * K);
  const Eigen::MatrixXd KtU = Kt * Eigen::MatrixXd(s.values());
  const auto cons = s.constrained_vertices();
  for (std::size_t k = 0; k < cons.size(); ++k)
    for (int d = 0; d < 3; ++d)
      EXPECT_NEAR(s.reaction_forces()(k, d), KtU(cons[k], d), 1e-10 * KtU.cwiseAbs().maxCoeff());
  // Free rows are in equilibrium.
  for (int i = 0; i < m.num_vertices(); ++i)
    if (s.domain().state(i) == VertexState::Free) {
      EXPECT_LE(KtU.row(i).norm(), 1e-8 * KtU.cwiseAbs().maxCoeff());
    }
}

TEST(Step, ReactionForceEqualsAssembledBackwardEulerRow) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_operators(m);
  const PdeCoefficients c{.alpha = 1.0, .b1 = 0.5, .b2 = 0.01, .g0 = 0.1, .g1 = 0.3, .g2 = 0.2};
  PdeSession s(m, ops, 1, c);
  s.cg_options.tolerance = 1e-13;
  s.activate_all();
  const double dt = 0.01;
  Field f = Field::Zero(m.num_vertices(), 1);
  f(7, 0) = 0.25;
  for (int k = 0; k < 3; ++k) {
    const double v = 0.01 * (k + 1);
    s.constrain(5, std::span<const double>(&v, 1));
    const Field u_old = s.values(), v_old = s.velocities();
    ASSERT_TRUE(s.step(dt, &f).cg.converged());
    // Assemble At and b and evaluate (row_5(At) v - b_5) / dt independently.
    const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
    Eigen::SparseMatrix<double> D(m.num_vertices(), m.num_vertices());
    for (int i = 0; i < m.num_vertices(); ++i) D.insert(i, i) = ops.D(i);
    const Eigen::SparseMatrix<double> M = mass_matrix(ops);
    const Eigen::SparseMatrix<double> Kt = c.g0 * M + c.g1 * K + c.g2 * (K * D * K);
    const Eigen::SparseMatrix<double> At = (c.alpha + c.b1 * dt) * M + (c.b2 + dt) * dt * Kt;
    const Eigen::VectorXd vv = s.velocities().col(0);
    const Eigen::VectorXd bb = c.alpha * (M * Eigen::VectorXd(v_old.col(0))) -
                               dt * (Kt * Eigen::VectorXd(u_old.col(0))) + dt * Eigen::VectorXd(f.col(0));
    Eigen::VectorXd res = At * vv - bb;
    EXPECT_NEAR(s.reaction_forces()(0, 0), res[5] / dt, 1e-9 * std::abs(res[5] / dt) + 1e-12);
    // Every free row satisfies the backward Euler equation.
    res[5] = 0;
    EXPECT_LE(res.cwiseAbs().maxCoeff(), 1e-10 * bb.cwiseAbs().maxCoeff());
  }
}

TEST(Steady, AssembledMatrixIsThePrincipalBlockOfTheWholeMeshProduct) {
  // Independent: g0 M + g1 K + g2 K D K from Eigen's sparse products over the whole
  // mesh, then the rows and columns of the free vertices in the order given. Below and
  // above the size where the columns are assembled on several threads, in a shuffled
  // order; every column's row indices strictly increasing (CHOLMOD and the leading-block
  // factors read them so).
  const Mesh m = bumpy_sphere(5);
  const FemOperators ops = build_operators(m);
  const PdeCoefficients c{.g0 = 0.3, .g1 = 0.7, .g2 = 1.1};
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
  Eigen::SparseMatrix<double> D(m.num_vertices(), m.num_vertices());
  for (int i = 0; i < m.num_vertices(); ++i) D.insert(i, i) = ops.D(i);
  const Eigen::SparseMatrix<double> whole =
      c.g0 * mass_matrix(ops) + c.g1 * K + c.g2 * Eigen::SparseMatrix<double>(K * D * K);
  std::mt19937 rng(5);
  const int limit = max_threads();
  for (const double z : {0.8, -0.5}) {  // about 1k and 7.7k of the 10k vertices
    std::vector<int> free;
    for (int v = 0; v < m.num_vertices(); ++v)
      if (m.positions()(v, 2) > z) free.push_back(v);
    std::shuffle(free.begin(), free.end(), rng);
    for (const int threads : {1, 2}) {
      set_max_threads(threads);
      const Eigen::SparseMatrix<double> A = assemble_steady_matrix(m, ops, c, free);
      ASSERT_EQ(A.rows(), static_cast<Eigen::Index>(free.size()));
      for (Eigen::Index j = 0; j < A.outerSize(); ++j)
        for (int q = A.outerIndexPtr()[j] + 1; q < A.outerIndexPtr()[j + 1]; ++q)
          ASSERT_LT(A.innerIndexPtr()[q - 1], A.innerIndexPtr()[q]) << "column " << j;
      Eigen::SparseMatrix<double> pick(A.rows(), m.num_vertices());  // row i: e_{free[i]}
      for (Eigen::Index i = 0; i < A.rows(); ++i) pick.insert(i, free[static_cast<std::size_t>(i)]) = 1;
      const Eigen::SparseMatrix<double> expected = pick * whole * pick.transpose();
      const Eigen::SparseMatrix<double> difference = A - expected;
      EXPECT_LE(Eigen::VectorXd::Map(difference.valuePtr(), difference.nonZeros()).cwiseAbs().maxCoeff(),
                1e-12 * Eigen::VectorXd::Map(expected.valuePtr(), expected.nonZeros()).cwiseAbs().maxCoeff())
          << free.size() << " free vertices, " << threads << " threads";
    }
  }
  set_max_threads(limit);
}
