// mesh/self_intersections.h: the triangle-pair test and the checker that follows the
// moved region, against the whole-mesh check (CGAL's count: test_self_intersections_cgal.cpp).
#include <gtest/gtest.h>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/self_intersections.h"
#include "test_support.h"

using namespace meshpde;

TEST(SelfIntersections, TriangleTestsAndTheCheckerFollowTheMovedRegion) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_TRUE(triangles_intersect(a, b, c, {0.2, 0.2, -1}, {0.2, 0.2, 1}, {0.3, 0.25, 1}));
  EXPECT_FALSE(triangles_intersect(a, b, c, {0.2, 0.2, 0.1}, {0.2, 0.2, 1}, {0.3, 0.25, 1}));
  // A tube: push a wall vertex straight through the opposite wall.
  const Mesh t = test::make(tube(5.0, 60.0, 25, 24));
  const SelfIntersectionChecker checker(t);
  EXPECT_TRUE(checker.all_pairs().empty());
  int v = 0;
  (t.positions().rowwise() - Eigen::RowVector3d(5, 0, 30)).rowwise().squaredNorm().minCoeff(&v);
  Positions V = t.positions();
  EXPECT_EQ(checker.count_new(V, std::vector<int>{v}), 0);
  V(v, 0) = -7;  // through the wall at x = -5
  const int n = checker.count_new(V, std::vector<int>{v});
  EXPECT_GT(n, 0);
  // The same count from the whole-mesh check built on the moved positions.
  Mesh moved = t;
  moved.set_positions(V);
  EXPECT_EQ(static_cast<int>(SelfIntersectionChecker(moved).all_pairs().size()), n);
}
