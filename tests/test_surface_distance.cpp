// mesh/surface_distance.h: point-triangle and Hausdorff distances against hand-computed
// cases and concentric spheres.
#include <gtest/gtest.h>

#include <cmath>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/surface_distance.h"

using namespace meshpde;

TEST(SurfaceDistance, PointTriangleAndHausdorffAgainstHandComputedCases) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_DOUBLE_EQ(point_triangle_distance(Eigen::Vector3d(0.2, 0.2, 3), a, b, c), 3.0);           // face
  EXPECT_DOUBLE_EQ(point_triangle_distance(Eigen::Vector3d(-3, -4, 0), a, b, c), 5.0);             // vertex
  EXPECT_NEAR(point_triangle_distance(Eigen::Vector3d(1, 1, 0), a, b, c), std::sqrt(0.5), 1e-15);  // edge
  // Two concentric icospheres: every sample of the outer one is 0.5 from the inner
  // surface at most (more where the inner facets are flat), at least 0.5 - chord error.
  const GeneratedMesh s1 = icosphere(3, 1.0), s2 = icosphere(3, 1.5);
  const double h = hausdorff_distance(s1.V, s1.F, s2.V, s2.F);
  EXPECT_GT(h, 0.5);
  EXPECT_LT(h, 0.52);
  EXPECT_LT(hausdorff_distance(s1.V, s1.F, s1.V, s1.F), 1e-12);
}
