// solvers/direct.h and solvers/refinement.h: sparse Cholesky backends, written-out
// sweeps, pivots, conditioning, leading-block and split factors, refinement.
#include <gtest/gtest.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <limits>
#include <numeric>
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

// ---- direct path -------------------------------------------------------------

TEST(Direct, BackendsAgreeReuseTheAnalysisAndRejectIndefinite) {
  const Mesh m = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(m);
  Eigen::SparseMatrix<double> A = stiffness_matrix(m, ops) + mass_matrix(ops);  // SPD
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(m.num_vertices(), 3);
  SparseCholesky eig(SparseCholesky::Backend::Eigen);
  eig.factorize(A);
  const Eigen::MatrixXd xe = eig.solve(B);
  EXPECT_LE((A * xe - B).norm(), 1e-10 * B.norm());
  if (SparseCholesky::cholmod_available()) {
    SparseCholesky chol(SparseCholesky::Backend::Cholmod);
    chol.factorize(A);
    EXPECT_LE((chol.solve(B) - xe).norm(), 1e-9 * xe.norm());
    A *= 2.0;  // same pattern, new values: numeric factorization only
    chol.factorize(A);
    EXPECT_EQ(chol.analyses(), 1);
    EXPECT_EQ(chol.factorizations(), 2);
    EXPECT_LE((chol.solve(B) - 0.5 * xe).norm(), 1e-9 * xe.norm());
  }
  Eigen::SparseMatrix<double> bad = stiffness_matrix(m, ops);
  bad.coeffRef(3, 3) = -10;
  for (const auto b : {SparseCholesky::Backend::Eigen, SparseCholesky::Backend::Auto}) {
    SparseCholesky s(b);
    try {
      s.factorize(bad);
      FAIL() << "indefinite matrix accepted";
    } catch (const SolverError& e) {
      EXPECT_NE(std::string(e.what()).find("not positive definite"), std::string::npos) << e.what();
    }
  }
}

