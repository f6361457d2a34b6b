// pde/global_bilaplacian.h: the global steady solver and its preconditioners.
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

TEST(GlobalBilaplacian, IterationsStayFlatUnderRefinementAndMatchTheDirectSolve) {
  std::vector<int> iterations;
  for (int level : {3, 4, 5}) {
    const auto [m, ops, u, free] = global_problem(level);
    const GlobalBilaplacianResult r = solve_global_bilaplacian(
        m, ops, free, u, global_params(GlobalBilaplacianParams::Preconditioner::LaplacianFactor));
    ASSERT_TRUE(r.converged) << "level " << level;
    EXPECT_EQ(r.used, GlobalBilaplacianParams::Preconditioner::LaplacianFactor);
    EXPECT_EQ(r.multigrid_iterations, 0);
    iterations.push_back(r.iterations);
    // The factor of K_FF holds at least K_FF's lower triangle; the memory estimate
    // counts it at 12 bytes a nonzero.
    EXPECT_GE(r.factor_nonzeros, 4.0 * static_cast<double>(free.size()));
    EXPECT_GE(r.bytes_per_vertex, 12.0 * r.factor_nonzeros / m.num_vertices());
    const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, free);
    const Field x = direct.solve(u);
    EXPECT_LE((r.values - x).cwiseAbs().maxCoeff(), 1e-7 * x.cwiseAbs().maxCoeff()) << "level " << level;
  }
  // 16x the vertices from level 3 to 5; Jacobi-CG would need about 4x the iterations.
  EXPECT_LE(iterations[2], 2 * iterations[0]) << iterations[0] << " -> " << iterations[2];
  EXPECT_THROW(solve_global_bilaplacian(make(icosphere(1)), build_cotan_operators(make(icosphere(1))), {0},
                                        Field::Zero(42, 1), GlobalBilaplacianParams{.g2 = 0}),
               InputError);
  EXPECT_THROW(solve_global_bilaplacian(make(icosphere(1)), build_cotan_operators(make(icosphere(1))), {0},
                                        Field::Zero(42, 1), GlobalBilaplacianParams{.probe_iterations = 0}),
               InputError);
}

TEST(GlobalBilaplacian, AFloatingPartIsNamed) {
  // Two separate spheres, a vertex of the first held: the second has nothing to hold
  // it, and with either preconditioner the error names a vertex there.
  const Mesh m = two_spheres(3);
  const int second = m.num_vertices() / 2;  // sphere 2: vertices second .. 2 second - 1
  const FemOperators ops = build_cotan_operators(m);
  std::vector<int> free;
  for (int v = 1; v < m.num_vertices(); ++v) free.push_back(v);
  Field u = Field::Zero(m.num_vertices(), 1);
  u(0, 0) = 1;
  for (const auto pre :
       {GlobalBilaplacianParams::Preconditioner::Auto, GlobalBilaplacianParams::Preconditioner::LaplacianFactor}) {
    GlobalBilaplacianParams p;
    p.preconditioner = pre;
    try {
      (void)solve_global_bilaplacian(m, ops, free, u, p);
      ADD_FAILURE() << "a floating part was accepted";
    } catch (const SolverError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("touches no held vertex"), std::string::npos) << msg;
      const std::string part = std::to_string(second) + " free vertices (vertex " + std::to_string(second);
      EXPECT_NE(msg.find(part), std::string::npos) << msg;
    }
  }
}

TEST(GlobalBilaplacian, AutoKeepsTheMultigridOnWellShapedMeshes) {
  // The default rule on an icosphere: the multigrid's rate predicts about 20
  // iterations, so it finishes the solve, and the answer is the direct solve's.
  const auto [m, ops, u, free] = global_problem(5);
  const GlobalBilaplacianResult r =
      solve_global_bilaplacian(m, ops, free, u, global_params(GlobalBilaplacianParams::Preconditioner::Auto));
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.used, GlobalBilaplacianParams::Preconditioner::Multigrid);
  EXPECT_EQ(r.multigrid_iterations, r.iterations);
  EXPECT_GT(r.multigrid_predicted_iterations, 0);
  EXPECT_LE(r.multigrid_predicted_iterations, 50);
  EXPECT_GE(r.level_unknowns.size(), 2u);
  EXPECT_EQ(r.factor_nonzeros, 0);
  const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, free);
  const Field x = direct.solve(u);
  EXPECT_LE((r.values - x).cwiseAbs().maxCoeff(), 1e-7 * x.cwiseAbs().maxCoeff());
}

