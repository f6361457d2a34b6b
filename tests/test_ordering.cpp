// solvers/ordering.h: nested dissection and the index map.
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

namespace {

// Nonzeros of the Cholesky factor of A taken in the order it is given.
double factor_fill(const Eigen::SparseMatrix<double>& A) {
  const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> llt(A);
  EXPECT_EQ(llt.info(), Eigen::Success);
  return static_cast<double>(llt.matrixL().nestedExpression().nonZeros());
}

}  // namespace

TEST(Ordering, IndexMapNumbersKeysInInsertionOrderAcrossGrowth) {
  IndexMap map(2);  // grows several times below
  std::vector<int> keys;
  for (int k = 0; k < 5000; ++k) keys.push_back((k * 7919) % 1000003);
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const auto [index, inserted] = map.insert(keys[k]);
    EXPECT_TRUE(inserted);
    EXPECT_EQ(index, static_cast<int>(k));
  }
  EXPECT_EQ(map.insert(keys[17]), std::make_pair(17, false));
  EXPECT_EQ(map.size(), keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k) EXPECT_EQ(map.find(keys[k]), static_cast<int>(k));
  EXPECT_EQ(map.find(3), -1);  // 3 is not a multiple of 7919 modulo 1000003 below 5000 steps
  EXPECT_FALSE(map.contains(1000004));
}

TEST(Ordering, NestedDissectionIsAPermutationWithAmdLevelFill) {
  const Mesh mesh = make(icosphere(6));
  const FemOperators ops = build_cotan_operators(mesh);
  const std::vector<int> region = ordering_region(mesh);
  ASSERT_GT(region.size(), 2800u);
  for (const int hops : {2, 1}) {
    const PdeCoefficients c{.g0 = 0, .g1 = hops == 1 ? 1.0 : 0.0, .g2 = hops == 2 ? 1.0 : 0.0};
    const std::vector<int> nd = nested_dissection_order(mesh, region, NestedDissectionParams{.separator_hops = hops});
    std::vector<int> a = nd, b = region;
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(a, b) << "not a permutation of the region";
    const Eigen::SparseMatrix<double> in_ball_order = assemble_steady_matrix(mesh, ops, c, region);
    Eigen::AMDOrdering<int> amd;
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm;
    amd(in_ball_order, perm);
    Eigen::SparseMatrix<double> in_amd_order;
    in_amd_order = in_ball_order.selfadjointView<Eigen::Lower>().twistedBy(perm.inverse());
    const double nd_fill = factor_fill(assemble_steady_matrix(mesh, ops, c, nd));
    const double amd_fill = factor_fill(in_amd_order), ball_fill = factor_fill(in_ball_order);
    std::printf("hops %d: factor nonzeros %.0f nested dissection, %.0f AMD, %.0f geodesic-ball order\n", hops, nd_fill,
                amd_fill, ball_fill);
    // Measured: K D K 218k against AMD's 205k, K 82k against 71k (its leaves keep the
    // order given); on the 10k-vertex drag region of the bench it has 5 % less fill
    // than AMD and 23 % fewer flops.
    EXPECT_LE(nd_fill, 1.25 * amd_fill);
    EXPECT_LE(nd_fill, 0.5 * ball_fill);
    if (hops == 2) {
      // One-layer separators do not separate K D K (it couples vertices two edges
      // apart): the same recursion with them leaves more fill.
      const std::vector<int> thin = nested_dissection_order(mesh, region, NestedDissectionParams{.separator_hops = 1});
      const double thin_fill = factor_fill(assemble_steady_matrix(mesh, ops, c, thin));
      std::printf("K D K in the one-hop order: %.0f\n", thin_fill);
      EXPECT_GT(thin_fill, 1.1 * nd_fill);
    }
  }
}

TEST(Ordering, TwoThreadsGiveTheOneThreadOrder) {
  // From 4,000 vertices the top level's halves are ordered on two threads at the same
  // time; the order and the halves' sizes must be those of one thread.
  const Mesh mesh = make(icosphere(6));
  int top = 0;
  mesh.positions().col(2).maxCoeff(&top);
  const std::vector<int> region = geodesic_ball(mesh, top, 1.0);  // about 7.5k vertices
  ASSERT_GT(region.size(), 4000u);
  const int limit = max_threads();
  set_max_threads(1);
  const NestedDissection one = nested_dissection(mesh, region);
  set_max_threads(2);
  const NestedDissection two = nested_dissection(mesh, region);
  set_max_threads(limit);
  EXPECT_EQ(one.order, two.order);
  EXPECT_EQ(one.parts[0], two.parts[0]);
  EXPECT_EQ(one.parts[1], two.parts[1]);
  EXPECT_GT(two.parts[0], 1000u);
  EXPECT_GT(two.parts[1], 1000u);
}

TEST(Ordering, BadRequestsAreRefusedInWords) {
  const Mesh mesh = make(icosphere(2));
  auto message = [&](const std::vector<int>& v, const NestedDissectionParams& p) {
    try {
      (void)nested_dissection_order(mesh, v, p);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message({1, 2, 1}, {}).find("vertex 1 is listed twice"), std::string::npos);
  EXPECT_NE(message({1, mesh.num_vertices()}, {}).find("does not exist"), std::string::npos);
  EXPECT_NE(message({1, 2}, NestedDissectionParams{.separator_hops = 3}).find("separator_hops"), std::string::npos);
  EXPECT_NE(message({1, 2}, NestedDissectionParams{.leaf_size = 0}).find("leaf_size"), std::string::npos);
  EXPECT_TRUE(nested_dissection_order(mesh, {}).empty());
}