// Every backend refuses in words what it cannot do: a solve before a factor, a
// right-hand side of the wrong height, CHOLMOD in a build without it.
TEST(Direct, EveryBackendRefusesBadRequestsInWords) {
  const Mesh m = make(icosphere(2));
  const FemOperators ops = build_cotan_operators(m);
  const Eigen::SparseMatrix<double> A = stiffness_matrix(m, ops) + mass_matrix(ops);
  auto refused = [](auto&& call, const char* words) {
    try {
      call();
      ADD_FAILURE() << "accepted; expected an error with '" << words << "'";
    } catch (const SolverError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  std::vector<SparseCholesky::Backend> backends{SparseCholesky::Backend::Eigen};
  if (SparseCholesky::cholmod_available()) {
    backends.push_back(SparseCholesky::Backend::Cholmod);
  } else {
    refused([] { SparseCholesky s(SparseCholesky::Backend::Cholmod); }, "built without it");
    refused([] { LeadingBlockCholesky s(SparseCholesky::Backend::Cholmod); }, "built without it");
    refused([&] { SplitCholesky().factorize(A, 10, 10); }, "needs CHOLMOD");
  }
  for (const auto b : backends) {
    SparseCholesky s(b);
    refused([&] { s.solve(Eigen::MatrixXd::Ones(A.rows(), 1)); }, "before a successful factorize");
    s.factorize(A);
    refused([&] { s.solve(Eigen::MatrixXd::Ones(A.rows() + 1, 2)); }, "rows for a factor of");
    EXPECT_LE((A * s.solve(Eigen::MatrixXd::Ones(A.rows(), 2)) - Eigen::MatrixXd::Ones(A.rows(), 2)).norm(), 1e-9)
        << s.backend_name();
  }
}

TEST(Direct, PivotRatioIsTheSmallestOverTheLargestPivot) {
  // A diagonal matrix's pivots are its entries (LDL^T and LL^T alike): 0.5 / 8. With
  // the 2 x 2 block [1 1; 1 1 + 1e-14] in place of its first two rows, one pivot is
  // about 1e-14 (in either order of the two rows), so the ratio is about 1.25e-15: a
  // matrix this close to singular factors without a complaint, and the ratio shows it.
  // K + M of a mesh is far from that.
  const Mesh m = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(m);
  const Eigen::SparseMatrix<double> KM = stiffness_matrix(m, ops) + mass_matrix(ops);
  const Eigen::Index n = KM.rows();
  Eigen::SparseMatrix<double> diag(n, n), near_singular(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double d = i == 5 ? 0.5 : (i == 9 ? 8.0 : 1.0 + (i % 3));
    diag.insert(i, i) = d;
    if (i >= 2) near_singular.insert(i, i) = d;
  }
  near_singular.insert(0, 0) = 1;
  near_singular.insert(0, 1) = 1;
  near_singular.insert(1, 0) = 1;
  near_singular.insert(1, 1) = 1 + 1e-14;
  std::vector<SparseCholesky::Backend> backends{SparseCholesky::Backend::Eigen};
  if (SparseCholesky::cholmod_available()) backends.push_back(SparseCholesky::Backend::Cholmod);
  for (const auto backend : backends) {
    SparseCholesky s(backend);
    SCOPED_TRACE(s.backend_name());
    EXPECT_EQ(s.pivot_ratio(), 0);  // nothing factored yet
    s.factorize(diag);
    EXPECT_NEAR(s.pivot_ratio(), 0.5 / 8.0, 1e-15);
    s.factorize(near_singular);
    EXPECT_GT(s.pivot_ratio(), 0.5e-15);
    EXPECT_LT(s.pivot_ratio(), 2e-15);
    s.factorize(KM);
    EXPECT_GT(s.pivot_ratio(), 1e-6);
  }
}

TEST(Direct, SteadySolveMatchesConjugateGradientsAndReusesItsFactor) {
  Mesh m;
  if (!test::load_data("bunny-3k.off", m)) return;
  const FemOperators ops = build_cotan_operators(m);
  const std::vector<InterpolationConstraint> cons = {{10, Eigen::VectorXd::Constant(1, 1.0)},
                                                     {1000, Eigen::VectorXd::Constant(1, -2.0)},
                                                     {2500, Eigen::VectorXd::Constant(1, 0.5)}};
  for (const auto& [g1, g2] : {std::pair{1.0, 0.0}, {0.0, 1.0}, {1.0, 0.1}}) {
    const auto direct = interpolate(m, ops, FieldKind::Scalar, cons, InterpolationParams{.g1 = g1, .g2 = g2});
    const auto cg = interpolate(m, ops, FieldKind::Scalar, cons,
                                InterpolationParams{.g1 = g1, .g2 = g2, .solver = SteadySolver::Iterative});
    EXPECT_LE(direct.cg.relative_residual, 1e-10);
    EXPECT_LE((direct.values - cg.values).cwiseAbs().maxCoeff(), 1e-7 * cg.values.cwiseAbs().maxCoeff());
  }
  // One factor, many held values: a drag's handle moving step after step.
  std::vector<int> free;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (v != 10 && v != 1000) free.push_back(v);
  const SteadyDirectSolver s(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  Field u = Field::Zero(m.num_vertices(), 3);
  for (int k = 1; k <= 3; ++k) {
    u(10, 0) = 0.001 * k;
    const Field x = s.solve(u);
    EXPECT_EQ(x(10, 0), 0.001 * k);
    EXPECT_LE(s.last_relative_residual(), 1e-10);
  }
  EXPECT_EQ(s.factor().factorizations(), 1);
}

TEST(Direct, WrittenOutSweepsMatchCholmodsOwnOnOneAndTwoThreads) {
  if (!SparseCholesky::cholmod_available()) GTEST_SKIP() << "meshpde was built without CHOLMOD";
  // K + M on a 41k-vertex sphere (a factor large enough for the two-thread sweeps), on
  // two separate spheres (a forest: the split falls between the trees), and the
  // bi-Laplacian of a sphere with a cap held (larger supernodes).
  const Mesh one = make(icosphere(6)), two = two_spheres(5), cap = make(icosphere(5));
  const FemOperators o1 = build_cotan_operators(one), o2 = build_cotan_operators(two), o3 = build_cotan_operators(cap);
  std::vector<int> free;
  for (int v = 0; v < cap.num_vertices(); ++v)
    if (cap.positions()(v, 2) > -0.9) free.push_back(v);
  const std::vector<Eigen::SparseMatrix<double>> matrices{
      stiffness_matrix(one, o1) + mass_matrix(o1), stiffness_matrix(two, o2) + mass_matrix(o2),
      assemble_steady_matrix(cap, o3, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free)};
  const int limit = max_threads();
  for (const auto& A : matrices)
    for (const int columns : {1, 2, 3, 4, 6}) {  // six: cholmod_solve in both modes
      const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A.rows(), columns);
      SparseCholesky chol(SparseCholesky::Backend::Cholmod);
      chol.factorize(A);
      chol.set_sweeps(SparseCholesky::Sweeps::Cholmod);
      const Eigen::MatrixXd reference = chol.solve(B);
      chol.set_sweeps(SparseCholesky::Sweeps::WrittenOut);
      set_max_threads(2);
      const Eigen::MatrixXd x2 = chol.solve(B);
      set_max_threads(1);
      const Eigen::MatrixXd x1 = chol.solve(B);
      set_max_threads(limit);
      EXPECT_LE((x2 - reference).cwiseAbs().maxCoeff(), 1e-10 * reference.cwiseAbs().maxCoeff())
          << A.rows() << " rows, " << columns << " columns";
      EXPECT_LE((A * x2 - B).norm(), 1e-10 * B.norm());
      // The groups' updates of shared rows are buffered and added in order: the thread
      // count does not change a bit of the answer.
      EXPECT_EQ((x1 - x2).cwiseAbs().maxCoeff(), 0.0);
    }
  // Right-hand sides with a few nonzeros (a unit load, a vertex's coupling): the forward
  // sweep skips the supernodes they leave at zero, with the same answer.
  for (const auto& A : matrices) {
    const Eigen::Index n = A.rows();
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n, 3);
    B(n / 3, 0) = 1;
    B(0, 1) = 2;
    B(n - 1, 1) = -1;
    for (Eigen::Index i = n / 2; i < n / 2 + 7; ++i) B(i, 2) = 0.25 * static_cast<double>(i - n / 2 + 1);
    SparseCholesky chol(SparseCholesky::Backend::Cholmod);
    chol.factorize(A);
    chol.set_sweeps(SparseCholesky::Sweeps::Cholmod);
    const Eigen::MatrixXd reference = chol.solve(B);
    chol.set_sweeps(SparseCholesky::Sweeps::WrittenOut);
    for (const int threads : {1, 2}) {
      set_max_threads(threads);
      for (Eigen::Index c = 0; c < 3; ++c) {
        const Eigen::MatrixXd x = chol.solve(B.col(c));
        EXPECT_LE((x.col(0) - reference.col(c)).cwiseAbs().maxCoeff(), 1e-10 * reference.col(c).cwiseAbs().maxCoeff())
            << n << " rows, sparse column " << c << ", " << threads << " threads";
      }
    }
    set_max_threads(limit);
  }
  SparseCholesky chol;
  chol.factorize(matrices[0]);
  EXPECT_THROW(chol.solve(Eigen::MatrixXd::Ones(5, 1)), SolverError);
}

TEST(Direct, AFloatingPartIsNamed) {
  // Two separate spheres; only the first has a held vertex.
  const Mesh m = two_spheres(2);
  const int second = m.num_vertices() / 2;  // the first vertex of sphere 2
  const FemOperators ops = build_cotan_operators(m);
  std::vector<int> free;
  for (int v = 1; v < m.num_vertices(); ++v) free.push_back(v);
  try {
    SteadyDirectSolver s(m, ops, PdeCoefficients{.g0 = 0, .g1 = 1, .g2 = 0}, free);
    FAIL() << "floating part accepted";
  } catch (const SolverError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("touches no held vertex"), std::string::npos) << msg;
    EXPECT_NE(msg.find(std::to_string(second)), std::string::npos) << msg;  // names a vertex of sphere 2
  }
  // With a foundation term the floating part is determined.
  EXPECT_NO_THROW(SteadyDirectSolver(m, ops, PdeCoefficients{.g0 = 1, .g1 = 1, .g2 = 0}, free));
}

