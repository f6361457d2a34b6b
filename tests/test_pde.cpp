// pde/pde_session.h: constraints and reaction forces, conservation, backward Euler
// steps, the self-adjusting domain and localization.
#include <gtest/gtest.h>

#include <Eigen/SparseCore>
#include <chrono>
#include <random>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"
#include "test_support.h"

using namespace meshpde;
using test::make;
using test::unit_edge_icosphere;

TEST(Pde, HeatConservesTheMassWeightedTotal) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_cotan_operators(m);
  PdeSession s(m, ops, 1, PdeCoefficients{.alpha = 0, .b1 = 1, .b2 = 0, .g1 = 1, .g2 = 0.1});
  s.cg_options.tolerance = 1e-13;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u01(0, 1);
  Field u(m.num_vertices(), 1);
  for (int i = 0; i < m.num_vertices(); ++i) u(i, 0) = u01(rng);
  s.set_values(u);
  s.activate_all();
  const double total = ops.mass.dot(u.col(0));
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(s.step(0.01).cg.converged());
  }
  EXPECT_NEAR(ops.mass.dot(s.values().col(0)), total, 1e-10 * total);
  // And it smooths: the spread shrinks.
  EXPECT_LT(s.values().maxCoeff() - s.values().minCoeff(), 0.5 * (u.maxCoeff() - u.minCoeff()));
}

TEST(Pde, ConstraintsAreAddedMovedAndReleasedBetweenSteps) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_cotan_operators(m);
  PdeSession s(m, ops, 3, PdeCoefficients{.alpha = 0.1, .b1 = 1, .b2 = 0, .g1 = 1, .g2 = 0.1});
  s.activate_all();
  const double a[3] = {0.1, 0, 0}, b[3] = {0, 0.2, -0.1};
  s.constrain(10, a);
  ASSERT_TRUE(s.step(0.01).cg.converged());
  EXPECT_EQ(s.values()(10, 0), 0.1);
  EXPECT_GT(s.values().row(m.neighbors(10)[0]).norm(), 0.0);  // neighbours follow
  s.constrain(10, b);                                         // moved
  s.constrain(50, a);                                         // added
  ASSERT_TRUE(s.step(0.01).cg.converged());
  EXPECT_EQ(s.values()(10, 1), 0.2);
  EXPECT_EQ(s.values()(50, 0), 0.1);
  EXPECT_EQ(s.constrained_vertices().size(), 2u);
  // Reactions oppose nothing at rest and something here.
  EXPECT_GT(s.reaction_forces().norm(), 0.0);
  s.release(10);
  s.release(50);
  EXPECT_TRUE(s.constrained_vertices().empty());
  EXPECT_EQ(s.domain().state(10), VertexState::Free);
  for (int k = 0; k < 200; ++k) s.step(0.05);
  // Without a foundation term (g0 = 0) nothing holds the surface in place (K 1 = 0):
  // it settles at a rigid offset, every vertex displaced alike.
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(s.values().col(c).maxCoeff() - s.values().col(c).minCoeff(), 1e-3);
  }
  EXPECT_GT(s.values().cwiseAbs().maxCoeff(), 1e-3);

  // With a foundation it returns to rest.
  PdeSession anchored(m, ops, 3, PdeCoefficients{.alpha = 0.1, .b1 = 1, .b2 = 0, .g0 = 1, .g1 = 1, .g2 = 0.1});
  anchored.activate_all();
  anchored.constrain(10, a);
  anchored.step(0.01);
  anchored.release(10);
  for (int k = 0; k < 200; ++k) anchored.step(0.05);
  EXPECT_LT(anchored.values().cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Pde, ZeroAreaVerticesAreHeldFixed) {
  Positions V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5;  // vertex 3 unreferenced
  Triangles F(1, 3);
  F << 0, 1, 2;
  const Mesh m(V, F);
  const FemOperators ops = build_cotan_operators(m);
  PdeSession s(m, ops, 1);
  s.activate_all();
  EXPECT_EQ(s.domain().num_free(), 3);
  EXPECT_EQ(s.domain().state(3), VertexState::Frozen);
}

