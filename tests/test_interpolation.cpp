// apps/interpolation.h: scattered-data interpolation and its constraint files.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "meshpde/apps/interpolation.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/operators/connection.h"
#include "meshpde/operators/fem_operators.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

namespace {
int nearest(const Mesh& m, const Eigen::Vector3d& p) {
  int v = 0;
  (m.positions().rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&v);
  return v;
}
InterpolationConstraint con(int v, std::initializer_list<double> x) {
  InterpolationConstraint c{v, Eigen::VectorXd(static_cast<Eigen::Index>(x.size()))};
  int k = 0;
  for (double e : x) c.value[k++] = e;
  return c;
}
}  // namespace

TEST(Interpolation, ExactAtConstraintsForEveryMix) {
  Mesh m;
  if (!test::load_data("bunny-3k.off", m)) return;
  const FemOperators ops = build_cotan_operators(m);
  const std::vector<InterpolationConstraint> cons = {con(10, {1.0}), con(1000, {-2.0}), con(2500, {0.5})};
  for (const auto& [g1, g2] : {std::pair{1.0, 0.0}, {0.0, 1.0}, {1.0, 0.1}}) {
    const auto r = interpolate(m, ops, FieldKind::Scalar, cons, InterpolationParams{.g1 = g1, .g2 = g2});
    for (const auto& c : cons) {
      EXPECT_EQ(r.values(c.vertex, 0), c.value[0]);
    }
    EXPECT_TRUE(r.cg.converged());
    // Laplacian interpolation obeys the maximum principle (up to obtuse-angle effects).
    if (g2 == 0) {
      EXPECT_LE(r.values.maxCoeff(), 1.0 + 1e-6);
    }
  }
  const auto d = interpolate(m, ops, FieldKind::Displacement, {con(7, {0.0, 0.01, 0.0}), con(900, {0, 0, 0})});
  EXPECT_EQ(d.values.row(7), Eigen::RowVector3d(0, 0.01, 0));
  EXPECT_THROW(interpolate(m, ops, FieldKind::Scalar, {con(7, {1.0}), con(7, {2.0})}), InputError);
  EXPECT_THROW(interpolate(m, ops, FieldKind::Scalar, {con(7, {1.0, 2.0})}), InputError);
  EXPECT_THROW(interpolate(m, ops, FieldKind::Scalar, {}), InputError);
}

TEST(Interpolation, BilaplacianReproducesLinearFields) {
  const Mesh m = make(plane_grid(14, 14));
  const FemOperators ops = build_cotan_operators(m);
  std::vector<InterpolationConstraint> cons;
  for (int i = 0; i < m.num_vertices(); ++i) {
    const Eigen::RowVector3d p = m.positions().row(i);
    if (std::min({p.x(), 1 - p.x(), p.y(), 1 - p.y()}) < 1.5 / 14) cons.push_back(con(i, {3 * p.x() - p.y() + 2}));
  }
  const auto r = interpolate(m, ops, FieldKind::Scalar, cons, InterpolationParams{.g1 = 0, .g2 = 1});
  for (int i = 0; i < m.num_vertices(); ++i)
    EXPECT_NEAR(r.values(i, 0), 3 * m.positions()(i, 0) - m.positions()(i, 1) + 2, 1e-9);
}

TEST(Interpolation, TangentFieldsAreTangent) {
  Mesh m;
  if (!test::load_data("bunny-3k.off", m)) return;
  const FemOperators ops = build_cotan_operators(m);
  const Eigen::MatrixX3d N = vertex_normals(m);
  std::vector<InterpolationConstraint> cons;
  for (int v : {100, 800, 1600, 3000}) {
    const Eigen::Vector3d a = Eigen::Vector3d(1, 0.3, -0.2).cross(N.row(v).transpose());  // tangent at v
    cons.push_back(con(v, {a.x(), a.y(), a.z()}));
  }
  for (const auto method : {TangentMethod::Componentwise, TangentMethod::Connection}) {
    const auto r =
        interpolate(m, ops, FieldKind::Tangent, cons, InterpolationParams{.g1 = 1, .g2 = 0.05, .method = method});
    for (int i = 0; i < m.num_vertices(); ++i)
      ASSERT_LE(std::abs(r.values.row(i).dot(N.row(i))), 1e-9 * std::max(1e-300, r.values.row(i).norm())) << i;
    for (const auto& c : cons) {
      EXPECT_LE((r.values.row(c.vertex).transpose() - c.value).norm(), 1e-12);
    }
  }
}