TEST(GlobalBilaplacian, AutoHandsBadlyShapedMeshesOnToTheFactor) {
  // An icosphere stretched 8x along x: long thin triangles, on which the multigrid's
  // coarse spaces are weak (hundreds of iterations, against about ten with the
  // Laplacian factor). The default rule sees the slow rate within a few iterations and
  // goes on from the multigrid's iterate with the factor, to the same answer.
  const auto [m, ops, u, free] = stretched_global_problem(4);
  GlobalBilaplacianParams p{.tolerance = 1e-10, .max_iterations = 2000};
  p.preconditioner = GlobalBilaplacianParams::Preconditioner::Multigrid;
  p.multigrid.coarsest_unknowns = kTestCoarsest;
  const GlobalBilaplacianResult mg = solve_global_bilaplacian(m, ops, free, u, p);
  ASSERT_TRUE(mg.converged);
  // The premise: a bad case for the multigrid, beyond what Auto lets it take (measured
  // 226 iterations at a relative residual of 1e-8).
  EXPECT_GT(mg.iterations, p.max_multigrid_iterations);
  p.preconditioner = GlobalBilaplacianParams::Preconditioner::Auto;
  const GlobalBilaplacianResult r = solve_global_bilaplacian(m, ops, free, u, p);
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.used, GlobalBilaplacianParams::Preconditioner::LaplacianFactor);
  EXPECT_GE(r.multigrid_iterations, p.probe_iterations);
  EXPECT_GT(r.multigrid_predicted_iterations, p.max_multigrid_iterations);
  EXPECT_GT(r.iterations, r.multigrid_iterations);
  EXPECT_LT(r.iterations, 50);
  EXPECT_GT(r.factor_nonzeros, 0);
  const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  const Field x = direct.solve(u);
  EXPECT_LE((r.values - x).cwiseAbs().maxCoeff(), 1e-6 * x.cwiseAbs().maxCoeff());
  EXPECT_LE((r.values - mg.values).cwiseAbs().maxCoeff(), 1e-6 * x.cwiseAbs().maxCoeff());
}

TEST(GlobalBilaplacian, ASolverKeepsItsPreconditionerForTheNextSolves) {
  // One free set, two solves with other held values and another column count (the
  // handle moved elsewhere, the held cap tilted): each answer is the direct solve's, and
  // only the first builds a preconditioner, with the default rule (the multigrid here)
  // and with the factor forced.
  const auto [m, ops, u, free] = global_problem(5);
  int handle = 0;
  m.positions().col(2).maxCoeff(&handle);
  Field tilted = Field::Zero(m.num_vertices(), 1);
  tilted(handle, 0) = -0.05;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (m.positions()(v, 2) <= -0.95) tilted(v, 0) = 0.01 * m.positions()(v, 0);
  const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, free);
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;
  for (const Preconditioner pre : {Preconditioner::Auto, Preconditioner::LaplacianFactor}) {
    GlobalBilaplacianSolver solver(m, ops, free, global_params(pre));
    EXPECT_EQ(solver.multigrid_builds() + solver.factorizations(), 0);
    for (const Field* values : std::initializer_list<const Field*>{&u, &tilted}) {
      const GlobalBilaplacianResult r = solver.solve(*values);
      ASSERT_TRUE(r.converged);
      EXPECT_EQ(r.used, pre == Preconditioner::Auto ? Preconditioner::Multigrid : Preconditioner::LaplacianFactor);
      const Field x = direct.solve(*values);
      ASSERT_EQ(r.values.cols(), values->cols());
      EXPECT_LE((r.values - x).cwiseAbs().maxCoeff(), 1e-7 * x.cwiseAbs().maxCoeff());
    }
    EXPECT_EQ(solver.multigrid_builds(), pre == Preconditioner::Auto ? 1 : 0);
    EXPECT_EQ(solver.factorizations(), pre == Preconditioner::Auto ? 0 : 1);
    EXPECT_THROW((void)solver.solve(Field::Zero(3, 1)), InputError);
  }
}