// The sanitizer build runs the two self-adjusting-domain tests on a sphere of one level
// less (2,562 vertices, the same edge length): 400 steps of level 5 take minutes there.
constexpr int kDomainTestLevel = test::kSanitized ? 4 : 5;

TEST(Pde, SelfAdjustingDomainGrowsUnderAPokeAndShrinksAfterRelease) {
  const Mesh m = unit_edge_icosphere(kDomainTestLevel);
  const FemOperators ops = build_cotan_operators(m);
  PdeSession s(m, ops, 3, PdeCoefficients{.alpha = 1, .b1 = 1, .b2 = 0.01, .g0 = 1, .g1 = 0, .g2 = 100},
               DomainOptions{.self_adjusting = true, .rest_value = 1e-4, .rest_rate = 1e-3});
  s.cg_options.tolerance = 1e-8;
  const int handle = 0;
  const Eigen::Vector3d n = m.positions().row(handle).normalized();
  int peak = 0;
  for (int k = 1; k <= 100; ++k) {
    const Eigen::Vector3d target = -0.005 * k * n;
    s.constrain(handle, std::span<const double>(target.data(), 3));
    ASSERT_TRUE(s.step(1e-3).cg.converged());
    peak = std::max(peak, s.domain().num_free());
  }
  EXPECT_GT(peak, 30);  // grew beyond the seed rings (about 16 vertices)
  EXPECT_LT(peak, m.num_vertices() / 4);
  s.release(handle);
  int steps = 0;
  // Relaxation takes seconds of model time (rate about b1 / 2alpha); larger steps get there.
  while (s.domain().num_free() > 0 && steps < 5000) {
    s.step(2e-2);
    ++steps;
  }
  EXPECT_EQ(s.domain().num_free(), 0) << "domain did not shrink back after " << steps << " steps";
  EXPECT_LE(s.values().cwiseAbs().maxCoeff(), 1e-4);
}

// pde/step_factor.h: a step on exactly the factor's free set is the factor's solve, and
// gives what a tight CG gives; on any other free set, or another dt, the step is CG.
TEST(Pde, StepFactorGivesTheCgStepAndIsUsedOnlyOnItsFreeSetAndStep) {
  const Mesh m = unit_edge_icosphere(4);
  const FemOperators ops = build_cotan_operators(m);
  const PdeCoefficients c{.alpha = 0.01, .b1 = 0.2, .b2 = 1e-3, .g0 = 1, .g1 = 0, .g2 = 81};
  PdeSession direct(m, ops, 3, c), cg(m, ops, 3, c);
  cg.cg_options.tolerance = 1e-13;
  cg.cg_options.max_iterations = 10000;
  const int handle = 3;
  const Eigen::Vector3d n = m.positions().row(handle).normalized();
  const Eigen::Vector3d rest = Eigen::Vector3d::Zero();
  for (PdeSession* s : {&direct, &cg}) {
    s->constrain(handle, std::span<const double>(rest.data(), 3));
    s->activate_rings(handle, 6);
  }
  const std::vector<int> free(direct.domain().free_vertices().begin(), direct.domain().free_vertices().end());
  std::vector<int> reversed(free.rbegin(), free.rend());  // any row order
  auto factor = std::make_shared<StepFactor>(m, ops, c, reversed, 1e-3);
  EXPECT_GT(factor->factor_nonzeros(), 0.0);
  direct.set_step_factor(factor);
  for (int k = 1; k <= 40; ++k) {
    const Eigen::Vector3d target = -0.02 * std::min(k, 20) * n;
    for (PdeSession* s : {&direct, &cg}) s->constrain(handle, std::span<const double>(target.data(), 3));
    const StepResult a = direct.step(1e-3), b = cg.step(1e-3);
    ASSERT_TRUE(a.factored) << "step " << k;
    EXPECT_FALSE(b.factored);
    EXPECT_EQ(a.cg.iterations, 0);
    // 1e-9 of the deepest offset (0.4)
    EXPECT_LE((direct.values() - cg.values()).cwiseAbs().maxCoeff(), 4e-10) << "step " << k;
    EXPECT_LE((direct.reaction_forces() - cg.reaction_forces()).norm(), 1e-8 * cg.reaction_forces().norm());
  }
  EXPECT_FALSE(direct.step(2e-3).factored) << "another dt";
  direct.activate_rings(handle, 7);
  EXPECT_FALSE(direct.step_factor_applies(1e-3)) << "another free set";
  EXPECT_FALSE(direct.step(1e-3).factored);
  direct.set_free_set(free);
  EXPECT_TRUE(direct.step_factor_applies(1e-3)) << "the factor's free set again";
  direct.set_step_factor(nullptr);
  EXPECT_FALSE(direct.step(1e-3).factored);
  EXPECT_THROW(StepFactor(m, ops, c, {1, 2, 1}, 1e-3), InputError);
  EXPECT_THROW(StepFactor(m, ops, c, {1, 2}, 0.0), InputError);
  EXPECT_THROW(StepFactor(m, ops, c, {1, m.num_vertices()}, 1e-3), InputError);
}