TEST(Interpolation, ConnectionHolonomyAroundLatitudeLoops) {
  const int n = 40;
  const Mesh m = make(latlong_sphere(n, 1.0));
  const Connection c = build_connection(m);
  for (int k : {4, 10, 20}) {
    // Ring k (polar angle k pi / n) holds vertices 1 + (k-1) 2n ... in meridian order.
    double angle = 0;
    const int first = 1 + (k - 1) * 2 * n;
    for (int j = 0; j < 2 * n; ++j) {
      const int a = first + j, b = first + (j + 1) % (2 * n);
      angle += c.transport(m, b, m.find_slot(b, a));  // carry the vector from a to b
    }
    double defect = 0;  // faces with every corner in the pole .. ring k
    const auto& F = m.triangles();
    const auto& V = m.positions();
    for (int f = 0; f < m.num_faces(); ++f) {
      if (F.row(f).maxCoeff() >= first + 2 * n) continue;
      double kf = -M_PI;
      for (int q = 0; q < 3; ++q) {
        const int v = F(f, q);
        const Eigen::Vector3d u = V.row(F(f, (q + 1) % 3)) - V.row(v), w = V.row(F(f, (q + 2) % 3)) - V.row(v);
        kf += std::atan2(u.cross(w).norm(), u.dot(w)) * 2 * M_PI / c.theta[v];
      }
      defect += kf;
    }
    auto wrap = [](double x) { return std::remainder(x, 2 * M_PI); };
    EXPECT_NEAR(wrap(angle - defect), 0.0, 1e-9) << "ring " << k;
    const double analytic = 2 * M_PI * (1 - std::cos(M_PI * k / n));
    EXPECT_NEAR(wrap(angle - analytic), 0.0, 0.02 * analytic) << "ring " << k;
  }
}

TEST(Interpolation, ConnectionKeepsMagnitudesWhereComponentwiseCollapses) {
  const Mesh m = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(m);
  // Two "eastward" unit vectors at opposite points of the equator.
  const int a = nearest(m, {1, 0, 0}), b = nearest(m, {-1, 0, 0}), mid = nearest(m, {0, 1, 0});
  const std::vector<InterpolationConstraint> cons = {con(a, {0, 1, 0}), con(b, {0, -1, 0})};
  const InterpolationParams base{.g1 = 1, .g2 = 0};
  const auto comp = interpolate(m, ops, FieldKind::Tangent, cons, base);
  InterpolationParams cp = base;
  cp.method = TangentMethod::Connection;
  const auto conn = interpolate(m, ops, FieldKind::Tangent, cons, cp);
  EXPECT_LT(comp.values.row(mid).norm(), 0.3);  // the 3D components cancel
  EXPECT_GT(conn.values.row(mid).norm(), 0.8);
  EXPECT_GT(conn.values.row(mid).normalized().dot(Eigen::RowVector3d(-1, 0, 0)), 0.9);  // still eastward
}

TEST(Parsers, ConstraintsFromCsvAndJsonWithErrorsThatNameThePlace) {
  const Mesh m = make(plane_grid(4, 4));  // 25 vertices on [0, 1]^2
  const auto csv = parse_constraints(m, "vertex,value\n# a comment\n3, 1.5\n24,-2\n", 1, "c.csv");
  ASSERT_EQ(csv.size(), 2u);
  EXPECT_EQ(csv[0].vertex, 3);
  EXPECT_EQ(csv[0].value[0], 1.5);
  EXPECT_EQ(csv[1].vertex, 24);
  EXPECT_EQ(csv[1].value[0], -2.0);
  const auto json = parse_constraints(
      m, R"({"constraints": [{"vertex": 0, "value": [1, 2, 3]}, {"vertex": "@0,0,0", "value": [4, 5, 6]}]})", 3,
      "c.json");
  ASSERT_EQ(json.size(), 2u);
  EXPECT_EQ(json[1].vertex, 0);
  EXPECT_EQ(json[1].value[2], 6.0);
  EXPECT_EQ(parse_constraints(m, R"([{"vertex": 2, "value": 7}])", 1, "bare.json").size(), 1u);

  EXPECT_NE(error_of([&] { parse_constraints(m, "1,2\n99,1\n", 1, "c.csv"); }).find("c.csv: line 2"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, "1,abc\n", 1, "c.csv"); }).find("'abc' is not a number"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, "1,2,3\n", 3, "c.csv"); }).find("2 values, expected 3"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, "# nothing\n", 1, "c.csv"); }).find("no constraints"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, "{\"constraints\": [", 1, "c.json"); }).find("invalid JSON"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, R"([{"vertex": 1, "value": 1e999}])", 1, "c.json"); }).find("c.json"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_constraints(m, R"({"constraints": [{"vertex": 1}]})", 1, "c.json");
            }).find("constraint 0: needs 'vertex' and 'value'"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_constraints(m, R"({"constraints": 5})", 1, "c.json"); }).find("must be an array"),
            std::string::npos);
}

