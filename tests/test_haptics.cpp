// apps/haptics.h: haptic poking, probe paths.
#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <thread>

#include "meshpde/apps/haptics.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

using meshpde::test::unit_edge_icosphere;

TEST(Haptics, ForceOpposesIndentationGrowsWithDepthAndVanishesAtRest) {
  const Mesh m = unit_edge_icosphere(4);
  const FemOperators ops = build_operators(m);
  HapticSession h(m, ops);
  const int v = 0;
  const Eigen::Vector3d n = m.positions().row(v).normalized();
  h.touch(v);
  EXPECT_EQ(h.step(1e-3), Eigen::Vector3d::Zero());  // at rest: no force
  double last = 0;
  for (const double depth : {0.05, 0.1, 0.2, 0.3}) {
    h.move_probe(-depth * n);
    Eigen::Vector3d f;
    for (int k = 0; k < 60; ++k) f = h.step(5e-2);  // settle (backward Euler: any step size is stable)
    EXPECT_GT(f.dot(n), 0.0) << "pushes back out";
    EXPECT_GT(f.normalized().dot(n), 0.99);
    EXPECT_GT(f.norm(), last) << "depth " << depth;
    last = f.norm();
  }
}

TEST(Haptics, SettledForceMatchesAnIndependentFullMatrixSolve) {
  const Mesh m = unit_edge_icosphere(4);
  const FemOperators ops = build_operators(m);
  const HapticParams params;
  HapticSession h(m, ops, params);
  const int v = 5;
  const Eigen::Vector3d offset(0.1, -0.25, 0.05);
  h.touch(v);
  h.move_probe(offset);
  Eigen::Vector3d f;
  for (int k = 0; k < 300; ++k) f = h.step(5e-2);  // 15 s of model time: settled
  // Independent: Kt = g0 M + g2 K D K assembled, Dirichlet at the contact, direct solve.
  const double L = 3 * mean_edge_length(m);
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops), M = mass_matrix(ops);
  Eigen::SparseMatrix<double> D(m.num_vertices(), m.num_vertices());
  for (int i = 0; i < m.num_vertices(); ++i) D.insert(i, i) = ops.D(i);
  const Eigen::SparseMatrix<double> Kt = params.stiffness * M + params.stiffness * std::pow(L, 4) * (K * D * K);
  const int n = m.num_vertices();
  std::vector<int> idx(n, -1);
  int nf = 0;
  for (int i = 0; i < n; ++i)
    if (i != v) idx[i] = nf++;
  std::vector<Eigen::Triplet<double>> t;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, 3);
  for (int c = 0; c < Kt.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(Kt, c); it; ++it) {
      if (idx[it.row()] < 0) continue;
      if (idx[it.col()] >= 0)
        t.emplace_back(idx[it.row()], idx[it.col()], it.value());
      else
        rhs.row(idx[it.row()]) -= it.value() * offset.transpose();
    }
  Eigen::SparseMatrix<double> A(nf, nf);
  A.setFromTriplets(t.begin(), t.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  const Eigen::MatrixXd x = solver.solve(rhs);
  Eigen::MatrixXd u(n, 3);
  for (int i = 0; i < n; ++i)
    u.row(i) = i == v ? Eigen::RowVector3d(offset.transpose()) : Eigen::RowVector3d(x.row(idx[i]));
  const Eigen::Vector3d reaction = (Kt * u).row(v).transpose();
  EXPECT_LE((f + reaction).norm(), 0.01 * reaction.norm())
      << "haptic " << f.transpose() << " vs full " << -reaction.transpose();
  EXPECT_LT(h.pde().domain().num_free(), n / 2);  // and it stayed local
}

TEST(Haptics, DomainGrowsWithIndentationAndShrinksAfterRelease) {
  const Mesh m = unit_edge_icosphere(5);
  const FemOperators ops = build_operators(m);
  HapticSession h(m, ops);
  h.touch(0);
  const Eigen::Vector3d n = m.positions().row(0).normalized();
  int small = 0, large = 0;
  for (int k = 1; k <= 200; ++k) {
    h.move_probe(-0.002 * k * n);
    h.step(1e-3);
    if (k == 20) small = h.pde().domain().num_free();
  }
  large = h.pde().domain().num_free();
  EXPECT_GT(large, small);
  h.release();
  EXPECT_EQ(h.step(1e-3), Eigen::Vector3d::Zero());
  for (int k = 0; k < 3000 && h.pde().domain().num_free() > 0; ++k) h.step(1e-2);
  EXPECT_EQ(h.pde().domain().num_free(), 0);
}