// propose_domain_change() records what the self-adjusting rule would do; applying it
// with set_free_set() after every step reproduces a self-adjusting session exactly.
TEST(Pde, ProposedDomainChangesAppliedLaterReproduceTheSelfAdjustingDomain) {
  const Mesh m = unit_edge_icosphere(kDomainTestLevel);
  const FemOperators ops = build_cotan_operators(m);
  const PdeCoefficients c{.alpha = 1, .b1 = 1, .b2 = 0.01, .g0 = 1, .g1 = 0, .g2 = 100};
  const DomainOptions d{.self_adjusting = true, .rest_value = 1e-4, .rest_rate = 1e-3};
  DomainOptions manual_options = d;
  manual_options.self_adjusting = false;
  PdeSession automatic(m, ops, 3, c, d), manual(m, ops, 3, c, manual_options);
  for (PdeSession* s : {&automatic, &manual}) s->cg_options.tolerance = 1e-12;
  const int handle = 0;
  const Eigen::Vector3d n = m.positions().row(handle).normalized();
  int grown = 0, shrunk = 0;
  for (int k = 1; k <= 400; ++k) {
    const bool pressing = k <= 100;
    const Eigen::Vector3d target = -0.005 * std::min(k, 100) * n;
    if (pressing)
      for (PdeSession* s : {&automatic, &manual}) s->constrain(handle, std::span<const double>(target.data(), 3));
    if (k == 101)
      for (PdeSession* s : {&automatic, &manual}) s->release(handle);
    const double dt = pressing ? 1e-3 : 2e-2;
    automatic.step(dt);
    manual.step(dt);
    const DomainChange change = manual.propose_domain_change();
    grown += static_cast<int>(change.grow.size());
    shrunk += static_cast<int>(change.shrink.size());
    std::vector<int> next;
    for (int v : manual.domain().free_vertices())
      if (std::find(change.shrink.begin(), change.shrink.end(), v) == change.shrink.end()) next.push_back(v);
    next.insert(next.end(), change.grow.begin(), change.grow.end());
    manual.set_free_set(next, change.shrink);
    std::vector<int> a(automatic.domain().free_vertices().begin(), automatic.domain().free_vertices().end());
    std::vector<int> b(manual.domain().free_vertices().begin(), manual.domain().free_vertices().end());
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    ASSERT_EQ(a, b) << "step " << k;
    ASSERT_LE((automatic.values() - manual.values()).cwiseAbs().maxCoeff(), 1e-9) << "step " << k;
  }
  EXPECT_GT(grown, 30);
  EXPECT_GT(shrunk, 30);
}