TEST(GlobalBilaplacian, AWarmStartFromThePreviousAnswerTakesFewerIterations) {
  // The handle moved on by a tenth of its move: started from the previous answer, the
  // solve needs fewer iterations than from zero, to the same answer (both
  // preconditioners); started from its own answer, next to none.
  const auto [m, ops, u, free] = global_problem(5);
  int handle = 0;
  m.positions().col(2).maxCoeff(&handle);
  const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0.1, .g2 = 1}, free);
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;
  for (const Preconditioner pre : {Preconditioner::Auto, Preconditioner::LaplacianFactor}) {
    GlobalBilaplacianSolver solver(m, ops, free, global_params(pre));
    const GlobalBilaplacianResult first = solver.solve(u);
    ASSERT_TRUE(first.converged);
    EXPECT_LE(solver.solve(first.values, true).iterations, 2);
    Field next = first.values;
    next.row(handle) *= 1.1;
    const GlobalBilaplacianResult warm = solver.solve(next, true);
    const GlobalBilaplacianResult cold = solver.solve(next);
    ASSERT_TRUE(warm.converged && cold.converged);
    EXPECT_LT(warm.iterations, cold.iterations);
    const Field x = direct.solve(next);
    EXPECT_LE((warm.values - x).cwiseAbs().maxCoeff(), 1e-7 * x.cwiseAbs().maxCoeff());
    EXPECT_LE((cold.values - x).cwiseAbs().maxCoeff(), 1e-7 * x.cwiseAbs().maxCoeff());
    Field bad = first.values;
    bad(free[3], 1) = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW((void)solver.solve(bad, true), InputError);
  }
}

