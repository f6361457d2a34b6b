// The one-include API (meshpde/meshpde.h) and the plain (V, F) forms of the one-off
// functions: each equals the (Mesh, FemOperators) form it stands for.
#include <gtest/gtest.h>
#include <meshpde/meshpde.h>

using namespace meshpde;

namespace {

struct Sphere {
  GeneratedMesh g = icosphere(3);
  Mesh mesh{g.V, g.F};
  FemOperators ops = build_cotan_operators(mesh);
};

}  // namespace

TEST(Api, PlainArraysGiveTheAnswersOfMeshAndOperators) {
  const Sphere s;
  const Field U = s.g.V;  // three columns
  EXPECT_EQ(apply_stiffness(s.g.V, s.g.F, U), apply_stiffness(s.mesh, s.ops, U));
  EXPECT_EQ(apply_bilaplacian(s.g.V, s.g.F, U), apply_bilaplacian(s.mesh, s.ops, U));
  EXPECT_EQ((stiffness_matrix(s.g.V, s.g.F) - stiffness_matrix(s.mesh, s.ops)).norm(), 0.0);
  EXPECT_EQ((mass_matrix(s.g.V, s.g.F) - mass_matrix(s.ops)).norm(), 0.0);
  EXPECT_EQ(mean_curvature(s.g.V, s.g.F, CurvatureScale::Area), mean_curvature(s.mesh, s.ops, CurvatureScale::Area));
  const std::vector<InterpolationConstraint> cons{{0, Eigen::VectorXd::Constant(1, 1.0)},
                                                  {100, Eigen::VectorXd::Constant(1, -1.0)}};
  EXPECT_EQ(interpolate(s.g.V, s.g.F, FieldKind::Scalar, cons).values,
            interpolate(s.mesh, s.ops, FieldKind::Scalar, cons).values);
  const PropagationParams heat{.steps = 5, .fixed = {{0, 1.0}}};
  EXPECT_EQ(propagate(s.g.V, s.g.F, heat).values, propagate(s.mesh, s.ops, heat).values);
  const DragParams drag{.vertex = 3, .displacement = Eigen::Vector3d(0, 0, 0.1), .rings = 2};
  EXPECT_EQ(drag_vertex(s.g.V, s.g.F, drag).V, drag_vertex(s.mesh, s.ops, drag).V);
  std::vector<int> free;
  Field held = Field::Zero(s.mesh.num_vertices(), 1);
  for (int v = 0; v < s.mesh.num_vertices(); ++v)
    if (s.g.V(v, 2) > -0.5)
      free.push_back(v);
    else
      held(v, 0) = s.g.V(v, 0);
  const PdeCoefficients plate{.g1 = 0, .g2 = 1};
  EXPECT_EQ(solve_steady(s.g.V, s.g.F, plate, free, held, SteadySolver::Direct).values,
            solve_steady(s.mesh, s.ops, plate, free, held, SteadySolver::Direct).values);
  EXPECT_EQ(solve_global_bilaplacian(s.g.V, s.g.F, free, held).values,
            solve_global_bilaplacian(s.mesh, s.ops, free, held).values);
}

TEST(Api, PlainArraysAreCheckedAsMeshesAre) {
  GeneratedMesh g = icosphere(1);
  g.F(3, 1) = 999;  // out of range
  EXPECT_THROW(mean_curvature(g.V, g.F, CurvatureScale::Area), InputError);
}

TEST(Api, PlainArraysChooseTheLaplacianTheSameWayEverywhere) {
  // A plane with a column of slivers (angles far below 1 degree): Auto takes the
  // intrinsic Delaunay operators there, and every (V, F) form does what
  // build_mesh_operators(Auto) does, as interpolate() always did.
  GeneratedMesh g = plane_grid(16, 16, 1.0, 1.0);
  const double h = 1.0 / 16;
  for (int v = 0; v < g.V.rows(); ++v)
    if (std::abs(g.V(v, 0) - 0.5) < 0.25 * h) g.V(v, 0) = 0.5 + h - 1e-4 * h;
  const MeshOperators mo = build_mesh_operators(Mesh(g.V, g.F), LaplacianKind::Auto);
  ASSERT_EQ(mo.kind, LaplacianKind::IntrinsicDelaunay) << mo.reason;
  const Mesh plain(g.V, g.F);
  const FemOperators cotan = build_cotan_operators(plain);
  std::vector<int> free;
  Field held = Field::Zero(plain.num_vertices(), 1);
  for (int v = 0; v < plain.num_vertices(); ++v) {
    const bool inside = g.V(v, 0) > 0.05 && g.V(v, 0) < 0.95 && g.V(v, 1) > 0.05 && g.V(v, 1) < 0.95;
    if (inside)
      free.push_back(v);
    else
      held(v, 0) = g.V(v, 1);
  }
  const PdeCoefficients plate{.g1 = 0, .g2 = 1};
  const Field steady = solve_steady(g.V, g.F, plate, free, held, SteadySolver::Direct).values;
  EXPECT_EQ(steady, solve_steady(mo.mesh, mo.ops, plate, free, held, SteadySolver::Direct).values);
  EXPECT_GT((steady - solve_steady(plain, cotan, plate, free, held, SteadySolver::Direct).values).norm(), 1e-6)
      << "the slivers should change the answer, or this test checks nothing";
  EXPECT_EQ(solve_steady(g.V, g.F, plate, free, held, SteadySolver::Direct, LaplacianKind::Cotan).values,
            solve_steady(plain, cotan, plate, free, held, SteadySolver::Direct).values);
  EXPECT_EQ(solve_global_bilaplacian(g.V, g.F, free, held).values,
            solve_global_bilaplacian(mo.mesh, mo.ops, free, held).values);
  const int centre = free[free.size() / 2];
  const DragParams drag{.vertex = centre, .displacement = Eigen::Vector3d(0, 0, 0.1), .rings = 4};
  EXPECT_EQ(drag_vertex(g.V, g.F, drag).V, drag_vertex(mo.mesh, mo.ops, drag).V);
  const PropagationParams heat{.steps = 5, .fixed = {{centre, 1.0}}};
  EXPECT_EQ(propagate(g.V, g.F, heat).values, propagate(mo.mesh, mo.ops, heat).values);
  const std::vector<InterpolationConstraint> cons{{free.front(), Eigen::VectorXd::Constant(1, 1.0)},
                                                  {free.back(), Eigen::VectorXd::Constant(1, -1.0)}};
  EXPECT_EQ(interpolate(g.V, g.F, FieldKind::Scalar, cons).values,
            interpolate(mo.mesh, mo.ops, FieldKind::Scalar, cons).values);
}
