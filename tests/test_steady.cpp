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
#include "../src/pde/mixed_bilaplacian.h"
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

TEST(Steady, BilaplacianReproducesLinearFieldsExactly) {
  const GeneratedMesh g = test::jittered_plane(16, 0.015, 11);
  const Mesh m = make(g);
  const FemOperators ops = build_cotan_operators(m);
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
  const FemOperators ops = build_cotan_operators(m);
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
  const FemOperators ops = build_cotan_operators(m);
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

TEST(Steady, AssembledMatrixIsThePrincipalBlockOfTheWholeMeshProduct) {
  // Independent: g0 M + g1 K + g2 K D K from Eigen's sparse products over the whole
  // mesh, then the rows and columns of the free vertices in the order given. Below and
  // above the size where the columns are assembled on several threads, in a shuffled
  // order; every column's row indices strictly increasing (CHOLMOD and the leading-block
  // factors read them so).
  const Mesh m = bumpy_sphere(5);
  const FemOperators ops = build_cotan_operators(m);
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

TEST(Steady, EverySolverRunsThroughSolveSteadyAndNonConvergenceIsAStatus) {
  // A cap of the icosphere held at a smooth field, the rest free: the bi-Laplacian
  // problem every application solves, by each solver through the one entry point.
  const auto g = icosphere(3);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  Field u = Field::Zero(mesh.num_vertices(), 3);
  std::vector<int> free;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (g.V(v, 2) < -0.5)
      u.row(v) = g.V.row(v) * 0.1;  // held
    else
      free.push_back(v);
  }
  const PdeCoefficients coef{.g0 = 0, .g1 = 0, .g2 = 1};
  const SteadySolveResult direct = solve_steady(mesh, ops, coef, free, u, SteadySolver::Direct);
  EXPECT_TRUE(direct.converged);
  const double scale = direct.values.cwiseAbs().maxCoeff();
  for (const SteadySolver s : {SteadySolver::Iterative, SteadySolver::Global, SteadySolver::Auto}) {
    const SteadySolveResult r = solve_steady(mesh, ops, coef, free, u, s, kAutoGlobalFromFreeVertices,
                                             CgOptions{.tolerance = 1e-12, .max_iterations = 100000});
    EXPECT_TRUE(r.converged) << to_string(s) << ": " << r.message;
    EXPECT_EQ(r.solver, s == SteadySolver::Auto ? SteadySolver::Direct : s);
    EXPECT_LE((r.values - direct.values).cwiseAbs().maxCoeff() / scale, 1e-6) << to_string(s);
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (g.V(v, 2) < -0.5) {
        ASSERT_EQ(r.values.row(v), u.row(v)) << "held vertex " << v << " moved";
      }
  }
  // Iterative stopped after 5 iterations: a status, the last iterate, no exception.
  const SteadySolveResult cut = solve_steady(mesh, ops, coef, free, u, SteadySolver::Iterative,
                                             kAutoGlobalFromFreeVertices, CgOptions{.max_iterations = 5});
  EXPECT_FALSE(cut.converged);
  EXPECT_EQ(cut.iterations, 5);
  EXPECT_NE(cut.message.find("no convergence in 5 iterations"), std::string::npos) << cut.message;
  EXPECT_EQ(cut.cg().status, CgStatus::MaxIterations);
  EXPECT_TRUE(cut.values.allFinite());
  // And so in the applications that take the solver: interpolate and fair.
  InterpolationParams ip;
  ip.solver = SteadySolver::Iterative;
  ip.cg = CgOptions{.max_iterations = 3};
  const InterpolationResult ir =
      interpolate(mesh, ops, FieldKind::Scalar, {{0, Eigen::VectorXd::Ones(1)}, {7, Eigen::VectorXd::Zero(1)}}, ip);
  EXPECT_FALSE(ir.cg.converged());
  EXPECT_EQ(ir.cg.iterations, 3);
  FairParams fp;
  fp.solver = SteadySolver::Iterative;
  fp.cg = CgOptions{.max_iterations = 3};
  std::vector<int> fixed;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (g.V(v, 2) < 0) fixed.push_back(v);
  const FairResult fr = fair(mesh, fixed, fp);
  EXPECT_FALSE(fr.converged);
  EXPECT_NE(fr.message.find("no convergence"), std::string::npos) << fr.message;
}

// The bi-Laplacian's free block inverted through the Laplacian's factor (the mixed
// form, pde/mixed_bilaplacian.h) against K D K's own factor: the same answers, the same
// products and couplings, on a closed mesh, an open one (natural boundary), and one
// with an unreferenced vertex (zero mass: D is 0 there and it is neither free nor held).
TEST(MixedBilaplacian, EqualsTheBilaplaciansOwnFactorOnClosedAndOpenMeshes) {
  struct Case {
    std::string name;
    GeneratedMesh g;
  };
  std::vector<Case> cases{{"icosphere", icosphere(4)}, {"plane", plane_grid(40, 30, 2.0, 1.5)}};
  {
    GeneratedMesh loose = icosphere(3);
    loose.V.conservativeResize(loose.V.rows() + 1, 3);
    loose.V.row(loose.V.rows() - 1) = Eigen::RowVector3d(3, 0, 0);  // in no triangle
    cases.push_back({"icosphere with an unreferenced vertex", loose});
  }
  std::mt19937 rng(11);
  for (Case& c : cases) {
    // Jitter the plane so that K has no exact symmetries and some obtuse angles.
    if (c.name == "plane") {
      std::uniform_real_distribution<double> jitter(-0.012, 0.012);
      for (Eigen::Index v = 0; v < c.g.V.rows(); ++v)
        c.g.V.row(v).head<2>() += Eigen::RowVector2d(jitter(rng), jitter(rng));
    }
    const Mesh mesh(c.g.V, c.g.F);
    const FemOperators ops = build_cotan_operators(mesh);
    const int nv = mesh.num_vertices();
    std::uniform_int_distribution<int> vertex(0, nv - 1);
    std::vector<char> held(static_cast<std::size_t>(nv), 0);
    for (int k = 0; k < 6; ++k) held[static_cast<std::size_t>(vertex(rng))] = 1;
    std::vector<int> free;
    int a_held = -1, held_with_area = 0;
    for (int v = 0; v < nv; ++v) {
      if (held[static_cast<std::size_t>(v)] && ops.mass[v] > 0) {
        a_held = v;
        ++held_with_area;
      }
      if (!held[static_cast<std::size_t>(v)] && ops.mass[v] > 0) free.push_back(v);
    }
    const double g2 = 2.5;
    const SteadyDirectSolver direct(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = g2}, free,
                                    SparseCholesky::Backend::Auto, Eigen::VectorXd(), DirectOrdering::Cholmod);
    const detail::MixedBilaplacianSolver mixed(mesh, ops, g2, free);
    ASSERT_EQ(mixed.num_free(), direct.num_free()) << c.name;
    EXPECT_EQ(mixed.num_held(), held_with_area) << c.name;  // the unreferenced vertex is neither
    // The factors: the Laplacian's has fewer nonzeros than K D K's.
    EXPECT_LT(mixed.factor_nonzeros(), direct.factor().factor_nonzeros()) << c.name;

    Eigen::MatrixXd B = Eigen::MatrixXd::Random(direct.num_free(), 3);
    B.col(2) = direct.coupling(a_held);  // a held vertex's load, as InterpolationSolver solves
    // Same couplings, same products (the assembled K D K of the direct solver).
    EXPECT_LT((mixed.coupling(a_held) - direct.coupling(a_held)).cwiseAbs().maxCoeff(),
              1e-12 * direct.coupling(a_held).cwiseAbs().maxCoeff())
        << c.name;
    const Eigen::MatrixXd Xd = direct.solve_rhs(B);
    EXPECT_LT((mixed.multiply(Xd) - direct.matrix() * Xd).norm(), 1e-12 * (direct.matrix() * Xd).norm()) << c.name;
    for (const bool refined : {false, true}) {
      const Eigen::MatrixXd Xm = refined ? mixed.solve_rhs(B) : mixed.solve(B);
      for (Eigen::Index k = 0; k < B.cols(); ++k) {
        const double scale = Xd.col(k).cwiseAbs().maxCoeff();
        EXPECT_LT((Xm.col(k) - Xd.col(k)).cwiseAbs().maxCoeff(), 1e-10 * scale)
            << c.name << ", column " << k << (refined ? ", refined" : ", plain");
        EXPECT_LT((B.col(k) - mixed.multiply(Xm.col(k))).norm(), 1e-10 * B.col(k).norm()) << c.name;
      }
    }
    // More columns than the sweeps take at once: the same as one at a time.
    const Eigen::MatrixXd wide = Eigen::MatrixXd::Random(direct.num_free(), 9);
    const Eigen::MatrixXd Xw = mixed.solve(wide);
    EXPECT_LT((Xw.col(8) - mixed.solve(wide.col(8))).cwiseAbs().maxCoeff(), 1e-13 * Xw.col(8).cwiseAbs().maxCoeff())
        << c.name;
  }
}
