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
    return refusal<InputError>([&] { (void)nested_dissection_order(mesh, v, p); });
  };
  EXPECT_NE(message({1, 2, 1}, {}).find("vertex 1 is listed twice"), std::string::npos);
  EXPECT_NE(message({1, mesh.num_vertices()}, {}).find("does not exist"), std::string::npos);
  EXPECT_NE(message({1, 2}, NestedDissectionParams{.separator_hops = 3}).find("separator_hops"), std::string::npos);
  EXPECT_NE(message({1, 2}, NestedDissectionParams{.leaf_size = 0}).find("leaf_size"), std::string::npos);
  EXPECT_TRUE(nested_dissection_order(mesh, {}).empty());
}

namespace {

// The mesh ordering needs METIS: a build without it fails these tests under CI and
// skips them (with the reason) elsewhere.
bool need_mesh_ordering() {
  if (mesh_ordering_available()) return true;
  if (under_ci()) ADD_FAILURE() << "this build has no METIS (libmetis-dev), which the mesh ordering needs";
  return false;
}

// The real-mesh problem of the bench on armadillo-43k: the lowest 2 % held.
bool armadillo_problem(Mesh& mesh, bench::TopDrag& drag) {
  if (!load_data("armadillo-43k.obj", mesh)) return false;
  drag = bench::top_drag(mesh, mean_edge_length(mesh));
  return true;
}

}  // namespace

TEST(Ordering, MeshOrderingOfARealMeshHasFillNearCholmodsMetis) {
  if (!need_mesh_ordering()) GTEST_SKIP() << "built without METIS";
  Mesh mesh;
  bench::TopDrag drag;
  if (!armadillo_problem(mesh, drag)) GTEST_SKIP() << "armadillo-43k.obj not in the data folder";
  const FemOperators ops = build_cotan_operators(mesh);
  for (const int hops : {2, 1}) {
    const PdeCoefficients c{.g0 = 0, .g1 = hops == 1 ? 1.0 : 0.0, .g2 = hops == 2 ? 1.0 : 0.0};
    const std::vector<int> order = mesh_nested_dissection_order(mesh, drag.free, {.separator_hops = hops});
    std::vector<int> a = order, b = drag.free;
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    ASSERT_EQ(a, b) << "not a permutation of the free vertices";
    // The fill of the order itself: one factor of the assembled matrix in it.
    const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, c, drag.free);
    std::vector<int> row(static_cast<std::size_t>(mesh.num_vertices()), -1);
    for (std::size_t k = 0; k < drag.free.size(); ++k)
      row[static_cast<std::size_t>(drag.free[k])] = static_cast<int>(k);
    std::vector<int> rows_in_order;
    for (int v : order) rows_in_order.push_back(row[static_cast<std::size_t>(v)]);
    SparseCholesky in_cholmods_order(SparseCholesky::Backend::Cholmod), in_mesh_order(SparseCholesky::Backend::Cholmod);
    in_mesh_order.set_order(rows_in_order);
    in_cholmods_order.factorize(A);
    in_mesh_order.factorize(A);
    const double theirs = in_cholmods_order.factor_nonzeros(), mine = in_mesh_order.factor_nonzeros();
    std::printf("hops %d: factor nonzeros %.0f in the mesh order, %.0f in CHOLMOD's (%.2fx)\n", hops, mine, theirs,
                mine / theirs);
    // Measured: K D K 1.20x (without the separator's couplings through held vertices
    // and separators above: 1.74x); K 1.39x, which is why Auto keeps CHOLMOD's order
    // for K.
    EXPECT_LE(mine, (hops == 2 ? 1.25 : 1.6) * theirs);
    const SteadyDirectSolver cholmod(mesh, ops, c, drag.free, SparseCholesky::Backend::Cholmod, {},
                                     DirectOrdering::Cholmod);
    const SteadyDirectSolver ours(mesh, ops, c, drag.free, SparseCholesky::Backend::Cholmod, {}, DirectOrdering::Mesh);
    // The same answer as CHOLMOD's own ordering.
    const Field x = ours.solve(drag.u), y = cholmod.solve(drag.u);
    EXPECT_LE((x - y).norm(), 1e-10 * y.norm());
  }
}