// A real-time loop on a machine too slow for its deadlines (every solve starts
// late): with a late tolerance the steps stay accurate to it, so the released
// surface follows the on-time trajectory instead of drifting on stale velocities.
TEST(Pde, LateStepsStayAccurateToTheLateTolerance) {
  const Mesh m = unit_edge_icosphere(4);
  const FemOperators ops = build_cotan_operators(m);
  auto run = [&](bool late) {
    PdeSession s(m, ops, 3, PdeCoefficients{.alpha = 1e-2, .b1 = 0.2, .b2 = 1e-3, .g0 = 1, .g1 = 0, .g2 = 81});
    s.activate_all();
    s.cg_options.tolerance = 5e-4;
    const Eigen::Vector3d target = -0.5 * Eigen::Vector3d(m.positions().row(0)).normalized();
    s.constrain(0, std::span<const double>(target.data(), 3));
    for (int k = 0; k < 20; ++k) s.step(1e-3);
    s.release(0);
    int late_steps = 0;
    for (int k = 0; k < 300; ++k) {
      if (late) {
        s.cg_options.deadline = std::chrono::steady_clock::now() - std::chrono::seconds(1);
        s.cg_options.late_tolerance = 1e-2;
      }
      const StepResult r = s.step(1e-3);
      late_steps += r.cg.status == CgStatus::Deadline;
      EXPECT_LE(r.cg.relative_residual, late ? 1e-2 : 5e-4);
    }
    return std::make_pair(Field(s.values()), late_steps);
  };
  const auto [on_time, none] = run(false);
  const auto [late, late_steps] = run(true);
  EXPECT_EQ(none, 0);
  EXPECT_GT(late_steps, 100);  // the deadline really cut solves short
  EXPECT_TRUE(late.allFinite());
  // Within 1 % of the 0.5 press of the on-time trajectory after 300 late steps
  // (measured 0.3 %), and relaxed like it: no drift.
  EXPECT_LE((late - on_time).cwiseAbs().maxCoeff(), 0.01 * 0.5);
  EXPECT_LE(late.cwiseAbs().maxCoeff(), 2 * on_time.cwiseAbs().maxCoeff());
}

// A localized poke on >= 500k vertices touches a bounded set and agrees with the
// same steps solved with the whole mesh active.
TEST(Pde, LocalizedPokeOnAHalfMillionVertexMeshMatchesAFullSolve) {
  // 655,362 vertices; the sanitizer build checks memory on 40,962 (level 6).
  const Mesh m = unit_edge_icosphere(test::kSanitized ? 6 : 8);
  if (!test::kSanitized) {
    ASSERT_GE(m.num_vertices(), 500000);
  }
  const FemOperators ops = build_cotan_operators(m);
  const PdeCoefficients c{.alpha = 1, .b1 = 1, .b2 = 0.01, .g0 = 1, .g1 = 0, .g2 = 100};
  const DomainOptions local{.self_adjusting = true, .rest_value = 1e-7, .rest_rate = 1e-6};
  PdeSession a(m, ops, 3, c, local), b(m, ops, 3, c);
  a.cg_options.tolerance = b.cg_options.tolerance = 1e-10;
  b.activate_all();
  const int handle = 0;
  const Eigen::Vector3d n = m.positions().row(handle).normalized();
  const int steps = 5;
  int touched = 0;
  for (int k = 1; k <= steps; ++k) {
    const Eigen::Vector3d target = -0.1 * k * n;
    a.constrain(handle, std::span<const double>(target.data(), 3));
    b.constrain(handle, std::span<const double>(target.data(), 3));
    ASSERT_TRUE(a.step(1e-3).cg.converged());
    ASSERT_TRUE(b.step(1e-3).cg.converged());
    touched = std::max(touched, a.domain().num_free() + static_cast<int>(a.domain().ring().size()));
  }
  EXPECT_LE(touched, 2000) << "the localized solve touched too many vertices";
  const double scale = 0.1 * steps;
  const double err = (a.values() - b.values()).cwiseAbs().maxCoeff();
  EXPECT_LE(err, 1e-3 * scale) << "local vs full";
  EXPECT_LE((a.reaction_forces() - b.reaction_forces()).norm(), 1e-3 * b.reaction_forces().norm());
}

TEST(Step, ReactionForceEqualsAssembledBackwardEulerRow) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_cotan_operators(m);
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