// InterpolationSolver: a kept factor, bordered for changed constraints, must give what a
// fresh interpolate() gives after every edit.
namespace {
double relative_difference(const Field& a, const Field& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(b.cwiseAbs().maxCoeff(), 1e-300);
}

// The kept solver's answer for a scalar field with plate weights (g1 = 0, g2 = 1),
// checked against a fresh direct interpolate() of its constraints to 1e-10.
InterpolationResult solve_like_a_fresh_plate(InterpolationSolver& solver, const Mesh& mesh, const FemOperators& ops,
                                             const std::string& what) {
  const InterpolationResult kept = solver.solve();
  const InterpolationResult fresh = interpolate(mesh, ops, FieldKind::Scalar, solver.constraints(),
                                                InterpolationParams{.g1 = 0, .g2 = 1, .solver = SteadySolver::Direct});
  EXPECT_LT(relative_difference(kept.values, fresh.values), 1e-10) << what;
  return kept;
}

// Random steps (add a constraint, remove one, change a value), each solved by the
// kept solver and by a fresh direct interpolate() on the same constraints.
void random_edits(const Mesh& mesh, const FemOperators& ops, FieldKind kind, const InterpolationParams& params,
                  int max_changes, unsigned seed, int& factorizations, int steps = 100) {
  InterpolationSolver solver(mesh, ops, kind, params);
  solver.max_changes = max_changes;
  const int m = kind == FieldKind::Scalar ? 1 : 3;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> vertex(0, mesh.num_vertices() - 1);
  std::uniform_real_distribution<double> value(-2, 2);
  auto random_value = [&] {
    Eigen::VectorXd x(m);
    for (int k = 0; k < m; ++k) x[k] = value(rng);
    return x;
  };
  for (int k = 0; k < 3; ++k) solver.set_value(vertex(rng), random_value());
  InterpolationParams direct = params;
  direct.solver = SteadySolver::Direct;
  int adds = 0, removes = 0, changes = 0;
  for (int step = 0; step < steps; ++step) {
    const std::vector<InterpolationConstraint> now = solver.constraints();
    const int action = static_cast<int>(rng() % 3);
    if (action == 0 || now.size() < 2) {
      solver.set_value(vertex(rng), random_value());
      ++adds;
    } else if (action == 1) {
      solver.remove(now[rng() % now.size()].vertex);
      ++removes;
    } else {
      solver.set_value(now[rng() % now.size()].vertex, random_value());
      ++changes;
    }
    const InterpolationResult kept = solver.solve();
    const InterpolationResult fresh = interpolate(mesh, ops, kind, solver.constraints(), direct);
    ASSERT_LT(kept.cg.relative_residual, 1e-9);
    ASSERT_LT(relative_difference(kept.values, fresh.values), 1e-10)
        << "step " << step << ", " << solver.num_constraints() << " constraints, " << solver.changed_constraints()
        << " changed since the factor";
    if (kind != FieldKind::Tangent) {  // tangent values are projected onto the tangent plane
      for (const auto& c : solver.constraints())
        ASSERT_EQ((kept.values.row(c.vertex).transpose() - c.value).cwiseAbs().maxCoeff(), 0.0);
    }
  }
  EXPECT_GT(adds, steps / 10);
  EXPECT_GT(removes, steps / 10);
  EXPECT_GT(changes, steps / 10);
  factorizations = solver.factorizations();
}
}  // namespace