TEST(Ordering, MeshOrderingIsTheSameOnOneAndTwoThreadsAndForEveryRun) {
  if (!need_mesh_ordering()) GTEST_SKIP() << "built without METIS";
  // Above 20,000 vertices the two top-level halves are ordered on two threads.
  const Mesh mesh = make(icosphere(6));  // 40,962 vertices
  std::vector<int> vertices;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.9) vertices.push_back(v);
  ASSERT_GT(vertices.size(), 30000u);
  const int limit = max_threads();
  set_max_threads(1);
  const std::vector<int> one = mesh_nested_dissection_order(mesh, vertices);
  set_max_threads(2);
  const std::vector<int> two = mesh_nested_dissection_order(mesh, vertices);
  const std::vector<int> again = mesh_nested_dissection_order(mesh, vertices);
  set_max_threads(limit);
  EXPECT_EQ(one, two);
  EXPECT_EQ(two, again);
  // And it is a nested dissection, not the order given: its factor beats AMD's.
  const FemOperators ops = build_cotan_operators(mesh);
  const PdeCoefficients c{.g0 = 0, .g1 = 0, .g2 = 1};
  const SteadyDirectSolver cholmod(mesh, ops, c, vertices, SparseCholesky::Backend::Cholmod, {},
                                   DirectOrdering::Cholmod);
  const SteadyDirectSolver ours(mesh, ops, c, vertices, SparseCholesky::Backend::Cholmod, {}, DirectOrdering::Mesh);
  EXPECT_LE(ours.factor().factor_nonzeros(), 1.25 * cholmod.factor().factor_nonzeros());
}

TEST(Ordering, AutoOrdersLargeBilaplacianFreeSetsByTheMeshAndAnalyzesOnce) {
  if (!need_mesh_ordering()) GTEST_SKIP() << "built without METIS";
  const Mesh mesh = make(icosphere(6));
  const FemOperators ops = build_cotan_operators(mesh);
  std::vector<int> vertices;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.5) vertices.push_back(v);
  ASSERT_GE(static_cast<int>(vertices.size()), kMeshOrderingFrom);
  const PdeCoefficients c{.g0 = 0, .g1 = 0, .g2 = 1};
  const SteadyDirectSolver automatic(mesh, ops, c, vertices);
  const SteadyDirectSolver mesh_order(mesh, ops, c, vertices, SparseCholesky::Backend::Auto, {},
                                      DirectOrdering::MeshSplit);
  const SteadyDirectSolver mesh_one(mesh, ops, c, vertices, SparseCholesky::Backend::Auto, {}, DirectOrdering::Mesh);
  const SteadyDirectSolver cholmod(mesh, ops, c, vertices, SparseCholesky::Backend::Auto, {}, DirectOrdering::Cholmod);
  EXPECT_EQ(automatic.factor().factor_nonzeros(), mesh_order.factor().factor_nonzeros());
  EXPECT_NE(automatic.factor().factor_nonzeros(), cholmod.factor().factor_nonzeros());
  EXPECT_NE(mesh_one.factor().factor_nonzeros(), automatic.factor().factor_nonzeros());  // one factor, not split
  EXPECT_EQ(automatic.factor().analyses(), 1);
  // K alone keeps CHOLMOD's ordering at any size.
  const PdeCoefficients membrane{.g0 = 0, .g1 = 1, .g2 = 0};
  const SteadyDirectSolver membrane_auto(mesh, ops, membrane, vertices);
  const SteadyDirectSolver membrane_cholmod(mesh, ops, membrane, vertices, SparseCholesky::Backend::Auto, {},
                                            DirectOrdering::Cholmod);
  EXPECT_EQ(membrane_auto.factor().factor_nonzeros(), membrane_cholmod.factor().factor_nonzeros());
  // A small free set keeps CHOLMOD's ordering.
  const std::vector<int> small(vertices.begin(), vertices.begin() + 3000);
  const SteadyDirectSolver small_auto(mesh, ops, c, small);
  const SteadyDirectSolver small_cholmod(mesh, ops, c, small, SparseCholesky::Backend::Auto, {},
                                         DirectOrdering::Cholmod);
  EXPECT_EQ(small_auto.factor().factor_nonzeros(), small_cholmod.factor().factor_nonzeros());
}