TEST(GlobalBilaplacian, AfterAHandOnTheSolverStartsWithTheFactor) {
  // The stretched icosphere (stretched_global_problem): the first solve hands on to the factor,
  // the second starts with it (no multigrid iteration, no new hierarchy or factor).
  const auto [m, ops, u, free] = stretched_global_problem(4);
  int handle = 0;
  m.positions().col(2).maxCoeff(&handle);
  GlobalBilaplacianParams p{.tolerance = 1e-10, .max_iterations = 2000};
  p.multigrid.coarsest_unknowns = kTestCoarsest;
  GlobalBilaplacianSolver solver(m, ops, free, p);
  const GlobalBilaplacianResult first = solver.solve(u);
  ASSERT_TRUE(first.converged);
  EXPECT_EQ(first.used, GlobalBilaplacianParams::Preconditioner::LaplacianFactor);
  EXPECT_GT(first.multigrid_iterations, 0);
  Field moved = u;
  moved.row(handle) << 0.05, -0.01, 0.02;
  const GlobalBilaplacianResult second = solver.solve(moved);
  ASSERT_TRUE(second.converged);
  EXPECT_EQ(second.used, GlobalBilaplacianParams::Preconditioner::LaplacianFactor);
  EXPECT_EQ(second.multigrid_iterations, 0);
  EXPECT_GT(second.factor_nonzeros, 0);
  EXPECT_EQ(solver.multigrid_builds(), 1);
  EXPECT_EQ(solver.factorizations(), 1);
  const SteadyDirectSolver direct(m, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  for (const auto& [r, values] : {std::pair<const GlobalBilaplacianResult*, const Field*>{&first, &u},
                                  std::pair<const GlobalBilaplacianResult*, const Field*>{&second, &moved}}) {
    const Field x = direct.solve(*values);
    EXPECT_LE((r->values - x).cwiseAbs().maxCoeff(), 1e-6 * x.cwiseAbs().maxCoeff());
  }
}

TEST(GlobalBilaplacian, AppsGetTheDirectSolversAnswerFromIt) {
  // SteadySolver::Global in interpolation, static drags and fairing: CG with the Auto
  // preconditioner to 1e-10, the same answer as the sparse Cholesky solve.
  const Mesh m = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(m);
  const std::vector<InterpolationConstraint> cons = {{0, Eigen::VectorXd::Constant(1, 1.0)},
                                                     {700, Eigen::VectorXd::Constant(1, -2.0)},
                                                     {2000, Eigen::VectorXd::Constant(1, 0.5)}};
  const auto direct = interpolate(m, ops, FieldKind::Scalar, cons, InterpolationParams{.g1 = 0.1, .g2 = 1});
  const auto global = interpolate(m, ops, FieldKind::Scalar, cons,
                                  InterpolationParams{.g1 = 0.1, .g2 = 1, .solver = SteadySolver::Global});
  EXPECT_EQ(direct.solver, SteadySolver::Direct);  // Auto, 2,559 free vertices: below its size rule
  EXPECT_EQ(global.solver, SteadySolver::Global);
  EXPECT_GT(global.cg.iterations, 0);
  EXPECT_LE(global.cg.relative_residual, 1e-10);
  EXPECT_LE((global.values - direct.values).cwiseAbs().maxCoeff(), 1e-7 * direct.values.cwiseAbs().maxCoeff());

  int top = 0;
  m.positions().col(2).maxCoeff(&top);
  DragParams dp{
      .vertex = top, .displacement = Eigen::Vector3d(0.01, 0, 0.05), .radius = 0.8, .boundary = RegionBoundary::Clamp};
  const DragResult d_direct = drag_vertex(m, ops, dp);
  dp.solver = SteadySolver::Global;
  const DragResult d_global = drag_vertex(m, ops, dp);
  EXPECT_EQ(d_global.region, d_direct.region);
  EXPECT_GT(d_global.cg.iterations, 0);
  EXPECT_LE((d_global.displacement - d_direct.displacement).cwiseAbs().maxCoeff(), 1e-7 * 0.05);
  EXPECT_LE((d_global.reaction - d_direct.reaction).norm(), 1e-6 * d_direct.reaction.norm());

  std::vector<int> fixed;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (m.positions()(v, 2) < 0.2) fixed.push_back(v);
  const FairResult f_direct = fair(m, fixed, FairParams{.order = 2});
  const FairResult f_global = fair(m, fixed, FairParams{.order = 2, .solver = SteadySolver::Global});
  EXPECT_GT(f_global.cg_iterations, 0);
  EXPECT_LE((f_global.V - f_direct.V).cwiseAbs().maxCoeff(), 1e-7);
  // The membrane has no bi-Laplacian term: the global solver says so.
  try {
    (void)fair(m, fixed, FairParams{.order = 1, .solver = SteadySolver::Global});
    ADD_FAILURE() << "the global solver took a problem without a bi-Laplacian term";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("g2 > 0"), std::string::npos) << e.what();
  }
}