// The Laplacian-squared preconditioner keeps iteration counts nearly flat under
// refinement (Jacobi-CG's grow like h^-2) and agrees with the direct solve.

TEST(Refinement, StopsWhenBackwardStableAndRefinesAnInexactSolve) {
  // A shifted 1-D Laplacian: SPD, condition number about 3,000.
  const int n = 200;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 2.001);
    if (i > 0) {
      t.emplace_back(i, i - 1, -1.0);
      t.emplace_back(i - 1, i, -1.0);
    }
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  const double a_norm_inf = 4.001;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1, 1);
  const Eigen::MatrixXd b = Eigen::MatrixXd::NullaryExpr(n, 2, [&] { return uni(rng); });
  auto multiply = [&](const Eigen::MatrixXd& x) -> Eigen::MatrixXd { return A * x; };
  const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> exact(A);
  // With tolerance 0 only the backward-error test can stop it: a Cholesky solve of a
  // well-conditioned system is already backward stable, so no step is spent.
  const RefinedSolve s = refined_solve(
      b, [&](const Eigen::MatrixXd& r) -> Eigen::MatrixXd { return exact.solve(r); }, multiply, a_norm_inf, 0.0, 5);
  EXPECT_EQ(s.steps, 0);
  EXPECT_LE(s.backward_error, kStableBackwardError);
  // The factor of a slightly different matrix (shift 1e-5 against a smallest eigenvalue
  // of 1.25e-3): its first answer is visibly off, and refinement must recover the exact
  // one to the requested residual.
  Eigen::SparseMatrix<double> shifted = A;
  for (int i = 0; i < n; ++i) shifted.coeffRef(i, i) += 1e-5;
  const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> inexact(shifted);
  const RefinedSolve r = refined_solve(
      b, [&](const Eigen::MatrixXd& x) -> Eigen::MatrixXd { return inexact.solve(x); }, multiply, a_norm_inf, 1e-12,
      20);
  EXPECT_GE(r.steps, 2);
  EXPECT_LE(r.relative_residual, 1e-12);
  const Eigen::MatrixXd x = exact.solve(b);
  EXPECT_LE((r.x - x).norm(), 1e-9 * x.norm());
  EXPECT_GT((inexact.solve(b) - x).norm(), 1e-4 * x.norm());  // the unrefined answer was off
}