TEST(Ordering, BadMeshOrderingRequestsAndGivenOrdersAreRefusedInWords) {
  const Mesh mesh = make(icosphere(2));
  auto message = [&](const std::vector<int>& v, const MeshOrderingParams& p) {
    return refusal<InputError>([&] { (void)mesh_nested_dissection_order(mesh, v, p); });
  };
  EXPECT_NE(message({1, 2, 1}, {}).find("vertex 1 is listed twice"), std::string::npos);
  EXPECT_NE(message({1, mesh.num_vertices()}, {}).find("does not exist"), std::string::npos);
  EXPECT_NE(message({1, 2}, {.separator_hops = 3}).find("separator_hops"), std::string::npos);
  EXPECT_NE(message({1, 2}, {.patch_size = 0}).find("patch_size"), std::string::npos);
  EXPECT_TRUE(mesh_nested_dissection_order(mesh, {}).empty());
  SparseCholesky chol;
  auto given = [&](std::vector<int> order) { return refusal<SolverError>([&] { chol.set_order(std::move(order)); }); };
  EXPECT_NE(given({0, 2, 2}).find("appears twice"), std::string::npos);
  EXPECT_NE(given({0, 3, 1}).find("out of range"), std::string::npos);
  EXPECT_EQ(given({2, 0, 1}), "accepted");
  Eigen::SparseMatrix<double> A(2, 2);
  A.insert(0, 0) = 2;
  A.insert(1, 1) = 3;
  A.makeCompressed();
  if (SparseCholesky::cholmod_available()) {
    SparseCholesky cholmod(SparseCholesky::Backend::Cholmod);
    cholmod.set_order({2, 0, 1});
    try {
      cholmod.factorize(A);
      ADD_FAILURE() << "an order of 3 rows factored a 2 x 2 matrix";
    } catch (const SolverError& e) {
      EXPECT_NE(std::string(e.what()).find("3 rows, the matrix 2"), std::string::npos) << e.what();
    }
  }
}

TEST(Ordering, SplitFactorInTheMeshOrderSolvesAsOneFactorOnOneAndTwoThreads) {
  if (!need_mesh_ordering()) GTEST_SKIP() << "built without METIS";
  if (!SparseCholesky::cholmod_available()) GTEST_SKIP() << "the split factor needs CHOLMOD";
  const Mesh mesh = make(icosphere(5));
  const FemOperators ops = build_cotan_operators(mesh);
  std::vector<int> vertices;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.8) vertices.push_back(v);
  const PdeCoefficients c{.g0 = 0, .g1 = 0.5, .g2 = 1};
  const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, c, vertices);
  NestedDissection nd = mesh_nested_dissection(mesh, vertices);
  ASSERT_GT(nd.parts[0], 1000u);
  ASSERT_GT(nd.parts[1], 1000u);
  ASSERT_LT(nd.parts[0] + nd.parts[1], vertices.size());
  std::vector<int> row(static_cast<std::size_t>(mesh.num_vertices()), -1);
  for (std::size_t k = 0; k < vertices.size(); ++k) row[static_cast<std::size_t>(vertices[k])] = static_cast<int>(k);
  for (int& v : nd.order) v = row[static_cast<std::size_t>(v)];
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A.rows(), 3);
  SparseCholesky one_factor(SparseCholesky::Backend::Cholmod);
  one_factor.factorize(A);
  const Eigen::MatrixXd reference = one_factor.solve(B);
  const int limit = max_threads();
  Eigen::MatrixXd x[2];
  for (const int threads : {1, 2}) {
    set_max_threads(threads);
    SparseCholesky split(SparseCholesky::Backend::Cholmod);
    split.set_order(nd.order, nd.parts[0], nd.parts[1]);
    split.factorize(A);
    x[threads - 1] = split.solve(B);
    EXPECT_EQ(split.pivot_ratio(), 0);  // not computed for a split factor
    EXPECT_GT(split.factor_nonzeros(), 0);
  }
  set_max_threads(limit);
  EXPECT_LE((x[1] - reference).norm(), 1e-10 * reference.norm());
  EXPECT_EQ(x[0], x[1]) << "the split factor's answer depends on the thread count";
  // Parts that leave no separator, or one part alone, are refused.
  SparseCholesky bad;
  EXPECT_THROW(bad.set_order(nd.order, nd.order.size() - 1, 1), SolverError);
  EXPECT_THROW(bad.set_order(nd.order, 10, 0), SolverError);
}

