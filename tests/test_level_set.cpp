// mesh/level_set.h: the level set of a vertex field as segments, exact for a field
// linear on the surface; what it skips and refuses.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/level_set.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

// u = 0.3 x + 0.7 y on a jittered unit square: the level set u = 0.5 is a straight line,
// and the segments are pieces of it exactly: every end on the line and on an edge of
// its triangle, their lengths adding up to the line's length inside the square.
TEST(LevelSet, ALinearFieldsLevelSetIsItsLineExactly) {
  const Mesh m = make(test::jittered_plane(24, 0.3 / 24, 5));
  const Eigen::VectorXd u = 0.3 * m.positions().col(0) + 0.7 * m.positions().col(1);
  const std::vector<LevelSetSegment> s = level_set_segments(m, u, 0.5);
  ASSERT_GT(s.size(), 24u);
  double length = 0;
  for (const LevelSetSegment& seg : s) {
    for (const Eigen::Vector3d* x : {&seg.a, &seg.b}) {
      EXPECT_NEAR(0.3 * x->x() + 0.7 * x->y(), 0.5, 1e-12);
      // On one of the triangle's edges: its distance to the nearest edge line is zero.
      double nearest = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = m.positions().row(m.triangles()(seg.face, k));
        const Eigen::Vector3d q = m.positions().row(m.triangles()(seg.face, (k + 1) % 3));
        nearest = std::min(nearest, ((*x - p).cross(q - p)).norm() / (q - p).norm());
      }
      EXPECT_LT(nearest, 1e-12);
    }
    length += (seg.b - seg.a).norm();
  }
  // From (0, 5/7) to (1, 2/7).
  EXPECT_NEAR(length, std::hypot(1.0, 3.0 / 7.0), 1e-12);
  // Restricted to some triangles: only theirs, in their order.
  const std::vector<int> faces = {s[3].face, s[0].face, 0};
  const std::vector<LevelSetSegment> some = level_set_segments(m, u, 0.5, faces);
  ASSERT_EQ(some.size(), 2u);  // triangle 0 (a corner of the square) is not crossed
  EXPECT_EQ(some[0].face, s[3].face);
  EXPECT_EQ(some[1].face, s[0].face);
  // The field read by vertex (what the editor's rim does with a region's distances):
  // the same segments, and a corner read only where a listed triangle needs it.
  std::vector<int> crossed;
  for (const LevelSetSegment& seg : s) crossed.push_back(seg.face);
  std::vector<char> read(static_cast<std::size_t>(m.num_vertices()), 0);
  const std::vector<LevelSetSegment> by_vertex = level_set_segments(
      m,
      [&](int v) {
        read[static_cast<std::size_t>(v)] = 1;
        return u[v];
      },
      0.5, crossed);
  ASSERT_EQ(by_vertex.size(), s.size());
  for (std::size_t k = 0; k < s.size(); ++k) {
    EXPECT_EQ(by_vertex[k].face, s[k].face);
    EXPECT_EQ(by_vertex[k].a, s[k].a);
    EXPECT_EQ(by_vertex[k].b, s[k].b);
  }
  std::vector<char> corner(static_cast<std::size_t>(m.num_vertices()), 0);
  for (const int f : crossed)
    for (int k = 0; k < 3; ++k) corner[static_cast<std::size_t>(m.triangles()(f, k))] = 1;
  EXPECT_EQ(read, corner);
}

TEST(LevelSet, SkipsUnmeasuredCornersAndRefusesBadInput) {
  const Mesh m = make(plane_grid(4, 4));
  Eigen::VectorXd u = m.positions().col(0);
  EXPECT_TRUE(level_set_segments(m, u, 2.0).empty());  // outside the field's range
  const std::size_t all = level_set_segments(m, u, 0.4).size();
  EXPECT_GT(all, 0u);
  // A vertex without a value, on the crossed band (x = 0.5, y = 0.5): the triangles
  // around it give nothing (exactly its crossed ones go), the others do.
  int v = 0;
  while ((m.positions().row(v) - Eigen::RowVector3d(0.5, 0.5, 0)).norm() > 1e-12) ++v;
  std::size_t crossed_around_v = 0;
  for (const LevelSetSegment& seg : level_set_segments(m, u, 0.4))
    for (int k = 0; k < 3; ++k) crossed_around_v += m.triangles()(seg.face, k) == v;
  ASSERT_GT(crossed_around_v, 0u);
  u[v] = std::numeric_limits<double>::infinity();
  const std::size_t fewer = level_set_segments(m, u, 0.4).size();
  EXPECT_EQ(fewer, all - crossed_around_v);
  u[v] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(level_set_segments(m, u, 0.4).size(), fewer);
  EXPECT_NE(error_of([&] { level_set_segments(m, Eigen::VectorXd::Zero(3), 0.4); }).find("3 values for 25 vertices"),
            std::string::npos);
  EXPECT_NE(error_of([&] { level_set_segments(m, u, NAN); }).find("not finite"), std::string::npos);
  const std::vector<int> bad = {m.num_faces()};
  EXPECT_NE(error_of([&] { level_set_segments(m, u, 0.4, bad); }).find("out of range"), std::string::npos);
}