TEST(Refinement, PreconditionedCgConvergesWhereThePlainStepStalls) {
  // A factor of a matrix that differs from A in five diagonal entries (ten times
  // larger): A_^-1 A is the identity plus a rank-five term with eigenvalues down to
  // about 0.1. The plain step, x += A_^-1 r, does not lower the residual's norm (here
  // it stops after its first step, at 0.95 of |b|); CG preconditioned by the same
  // factor needs six steps, one solve and one product each, to 1e-13.
  const int n = 300;
  std::vector<Eigen::Triplet<double>> t, u;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 2.0001);
    u.emplace_back(i, i, (i % 60 == 10) ? 20.0 : 2.0001);
    if (i > 0)
      for (auto* list : {&t, &u}) {
        list->emplace_back(i, i - 1, -1.0);
        list->emplace_back(i - 1, i, -1.0);
      }
  }
  Eigen::SparseMatrix<double> A(n, n), approx(n, n);
  A.setFromTriplets(t.begin(), t.end());
  approx.setFromTriplets(u.begin(), u.end());
  const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> factor(approx), exact(A);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uni(-1, 1);
  const Eigen::MatrixXd b = Eigen::MatrixXd::NullaryExpr(n, 3, [&] { return uni(rng); });
  auto solve = [&](const Eigen::MatrixXd& r) -> Eigen::MatrixXd { return factor.solve(r); };
  auto multiply = [&](const Eigen::MatrixXd& x) -> Eigen::MatrixXd { return A * x; };
  const Eigen::MatrixXd x = exact.solve(b);
  const RefinedSolve plain = refined_solve(b, solve, multiply, 4.0002, 1e-10, 30);
  const RefinedSolve cg = pcg_refined_solve(b, solve, multiply, 4.0002, 1e-10, 30);
  EXPECT_GT(plain.relative_residual, 1e-6) << plain.steps << " plain steps";
  EXPECT_LE(cg.relative_residual, 1e-9);
  EXPECT_LE(cg.steps, 10);
  EXPECT_LE((cg.x - x).norm(), 1e-7 * x.norm());
  // A first answer within the tolerance takes no step.
  const RefinedSolve at_once = pcg_refined_solve(
      b, [&](const Eigen::MatrixXd& r) -> Eigen::MatrixXd { return exact.solve(r); }, multiply, 4.0002, 1e-10, 30);
  EXPECT_EQ(at_once.steps, 0);
  EXPECT_LE(at_once.relative_residual, 1e-10);
}