TEST(Ordering, AReusedOrderKeepsTheRestsOrderAppendsNewVerticesAndKeepsItsFill) {
  if (!need_mesh_ordering()) GTEST_SKIP() << "built without METIS";
  // A free set of a 40k sphere, ordered by the mesh (split at the top), then changed by
  // 60 vertices: 40 held (dropped) and 20 released (added).
  const Mesh mesh = make(icosphere(6));
  const FemOperators ops = build_cotan_operators(mesh);
  const PdeCoefficients c{.g0 = 0, .g1 = 0, .g2 = 1};
  std::vector<int> before, after;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.6) before.push_back(v);
  ASSERT_GE(static_cast<int>(before.size()), kMeshOrderingFrom);
  const SteadyDirectSolver first(mesh, ops, c, before);
  const NestedDissection last = first.vertex_order();
  ASSERT_EQ(last.order.size(), before.size());
  ASSERT_GT(last.parts[1], 0u) << "the first factor is split";
  std::vector<char> in(static_cast<std::size_t>(mesh.num_vertices()), 0), held_now(in.size(), 0);
  for (int v : before) in[static_cast<std::size_t>(v)] = 1;
  std::mt19937 random(5);
  std::vector<int> released;
  for (int n = 0; n < 40;) {  // held now
    const int v = before[random() % before.size()];
    if (!held_now[static_cast<std::size_t>(v)]) held_now[static_cast<std::size_t>(v)] = 1, ++n;
  }
  for (int v = 0; v < mesh.num_vertices() && released.size() < 20; ++v)
    if (!in[static_cast<std::size_t>(v)] && mesh.positions()(v, 2) > -0.7) released.push_back(v);
  ASSERT_EQ(released.size(), 20u);
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if ((in[static_cast<std::size_t>(v)] && !held_now[static_cast<std::size_t>(v)]) ||
        std::find(released.begin(), released.end(), v) != released.end())
      after.push_back(v);
  int changed = 0;
  const NestedDissection reused = reuse_ordering(last, after, mesh.num_vertices(), &changed);
  EXPECT_EQ(changed, 60);
  // A permutation of the new set: the kept vertices in the last order, the new ones last.
  std::vector<int> expected;
  for (int v : last.order)
    if (!held_now[static_cast<std::size_t>(v)]) expected.push_back(v);
  expected.insert(expected.end(), released.begin(), released.end());
  EXPECT_EQ(reused.order, expected);
  std::size_t kept[2] = {0, 0};
  for (std::size_t k = 0; k < last.parts[0] + last.parts[1]; ++k)
    kept[k < last.parts[0] ? 0 : 1] += !held_now[static_cast<std::size_t>(last.order[k])];
  EXPECT_EQ(reused.parts[0], kept[0]);
  EXPECT_EQ(reused.parts[1], kept[1]);
  // Its parts stay uncoupled in the new matrix.
  const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, c, after);
  std::vector<int> row(static_cast<std::size_t>(mesh.num_vertices()), -1), part_of(after.size(), 2);
  for (std::size_t k = 0; k < after.size(); ++k) row[static_cast<std::size_t>(after[k])] = static_cast<int>(k);
  for (std::size_t k = 0; k < reused.parts[0] + reused.parts[1]; ++k)
    part_of[static_cast<std::size_t>(row[static_cast<std::size_t>(reused.order[k])])] = k < reused.parts[0] ? 0 : 1;
  int coupled = 0;
  for (Eigen::Index j = 0; j < A.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
      coupled += part_of[static_cast<std::size_t>(it.row())] + part_of[static_cast<std::size_t>(j)] == 1;
  EXPECT_EQ(coupled, 0);
  // The factor in the reused order: the same answer as a fresh mesh order, and fill
  // within 2 % of it (measured: docs/solvers-measurements.md).
  const SteadyDirectSolver fresh(mesh, ops, c, after);
  const SteadyDirectSolver again(mesh, ops, c, after, SparseCholesky::Backend::Auto, {}, DirectOrdering::Auto, &reused);
  Field u = Field::Zero(mesh.num_vertices(), 1);
  for (int v = 0; v < mesh.num_vertices(); ++v) u(v, 0) = mesh.positions()(v, 0) * mesh.positions()(v, 1);
  const Field x = again.solve(u), y = fresh.solve(u);
  EXPECT_LE((x - y).norm(), 1e-10 * y.norm());
  const double fill = again.factor().factor_nonzeros(), fresh_fill = fresh.factor().factor_nonzeros();
  std::printf("factor nonzeros: reused order %.0f, fresh mesh order %.0f (%.4fx)\n", fill, fresh_fill,
              fill / fresh_fill);
  EXPECT_LE(fill, 1.02 * fresh_fill);
  EXPECT_EQ(again.vertex_order().order, reused.order);
  // Refused in words: a vertex out of range or repeated, an order of another set.
  EXPECT_NE(refusal<InputError>([&] {
              (void)reuse_ordering(last, {0, 0}, mesh.num_vertices());
            }).find("listed twice"),
            std::string::npos);
  EXPECT_NE(refusal<InputError>([&] { (void)reuse_ordering(last, {-1}, mesh.num_vertices()); }).find("does not exist"),
            std::string::npos);
  EXPECT_NE(refusal<InputError>([&] {
              (void)SteadyDirectSolver(mesh, ops, c, before, SparseCholesky::Backend::Auto, {}, DirectOrdering::Auto,
                                       &reused);
            }).find("given order"),
            std::string::npos);
}
