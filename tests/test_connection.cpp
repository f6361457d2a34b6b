// operators/connection.h: the discrete Levi-Civita connection and its Laplacian.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "meshpde/mesh/generators.h"
#include "meshpde/operators/connection.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;

TEST(Connection, AConstantFieldOnAFlatMeshIsParallelAndHarmonic) {
  // A plane grid with its interior vertices jittered in the plane: flat, irregular.
  GeneratedMesh g = plane_grid(14, 12, 1.3, 1.1);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.025, 0.025);
  std::vector<char> on_border(static_cast<std::size_t>(g.V.rows()), 0);
  for (Eigen::Index i = 0; i < g.V.rows(); ++i) {
    const double x = g.V(i, 0), y = g.V(i, 1);
    on_border[static_cast<std::size_t>(i)] = x < 1e-9 || y < 1e-9 || x > 1.3 - 1e-9 || y > 1.1 - 1e-9;
    if (!on_border[static_cast<std::size_t>(i)]) {
      g.V(i, 0) += jitter(rng);
      g.V(i, 1) += jitter(rng);
    }
  }
  const Mesh mesh = test::make(g);
  const FemOperators ops = build_cotan_operators(mesh);
  const Connection c = build_connection(mesh);
  const Eigen::Vector3d v(std::cos(0.3), std::sin(0.3), 0.0);
  Eigen::VectorXd x(2 * mesh.num_vertices());
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const double a = tangent_angle(c, i, v);
    x[2 * i] = std::cos(a);
    x[2 * i + 1] = std::sin(a);
    // The frame's angle and back give the vector itself (the plane's normal is z).
    EXPECT_LT((tangent_vector(c, i, a, 1.0) - v).norm(), 1e-12) << i;
    if (!c.boundary[static_cast<std::size_t>(i)]) {
      EXPECT_NEAR(c.theta[i], 2 * std::numbers::pi, 1e-12) << i;
    }
  }
  // Away from the border (whose corners rescale their angles), the connection
  // Laplacian of a parallel field vanishes: each neighbour's vector, transported, is
  // the vertex's own.
  const Eigen::SparseMatrix<double> L = connection_laplacian(mesh, c, ops.Kii, ops.Kij);
  const Eigen::VectorXd Lx = L * x;
  int checked = 0;
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    bool inner = !on_border[static_cast<std::size_t>(i)];
    for (int j : mesh.neighbors(i)) inner = inner && !on_border[static_cast<std::size_t>(j)];
    if (!inner) continue;
    ++checked;
    EXPECT_LT(std::hypot(Lx[2 * i], Lx[2 * i + 1]), 1e-12 * ops.Kii[i]) << i;
  }
  EXPECT_GT(checked, 80);  // the 11 x 9 vertices two rings inside the border
  // Symmetric, with K_ii on the diagonal of every 2 x 2 block.
  EXPECT_LT((Eigen::SparseMatrix<double>(L.transpose()) - L).norm(), 1e-12 * L.norm());
  for (int i = 0; i < mesh.num_vertices(); ++i) EXPECT_NEAR(L.coeff(2 * i, 2 * i), ops.Kii[i], 1e-12 * ops.Kii[i]);
}

TEST(Connection, TheAngleAroundASphereVertexIsTwoPiLessItsAngleDefect) {
  // On a closed convex surface every vertex's total angle is below 2 pi, and the angle
  // defects add up to 4 pi (Gauss-Bonnet for a sphere).
  const Mesh mesh = test::make(icosphere(3));
  const Connection c = build_connection(mesh);
  double defect = 0;
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    EXPECT_LT(c.theta[i], 2 * std::numbers::pi) << i;
    defect += 2 * std::numbers::pi - c.theta[i];
  }
  EXPECT_NEAR(defect, 4 * std::numbers::pi, 1e-9);
}