TEST(Direct, ConditioningEstimateMatchesTheTrueConditionNumber) {
  // A small system whose 1-norm condition number is computed exactly from the dense
  // inverse: the estimate is a lower bound within a factor of 3 (Higham's experience).
  const GeneratedMesh g = icosphere(2);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  std::vector<int> free;
  for (int v = 1; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 2) > -0.5) free.push_back(v);
  const SteadyDirectSolver s(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  const Eigen::MatrixXd A = Eigen::MatrixXd(s.matrix());
  const Eigen::MatrixXd Ainv = A.inverse();
  const double exact = A.cwiseAbs().colwise().sum().maxCoeff() * Ainv.cwiseAbs().colwise().sum().maxCoeff();
  const auto c = s.conditioning();
  EXPECT_LE(c.condition_1, exact * (1 + 1e-9));
  EXPECT_GE(c.condition_1, exact / 3);
  EXPECT_TRUE(c.sufficient) << c.message;
  EXPECT_TRUE(c.message.empty());
  // Asking for more than double precision can give is refused in words.
  const auto strict = s.conditioning(1e-18);
  EXPECT_FALSE(strict.sufficient);
  EXPECT_NE(strict.message.find("ill-conditioned"), std::string::npos);
}

TEST(Direct, LeadingBlockSolvesMatchFreshFactorizationsOfTheBlocks) {
  const Mesh mesh = make(icosphere(6));
  const FemOperators ops = build_cotan_operators(mesh);
  int top = 0;
  mesh.positions().col(2).maxCoeff(&top);
  const std::vector<int> order = nested_dissection_order(mesh, geodesic_ball(mesh, top, 0.6));
  const Eigen::SparseMatrix<double> A =
      assemble_steady_matrix(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, order);
  const auto N = A.rows();
  ASSERT_GT(N, 3000);
  std::vector<SparseCholesky::Backend> backends{SparseCholesky::Backend::Eigen};
  if (SparseCholesky::cholmod_available()) backends.push_back(SparseCholesky::Backend::Cholmod);
  for (const auto backend : backends) {
    LeadingBlockCholesky f(backend);
    f.factorize(A);
    EXPECT_EQ(f.size(), N);
    EXPECT_GT(f.factor_nonzeros(), static_cast<double>(A.nonZeros()) / 2);
    for (const Eigen::Index n : {N, N - 150, N / 2}) {
      // The leading block by itself, factored afresh by the general solver.
      const Eigen::SparseMatrix<double> block = A.topLeftCorner(n, n);
      SparseCholesky fresh;
      fresh.factorize(block);
      const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 3);
      const Eigen::MatrixXd x = f.solve_leading(B), y = fresh.solve(B);
      EXPECT_LE((x - y).norm(), 1e-8 * y.norm()) << f.backend_name() << " block " << n;
      EXPECT_LE((block * x - B).norm(), 1e-8 * B.norm()) << f.backend_name() << " block " << n;
    }
    EXPECT_THROW((void)f.solve_leading(Eigen::MatrixXd::Zero(N + 1, 1)), SolverError);
    Eigen::SparseMatrix<double> bad = A;
    bad.coeffRef(7, 7) = -1;
    try {
      f.factorize(bad);
      FAIL() << "indefinite matrix accepted";
    } catch (const SolverError& e) {
      EXPECT_NE(std::string(e.what()).find("not positive definite"), std::string::npos) << e.what();
    }
    EXPECT_THROW((void)f.solve_leading(Eigen::MatrixXd::Zero(N, 1)), SolverError);  // no factor now
  }
}

TEST(Direct, SplitFactorMatchesOneFactorOfTheWholeAndRefusesCoupledParts) {
  if (!SplitCholesky::available()) GTEST_SKIP() << "built without CHOLMOD: no split factor";
  const Mesh mesh = make(icosphere(6));
  const FemOperators ops = build_cotan_operators(mesh);
  const NestedDissection nd = nested_dissection(mesh, ordering_region(mesh));
  ASSERT_GT(nd.parts[0], 1000u);
  ASSERT_GT(nd.parts[1], 1000u);
  const auto n1 = static_cast<Eigen::Index>(nd.parts[0]), n2 = static_cast<Eigen::Index>(nd.parts[1]);
  const Eigen::SparseMatrix<double> A =
      assemble_steady_matrix(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, nd.order);
  // The two halves are uncoupled in K D K: the top separator is two layers wide.
  for (Eigen::Index j = 0; j < n1; ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
      ASSERT_FALSE(it.row() >= n1 && it.row() < n1 + n2) << "rows " << j << " and " << it.row() << " coupled";
  SplitCholesky split;
  split.factorize(A, n1, n2);
  EXPECT_EQ(split.size(), A.rows());
  LeadingBlockCholesky whole;
  whole.factorize(A);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A.rows(), 3);
  const Eigen::MatrixXd x = split.solve(B), y = whole.solve_leading(B);
  EXPECT_LE((x - y).norm(), 1e-9 * y.norm());
  EXPECT_LE((A * x - B).norm(), 1e-9 * B.norm());
  // Same answers on one thread (the parts one after the other).
  set_max_threads(1);
  SplitCholesky serial;
  serial.factorize(A, n1, n2);
  const Eigen::MatrixXd z = serial.solve(B);
  set_max_threads(0);
  EXPECT_LE((z - x).norm(), 1e-12 * x.norm());
  auto message = [&](const Eigen::SparseMatrix<double>& M, Eigen::Index p1, Eigen::Index p2) {
    return refusal<SolverError>([&] { SplitCholesky().factorize(M, p1, p2); });
  };
  EXPECT_NE(message(A, n1 + 50, n2 - 50).find("couple the two parts"), std::string::npos);
  EXPECT_NE(message(A, n1, A.rows() - n1).find("leave no separator"), std::string::npos);
  Eigen::SparseMatrix<double> bad = A;
  bad.coeffRef(A.rows() - 3, A.rows() - 3) = -1e3;  // a separator row: the Schur complement fails
  EXPECT_NE(message(bad, n1, n2).find("not positive definite"), std::string::npos);
  bad = A;
  bad.coeffRef(5, 5) = -1e3;  // a row of part 1: its CHOLMOD factor fails
  EXPECT_NE(message(bad, n1, n2).find("not positive definite"), std::string::npos);
}