TEST(GlobalBilaplacian, AutoKeepsTheMultigridWhereItConvergesAndSolvesDirectlyElsewhere) {
  // SteadySolver::Auto, the default of the commands: on a bi-Laplacian problem without
  // g0, from kAutoGlobalFromFreeVertices free vertices on and with no angle below
  // kAutoMultigridMinAngleDeg around them, the multigrid, kept where its probe says it
  // converges and given up for the direct solve where it does not; the direct solve on
  // everything else. Every other choice is kept as asked.
  const PdeCoefficients plate{.g0 = 0, .g1 = 0.1, .g2 = 1};
  for (const SteadySolver s : {SteadySolver::Auto, SteadySolver::Direct, SteadySolver::Iterative, SteadySolver::Global})
    EXPECT_EQ(parse_steady_solver(to_string(s)), s);
  try {
    (void)parse_steady_solver("cholesky");
    ADD_FAILURE() << "an unknown solver name was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'auto', 'direct', 'global' or 'iterative'"), std::string::npos) << e.what();
  }

  // A well-shaped mesh with the size rule's threshold given lower: the multigrid
  // converges, Auto keeps it, and its answer is the direct one's.
  const Mesh m = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(m);
  std::vector<int> free;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (m.positions()(v, 2) > -0.8) free.push_back(v);
  Field u = Field::Zero(m.num_vertices(), 3);
  for (int v = 0; v < m.num_vertices(); ++v)
    if (m.positions()(v, 2) <= -0.8) u.row(v) = Eigen::RowVector3d(0.1, 0, 0.02 * m.positions()(v, 0));
  const int few = static_cast<int>(free.size());
  EXPECT_TRUE(auto_tries_multigrid(m, plate, free, few));
  EXPECT_FALSE(auto_tries_multigrid(m, plate, free, few + 1));
  EXPECT_FALSE(auto_tries_multigrid(m, plate, free));  // the default size rule: 50,000
  EXPECT_FALSE(auto_tries_multigrid(m, PdeCoefficients{.g0 = 0, .g1 = 1, .g2 = 0}, free, few));  // a membrane
  EXPECT_FALSE(auto_tries_multigrid(m, PdeCoefficients{.g0 = 1, .g1 = 0, .g2 = 1}, free, few));  // a foundation
  const auto [bad, bad_ops, bad_u, bad_free] = stretched_global_problem(4);
  ASSERT_LT(smallest_angle_deg(bad.positions(), bad.triangles()), kAutoMultigridMinAngleDeg);
  EXPECT_FALSE(auto_tries_multigrid(bad, plate, bad_free, 1));  // the shape rule
  // Only the triangles around the free set count: the lowest vertex (held, and so are
  // its neighbours) moved most of the way to a neighbour leaves thin triangles among
  // held vertices, which do not stop the try; the top vertex (free) moved so, does.
  const auto pulled = [&](bool top) {
    const Positions& P = m.positions();
    int v = 0;
    for (int i = 1; i < m.num_vertices(); ++i)
      if (top ? P(i, 2) > P(v, 2) : P(i, 2) < P(v, 2)) v = i;
    const int next = m.neighbors()[static_cast<std::size_t>(m.offsets()[v])];
    Positions X = P;
    for (int c = 0; c < 3; ++c) X(v, c) = P(v, c) + 0.9 * (P(next, c) - P(v, c));
    return Mesh(X, m.triangles());
  };
  const Mesh thin_below = pulled(false), thin_above = pulled(true);
  ASSERT_LT(smallest_angle_deg(thin_below.positions(), thin_below.triangles()), kAutoMultigridMinAngleDeg);
  EXPECT_TRUE(auto_tries_multigrid(thin_below, plate, free, few));
  EXPECT_FALSE(auto_tries_multigrid(thin_above, plate, free, few));
  const SteadySolveResult by_default = solve_steady(m, ops, plate, free, u, SteadySolver::Auto);
  EXPECT_EQ(by_default.solver, SteadySolver::Direct);  // 2,3xx free vertices: below the rule
  EXPECT_EQ(by_default.multigrid_probe_iterations, 0);
  const SteadySolveResult lowered = solve_steady(m, ops, plate, free, u, SteadySolver::Auto, 1000);
  EXPECT_EQ(lowered.solver, SteadySolver::Global);
  EXPECT_GT(lowered.iterations, 0);
  EXPECT_EQ(lowered.multigrid_probe_iterations, lowered.iterations);
  EXPECT_LE(lowered.relative_residual, 1e-10);
  EXPECT_LE((lowered.values - by_default.values).cwiseAbs().maxCoeff(), 1e-7 * by_default.values.cwiseAbs().maxCoeff());
  EXPECT_EQ(solve_steady(m, ops, PdeCoefficients{.g0 = 0, .g1 = 1, .g2 = 0}, free, u, SteadySolver::Auto, 1000).solver,
            SteadySolver::Direct);

  // Auto's try with a hierarchy of two levels (the default coarsest level holds this
  // whole mesh): kept on the sphere, to the same answer ...
  SurfaceMultigridParams two_levels;
  two_levels.coarsest_unknowns = kTestCoarsest;
  int probe = -1;
  const std::optional<SteadySolveResult> tried = try_multigrid_solve(m, ops, plate, free, u, &probe, two_levels);
  ASSERT_TRUE(tried.has_value());
  const SteadySolveResult kept = tried.value_or(SteadySolveResult{});
  EXPECT_EQ(kept.solver, SteadySolver::Global);
  EXPECT_GT(probe, 1);
  EXPECT_LE(kept.relative_residual, 1e-10);
  EXPECT_LE((kept.values - by_default.values).cwiseAbs().maxCoeff(), 1e-7 * by_default.values.cwiseAbs().maxCoeff());
  // ... and given up on a badly shaped mesh (the icosphere stretched 8x along x, where
  // the multigrid alone needs over 200 iterations) within a few iterations, where the
  // shape rule does not even let Auto try it.
  EXPECT_EQ(try_multigrid_solve(bad, bad_ops, plate, bad_free, bad_u, &probe, two_levels), std::nullopt);
  EXPECT_GE(probe, GlobalBilaplacianParams{}.probe_iterations);
  EXPECT_LT(probe, 50);
  const SteadySolveResult untried = solve_steady(bad, bad_ops, plate, bad_free, bad_u, SteadySolver::Auto, 1);
  EXPECT_EQ(untried.solver, SteadySolver::Direct);
  EXPECT_EQ(untried.multigrid_probe_iterations, 0);
  EXPECT_EQ(untried.values, solve_steady(bad, bad_ops, plate, bad_free, bad_u, SteadySolver::Direct).values);

  // The correction's Auto: the direct solver (with its condition estimate) for a small
  // region, and no refusal where only the direct solver serves (dynamic, fade).
  CorrectionParams cp;
  int top = 0;
  m.positions().col(2).maxCoeff(&top);
  cp.handles = {{top, Eigen::Vector3d(0, 0, 0.05)}};
  cp.radius = 0.8;
  const CorrectionResult c = correct_vessel(m, cp);
  EXPECT_EQ(c.solver, SteadySolver::Direct);
  EXPECT_GT(c.condition_estimate, 0);
  cp.boundary = RegionBoundary::Fade;
  EXPECT_EQ(correct_vessel(m, cp).solver, SteadySolver::Direct);
  cp.boundary = RegionBoundary::Clamp;
  cp.dynamic = true;
  cp.steps = 3;
  EXPECT_EQ(correct_vessel(m, cp).solver, SteadySolver::Direct);
  cp.dynamic = false;
  cp.solver = SteadySolver::Global;
  EXPECT_EQ(correct_vessel(m, cp).solver, SteadySolver::Global);
}

TEST(GlobalBilaplacian, EveryRealMeshInTheCoreFormatsMatchesTheDirectSolve) {
  // The answers equal the direct solve's to 1e-8 relative on every mesh of
  // ../shared/data, on one thread and two (the .vtp meshes: test_medical.cpp).
  for (const char* name : {"bunny-3k.off", "bunny-36k.obj", "armadillo-43k.obj", "fertility-4k.off",
                           "decimated-knight.off", "camelhead-11k.off", "cow-3k.off", "aorta-open-6k.stl",
                           "coronary-phantom-7k.stl", "nonmanifold-vierbein.obj", "nonmanifold-vertex-hourglass.obj"}) {
    if (test::kSanitized && (std::string(name) == "bunny-36k.obj" || std::string(name) == "armadillo-43k.obj"))
      continue;  // the two largest: test_support.h
    if (!test::have_data(name)) continue;
    expect_global_matches_direct(name, read_mesh(test::data_dir() / name));
  }
}