TEST(InterpolationSolver, HundredRandomEditsEqualAFreshSolveAfterEach) {
  const Mesh sphere = make(icosphere(3));  // 642 vertices
  const FemOperators ops = build_cotan_operators(sphere);
  int factorizations = 0;
  random_edits(sphere, ops, FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1}, 64, 1, factorizations);
  EXPECT_LE(factorizations, 2) << "the edits were not made by updates";
  // The other fields and mixes on a coarser sphere (162 vertices).
  const Mesh coarse = make(icosphere(2));
  const FemOperators coarse_ops = build_cotan_operators(coarse);
  random_edits(coarse, coarse_ops, FieldKind::Scalar, InterpolationParams{.g1 = 1, .g2 = 0}, 64, 2, factorizations);
  EXPECT_LE(factorizations, 2);
  random_edits(coarse, coarse_ops, FieldKind::Scalar, InterpolationParams{.g1 = 1, .g2 = 0.1}, 64, 3, factorizations);
  random_edits(coarse, coarse_ops, FieldKind::Displacement, InterpolationParams{.g1 = 0, .g2 = 1}, 64, 4,
               factorizations);
  random_edits(coarse, coarse_ops, FieldKind::Tangent, InterpolationParams{.g1 = 0, .g2 = 1}, 64, 5, factorizations);
  // Few changes allowed: factored afresh every few steps, same answers.
  random_edits(coarse, coarse_ops, FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1}, 3, 6, factorizations);
  EXPECT_GE(factorizations, 10);
}

// A fresh start after a few changed constraints keeps the last factor's order for the
// vertices still free (reuse_ordering) and gives a fresh solve's answer; after a change
// of more than 5 % of the free set it orders afresh.
TEST(InterpolationSolver, AFreshStartAfterFewChangesReusesTheLastOrder) {
  const Mesh sphere = make(icosphere(4));  // 2,562 vertices: a CHOLMOD factor
  const FemOperators ops = build_cotan_operators(sphere);
  const InterpolationParams params{.g1 = 0, .g2 = 1};
  InterpolationSolver solver(sphere, ops, FieldKind::Scalar, params);
  solver.max_changes = 3;
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> value(-2, 2);
  const auto check = [&](const std::string& what) { solve_like_a_fresh_plate(solver, sphere, ops, what); };
  for (int v = 0; v < sphere.num_vertices(); v += 250) solver.set_value(v, Eigen::VectorXd::Constant(1, value(rng)));
  check("first");
  for (int step = 0; step < 24; ++step) {
    const int v = static_cast<int>(rng() % static_cast<unsigned>(sphere.num_vertices()));
    if (solver.constrained(v) && solver.num_constraints() > 3)
      solver.remove(v);
    else
      solver.set_value(v, Eigen::VectorXd::Constant(1, value(rng)));
    check(fmt::format("step {}", step));
  }
  EXPECT_GE(solver.factorizations(), 4) << "max_changes 3 makes fresh starts";
  EXPECT_EQ(solver.reused_orders(), solver.factorizations() - 1) << "every fresh start after the first reuses";
  // 300 new constraints: more than 5 % of the free set, a new order.
  const int before = solver.reused_orders();
  solver.clear();
  for (int v = 1; v < sphere.num_vertices(); v += 8) solver.set_value(v, Eigen::VectorXd::Constant(1, value(rng)));
  check("a large change");
  EXPECT_EQ(solver.reused_orders(), before);
}

TEST(InterpolationSolver, EqualsAFreshSolveOnRealAndIrregularMeshesWithBoundary) {
  Mesh m;
  if (!test::load_data("bunny-3k.off", m)) return;
  // The operators interpolate() chooses there (intrinsic Delaunay: the bunny's cotangent
  // K is too ill-conditioned for two solves to agree to 1e-10, kept factor or not).
  const MeshOperators mo = build_mesh_operators(m, LaplacianKind::Auto);
  int factorizations = 0;
  random_edits(mo.mesh, mo.ops, FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1}, 64, 7, factorizations, 50);
  EXPECT_LE(factorizations, 2);
  // A plane jittered by 0.15 of its spacing (at 0.3 its slivers make the scaled
  // condition number 2e10, and two fresh solves with different orderings would agree to
  // about 1e-8 only: conditioning, not the kept factor).
  const Mesh plane = make(test::jittered_plane(30, 0.15, 8));
  random_edits(plane, build_cotan_operators(plane), FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1}, 64, 9,
               factorizations, 50);
}