TEST(Direct, SplitFactorInAGivenOrderEqualsTheSplitFactorOfThePermutedMatrix) {
  if (!SplitCholesky::available()) GTEST_SKIP() << "built without CHOLMOD: no split factor";
  const Mesh mesh = make(icosphere(5));
  const FemOperators ops = build_cotan_operators(mesh);
  const std::vector<int> region = ordering_region(mesh);
  const NestedDissection nd = nested_dissection(mesh, region);
  ASSERT_GT(nd.parts[1], 100u);
  const auto n1 = static_cast<Eigen::Index>(nd.parts[0]), n2 = static_cast<Eigen::Index>(nd.parts[1]);
  const PdeCoefficients c{.g0 = 0, .g1 = 0.1, .g2 = 1};
  // A in the region's own numbering (the order as rows of it), and A in the order.
  const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, c, region);
  const Eigen::SparseMatrix<double> ordered = assemble_steady_matrix(mesh, ops, c, nd.order);
  std::vector<int> row_of(static_cast<std::size_t>(mesh.num_vertices()), -1);
  for (std::size_t k = 0; k < region.size(); ++k) row_of[static_cast<std::size_t>(region[k])] = static_cast<int>(k);
  std::vector<int> order;
  for (int v : nd.order) order.push_back(row_of[static_cast<std::size_t>(v)]);
  ASSERT_NE(order, [&] {
    std::vector<int> identity(order.size());
    std::iota(identity.begin(), identity.end(), 0);
    return identity;
  }());
  SplitCholesky given, permuted;
  given.factorize(A, order, n1, n2);
  permuted.factorize(ordered, n1, n2);
  EXPECT_EQ(given.factor_nonzeros(), permuted.factor_nonzeros());
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A.rows(), 2);
  const Eigen::MatrixXd x = given.solve(B), y = permuted.solve(B);
  EXPECT_LE((x - y).norm(), 1e-12 * y.norm());
  // x solves A in the order's numbering: row k of x is row order[k] of A's unknowns.
  Eigen::MatrixXd b(A.rows(), 2), xa(A.rows(), 2);
  for (std::size_t k = 0; k < order.size(); ++k) {
    b.row(order[k]) = B.row(static_cast<Eigen::Index>(k));
    xa.row(order[k]) = x.row(static_cast<Eigen::Index>(k));
  }
  EXPECT_LE((A * xa - b).norm(), 1e-9 * b.norm());
  // Only A's lower triangle is read.
  const Eigen::SparseMatrix<double> lower = A.triangularView<Eigen::Lower>();
  SplitCholesky from_lower;
  from_lower.factorize(lower, order, n1, n2);
  EXPECT_LE((from_lower.solve(B) - x).norm(), 1e-14 * x.norm());
  // A bad order, in words.
  std::vector<int> twice = order;
  twice[1] = twice[0];
  EXPECT_NE(refusal<SolverError>([&] { SplitCholesky().factorize(A, twice, n1, n2); }).find("not a permutation"),
            std::string::npos);
  EXPECT_THROW(SplitCholesky().factorize(A, std::vector<int>(order.begin(), order.end() - 1), n1, n2), SolverError);
}