TEST(Haptics, ServoThreadStepsAndCountsMisses) {
  const Mesh m = unit_edge_icosphere(4);
  const FemOperators ops = build_operators(m);
  HapticSession h(m, ops, HapticParams{.rate_hz = 500});
  h.touch(3);
  h.start();
  const Eigen::Vector3d n = m.positions().row(3).normalized();
  for (int k = 0; k < 100; ++k) {
    h.move_probe(-0.001 * k * n);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  h.stop();
  const auto log = h.log();
  EXPECT_GT(log.size(), 10u);
  int missed = 0;
  for (const auto& s : log) missed += s.missed;
  EXPECT_EQ(missed, h.misses());
  EXPECT_GT(h.latest_force().dot(n), 0.0);
  h.stop();  // twice is fine
}

TEST(Haptics, DefaultStepToleranceTracksATightSolve) {
  const Mesh m = unit_edge_icosphere(5);
  const FemOperators ops = build_operators(m);
  HapticParams tight;
  tight.cg.tolerance = 1e-10;
  tight.cg.max_iterations = 5000;
  HapticSession fast(m, ops), exact(m, ops, tight);
  const int v = 7;
  const Eigen::Vector3d n = m.positions().row(v).normalized();
  fast.touch(v);
  exact.touch(v);
  double worst = 0, largest = 0;
  for (int k = 1; k <= 600; ++k) {  // press in over 0.3 s, sideways, hold
    const double s = std::min(k, 300) / 300.0;
    const Eigen::Vector3d offset =
        -0.5 * s * n + (k > 300 ? 0.2 * (k - 300) / 300.0 : 0.0) * m.positions().row(0).normalized().transpose();
    fast.move_probe(offset);
    exact.move_probe(offset);
    const Eigen::Vector3d a = fast.step(1e-3), b = exact.step(1e-3);
    worst = std::max(worst, (a - b).norm());
    largest = std::max(largest, b.norm());
  }
  EXPECT_GT(largest, 0.0);
  EXPECT_LE(worst, 0.01 * largest);
}

TEST(Parsers, ProbePathInterpolatesBetweenIncreasingTimes) {
  const auto p = parse_probe_path("t,dx,dy,dz\n0,0,0,0\n0.5 0 0 -1  # pressed\n1,0,0,-1\n", "p.csv");
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(probe_path_at(p, -1.0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(probe_path_at(p, 0.25).z(), -0.5, 1e-15);
  EXPECT_EQ(probe_path_at(p, 2.0), Eigen::Vector3d(0, 0, -1));
  EXPECT_NE(
      error_of([] { parse_probe_path("0,0,0,0\n0,0,0,1\n", "p.csv"); }).find("p.csv: line 2: times must increase"),
      std::string::npos);
  EXPECT_NE(error_of([] { parse_probe_path("0,0,0\n", "p.csv"); }).find("line 1: expected t,dx,dy,dz"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_probe_path("0,0,0,nan\n", "p.csv"); }).find("'nan' is not a number"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_probe_path("t,dx,dy,dz\n", "p.csv"); }).find("no path points"), std::string::npos);
}

TEST(Parsers, PressPathGoesInwardByTheDepthInEdgeLengths) {
  const Mesh m = make(icosphere(2));
  const int v = 7;
  const auto p = press_path(m, v, 0.5);
  ASSERT_EQ(p.size(), 3u);
  const Eigen::Vector3d bottom = probe_path_at(p, 0.6);
  EXPECT_NEAR(bottom.norm(), 0.5 * mean_edge_length(m), 1e-12);
  EXPECT_LT(bottom.dot(m.positions().row(v).transpose()), 0.0) << "into the sphere";
  EXPECT_NEAR(probe_path_at(p, 0.25).norm(), 0.25 * mean_edge_length(m), 1e-12);
  EXPECT_THROW(press_path(m, m.num_vertices(), 0.5), InputError);
}