// Many values held when the factor was made: new values at a few of them move the kept
// answer by their kept responses, at many of them at once (or past the responses kept)
// the held part is solved afresh; released ones join the border. Every answer equals a
// fresh solve without refinement, all on one factor.
TEST(InterpolationSolver, NewValuesAtManyOriginallyHeldVerticesEqualAFreshSolve) {
  const Mesh sphere = make(icosphere(3));  // 642 vertices
  const FemOperators ops = build_cotan_operators(sphere);
  const InterpolationParams params{.g1 = 0, .g2 = 1};
  InterpolationSolver solver(sphere, ops, FieldKind::Scalar, params);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> value(-2, 2);
  std::vector<int> held;
  for (int v = 0; v < sphere.num_vertices(); v += 7) held.push_back(v);  // 92 vertices
  for (const int v : held) solver.set_value(v, Eigen::VectorXd::Constant(1, value(rng)));
  solver.solve();
  const auto check = [&](const std::string& what) {
    const InterpolationResult kept = solve_like_a_fresh_plate(solver, sphere, ops, what);
    // The kept columns alone give it: no refinement step was needed.
    EXPECT_EQ(kept.cg.iterations, 0) << what;
  };
  // One at a time, past the number of responses kept (64), revisiting some.
  for (int k = 0; k < 80; ++k) {
    solver.set_value(held[static_cast<std::size_t>((k * 5) % held.size())], Eigen::VectorXd::Constant(1, value(rng)));
    check(fmt::format("one value changed, step {}", k));
  }
  // Ten at once.
  for (int k = 0; k < 10; ++k)
    solver.set_value(held[static_cast<std::size_t>(k)], Eigen::VectorXd::Constant(1, value(rng)));
  check("ten values changed at once");
  // Released and changed together.
  for (int k = 20; k < 26; ++k) solver.remove(held[static_cast<std::size_t>(k)]);
  solver.set_value(held[30], Eigen::VectorXd::Constant(1, value(rng)));
  check("six released and one changed");
  solver.set_value(held[20], Eigen::VectorXd::Constant(1, value(rng)));
  check("one restored");
  EXPECT_EQ(solver.factorizations(), 1);
}

TEST(InterpolationSolver, NewValuesAtTheSameVerticesKeepTheFactor) {
  const Mesh sphere = make(icosphere(3));
  InterpolationSolver solver(sphere);
  solver.set_value(0, Eigen::VectorXd::Constant(1, 1.0));
  solver.set_value(100, Eigen::VectorXd::Constant(1, -1.0));
  const Field first = solver.solve().values;
  solver.set_value(100, Eigen::VectorXd::Constant(1, 3.0));
  const Field second = solver.solve().values;
  EXPECT_EQ(solver.factorizations(), 1);
  EXPECT_EQ(solver.changed_constraints(), 0);
  EXPECT_EQ(second(100, 0), 3.0);
  // The problem is linear in the values: doubling them doubles the field.
  solver.set_value(0, Eigen::VectorXd::Constant(1, 2.0));
  solver.set_value(100, Eigen::VectorXd::Constant(1, -2.0));
  EXPECT_LT(relative_difference(solver.solve().values, 2 * first), 1e-12);
  // The owning constructor chose its operators as interpolate() does.
  const InterpolationResult fresh =
      interpolate(sphere, FieldKind::Scalar, solver.constraints(), InterpolationParams{.solver = SteadySolver::Direct});
  EXPECT_LT(relative_difference(solver.solve().values, fresh.values), 1e-10);
  EXPECT_EQ(solver.solve().laplacian, fresh.laplacian);
}

TEST(InterpolationSolver, BadRequestsAreRefusedInWords) {
  const Mesh sphere = make(icosphere(2));
  EXPECT_NE(error_of([&] { InterpolationSolver(sphere).solve(); }).find("at least one"), std::string::npos);
  EXPECT_NE(error_of([&] { InterpolationSolver(sphere).remove(3); }).find("not constrained"), std::string::npos);
  EXPECT_NE(error_of([&] {
              InterpolationSolver(sphere, FieldKind::Tangent, InterpolationParams{.method = TangentMethod::Connection});
            }).find("componentwise"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              InterpolationSolver(sphere, FieldKind::Scalar, InterpolationParams{.solver = SteadySolver::Iterative});
            }).find("direct factor"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              InterpolationSolver(sphere).set_value(sphere.num_vertices(), Eigen::VectorXd::Constant(1, 1.0));
            }).find("does not exist"),
            std::string::npos);
  EXPECT_NE(error_of([&] { InterpolationSolver(sphere).set_value(0, Eigen::VectorXd::Zero(3)); }).find("expected 1"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              InterpolationSolver(sphere).set_value(0, Eigen::VectorXd::Constant(1, std::nan("")));
            }).find("not finite"),
            std::string::npos);
}

TEST(InterpolationSolver, APartLeftWithoutConstraintsIsASolverError) {
  // Two spheres apart: removing the only constraint on the second leaves it undetermined.
  GeneratedMesh a = icosphere(2), b = icosphere(2);
  Positions V(a.V.rows() + b.V.rows(), 3);
  V << a.V, (b.V.rowwise() + Eigen::RowVector3d(5, 0, 0));
  Triangles F(a.F.rows() + b.F.rows(), 3);
  F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  const Mesh two(V, F);
  InterpolationSolver solver(two);
  const int on_b = static_cast<int>(a.V.rows()) + 3;
  solver.set_value(0, Eigen::VectorXd::Constant(1, 1.0));
  solver.set_value(on_b, Eigen::VectorXd::Constant(1, 2.0));
  const Field u = solver.solve().values;
  EXPECT_NEAR(u(on_b + 5, 0), 2.0, 1e-9);  // a lone constraint holds its part constant
  solver.remove(on_b);
  EXPECT_THROW(solver.solve(), SolverError);
  solver.set_value(on_b + 1, Eigen::VectorXd::Constant(1, -1.0));
  EXPECT_NEAR(solver.solve().values(on_b + 7, 0), -1.0, 1e-9);
}

// Which factor: the Laplacian's (the mixed form) for a plate with few constraints at
// the fresh start, K D K's with a membrane part or with more than 64; the same answer
// as a fresh direct interpolate() either way, and across a fresh start that changes
// from one to the other.
TEST(InterpolationSolver, APlateWithFewConstraintsFactorsTheLaplacian) {
  const Mesh sphere = make(icosphere(4));
  const FemOperators ops = build_cotan_operators(sphere);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> vertex(0, sphere.num_vertices() - 1);
  std::uniform_real_distribution<double> value(-1, 1);
  for (const double g1 : {0.0, 0.5}) {
    InterpolationSolver solver(sphere, ops, FieldKind::Scalar, InterpolationParams{.g1 = g1, .g2 = 1});
    for (int k = 0; k < 10; ++k) solver.set_value(vertex(rng), Eigen::VectorXd::Constant(1, value(rng)));
    const InterpolationParams direct{.g1 = g1, .g2 = 1, .solver = SteadySolver::Direct};
    auto check = [&](const std::string& what) {
      const InterpolationResult kept = solver.solve();
      const InterpolationResult fresh = interpolate(sphere, ops, FieldKind::Scalar, solver.constraints(), direct);
      EXPECT_LT(relative_difference(kept.values, fresh.values), 1e-10) << what << ", g1 " << g1;
    };
    check("first solve");
    EXPECT_EQ(solver.laplacian_factor(), g1 == 0);
    solver.set_value(vertex(rng), Eigen::VectorXd::Constant(1, value(rng)));  // a new vertex: bordered
    check("a new vertex");
    EXPECT_EQ(solver.factorizations(), 1);
    // Past 64 constraints a fresh start factors K D K.
    solver.max_changes = 0;
    while (solver.num_constraints() <= 64) solver.set_value(vertex(rng), Eigen::VectorXd::Constant(1, value(rng)));
    check("70 constraints");
    EXPECT_FALSE(solver.laplacian_factor());
    EXPECT_EQ(solver.factorizations(), 2);
    // And back.
    while (solver.num_constraints() > 20) solver.remove(solver.constraints().front().vertex);
    check("20 constraints");
    EXPECT_EQ(solver.laplacian_factor(), g1 == 0);
  }
}
