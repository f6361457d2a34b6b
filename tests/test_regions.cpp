// mesh/regions.h: balls by distance or rings, the region rule, and brushes.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <map>
#include <queue>
#include <set>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/topology.h"
#include "solver_problems.h"
#include "test_support.h"

using namespace meshpde;
using test::bumpy_sphere;
using test::make;

TEST(Regions, RingBallHoldsExactlyTheVerticesWithinKEdges) {
  const Mesh m = make(icosphere(3));
  // Independent: breadth-first hop counts over the edge list.
  std::vector<int> hops(static_cast<std::size_t>(m.num_vertices()), -1);
  hops[0] = 0;
  for (int k = 0; k < 3; ++k)
    for (int e = 0; e < m.num_edges(); ++e)
      for (int s = 0; s < 2; ++s) {
        const int a = m.edges()(e, s), b = m.edges()(e, 1 - s);
        if (hops[static_cast<std::size_t>(a)] == k && hops[static_cast<std::size_t>(b)] < 0)
          hops[static_cast<std::size_t>(b)] = k + 1;
      }
  const std::vector<int> ball = ring_ball(m, 0, 3);
  EXPECT_EQ(ball.front(), 0);
  std::set<int> expected;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (hops[static_cast<std::size_t>(v)] >= 0) expected.insert(v);
  EXPECT_EQ(std::set<int>(ball.begin(), ball.end()), expected);
}

// Multi-source distances: each vertex's distance is the least over the sources of
// the single-source ball's, the vertex set is the union of the balls, and the order is
// by distance.
TEST(Regions, GeodesicDistancesFromSeveralSourcesAreTheNearestBalls) {
  const Mesh m = bumpy_sphere(4);
  const int a = 0, b = m.num_vertices() / 2;
  const double radius = 0.9;
  const auto got = geodesic_distances(m, std::vector<int>{a, b}, radius);
  std::set<int> union_of;
  for (int s : {a, b})
    for (int v : geodesic_ball(m, s, radius)) union_of.insert(v);
  std::set<int> seen;
  double last = 0;
  for (const auto& [v, d] : got) {
    EXPECT_TRUE(seen.insert(v).second) << "vertex " << v << " twice";
    EXPECT_GE(d, last);
    last = d;
    EXPECT_LT(d, radius);
  }
  EXPECT_EQ(seen, union_of);
  // Single source: the distance of the path through the neighbour that gives the least.
  const auto one = geodesic_distances(m, std::vector<int>{a}, radius);
  std::map<int, double> dist(one.begin(), one.end());
  for (const auto& [v, d] : one) {
    if (v == a) {
      EXPECT_EQ(d, 0.0);
      continue;
    }
    double best = std::numeric_limits<double>::infinity();
    for (int w : m.neighbors(v))
      if (dist.count(w)) best = std::min(best, dist[w] + (m.positions().row(v) - m.positions().row(w)).norm());
    EXPECT_NEAR(d, best, 1e-12);
  }
  EXPECT_THROW(geodesic_distances(m, std::vector<int>{-1}, 1.0), InputError);
}

TEST(Regions, RegionAroundTakesARadiusOrRingsNeverBoth) {
  const Mesh m = make(icosphere(3));
  // By radius: the vertices nearer on the surface, nearest first; a surface distance is
  // never longer than an edge path, so the edge-path ball is inside, and here smaller
  // (47 vertices against 57).
  const std::vector<int> by_radius = region_around(m, 100, RegionSpec{.radius = 0.6, .rings = 0});
  std::vector<int> surface;
  for (const auto& [v, d] : geodesic_distances_from(m, GeodesicSources{.vertices = {100}}, 0.6)) surface.push_back(v);
  EXPECT_EQ(by_radius, surface);
  const std::vector<int> edge_ball = geodesic_ball(m, 100, 0.6);
  const std::set<int> in(by_radius.begin(), by_radius.end());
  for (const int v : edge_ball) EXPECT_TRUE(in.count(v)) << v;
  EXPECT_GT(by_radius.size(), edge_ball.size());
  // The correction's older rules keep the edge-path ball.
  EXPECT_EQ(influence_region(m, std::vector<int>{100}, RegionSpec{.radius = 0.6, .rings = 0}, false), edge_ball);
  EXPECT_THROW(influence_region(m, std::vector<int>{100}, RegionSpec{.radius = 0.6, .rings = 2}, false), InputError);
  EXPECT_EQ(region_around(m, 5, RegionSpec{.radius = 0, .rings = 2}), ring_ball(m, 5, 2));
  EXPECT_THROW(region_around(m, 5, RegionSpec{.radius = 0.3, .rings = 2}), InputError);
  EXPECT_THROW(region_around(m, 5, RegionSpec{}), InputError);
  EXPECT_THROW(region_around(m, -1, RegionSpec{.radius = 1, .rings = 0}), InputError);
  EXPECT_THROW(region_around(m, m.num_vertices(), RegionSpec{.radius = 1, .rings = 0}), InputError);
}

TEST(Regions, RingsForRadiusIsTheRadiusInMeanEdges) {
  const Mesh m = make(icosphere(3));
  const double h = mean_edge_length(m);
  EXPECT_EQ(rings_for_radius(m, 4.2 * h), 4);
  EXPECT_EQ(rings_for_radius(m, 4.6 * h), 5);
  EXPECT_EQ(rings_for_radius(m, 0.1 * h), 1);  // at least one ring
}

TEST(Regions, BrushPaintsItsGeodesicBallAndNothingElse) {
  const Mesh m = make(icosphere(3));
  Eigen::VectorXd w;  // empty: starts at 1
  apply_brush(m, w, Brush{.vertex = 7, .radius = 0.4, .value = 5});
  const std::vector<int> ball = geodesic_ball(m, 7, 0.4);
  const std::set<int> in(ball.begin(), ball.end());
  ASSERT_EQ(w.size(), m.num_vertices());
  for (int v = 0; v < m.num_vertices(); ++v) EXPECT_EQ(w[v], in.count(v) ? 5.0 : 1.0) << v;
  // a second stroke paints over the first
  apply_brush(m, w, Brush{.vertex = 7, .radius = 0.1, .value = 2});
  EXPECT_EQ(w[7], 2.0);
  EXPECT_THROW(apply_brush(m, w, Brush{.vertex = 7, .radius = 0, .value = 2}), InputError);
  EXPECT_THROW(apply_brush(m, w, Brush{.vertex = 7, .radius = 1, .value = -1}), InputError);
  EXPECT_THROW(apply_brush(m, w, Brush{.vertex = 9999, .radius = 1, .value = 1}), InputError);
  Eigen::VectorXd short_field = Eigen::VectorXd::Ones(3);
  EXPECT_THROW(apply_brush(m, short_field, Brush{.vertex = 7, .radius = 1, .value = 1}), InputError);
}

TEST(Regions, BrushesAreParsedAsTheCliWritesThem) {
  const Mesh m = make(icosphere(2));
  const Brush b = parse_brush(m, "12:2.5:3");
  EXPECT_EQ(b.vertex, 12);
  EXPECT_EQ(b.radius, 2.5);
  EXPECT_EQ(b.value, 3);
  const Eigen::Vector3d p = m.positions().row(20);
  const Brush at = parse_brush(m, fmt::format("@{},{},{}:1:2", p.x(), p.y(), p.z()));
  EXPECT_EQ(at.vertex, 20);
  for (const char* bad : {"12:2.5", "12:x:3", "12:2:0", "12:2:3x", "99999:1:1"})
    EXPECT_THROW(parse_brush(m, bad), InputError) << bad;
}

TEST(Regions, GeodesicBallIsDijkstraOverTheWholeMesh) {
  // Independent: Dijkstra over every vertex with std::priority_queue and whole-mesh
  // arrays. The ball must hold exactly the vertices closer than the radius, the source
  // first and the others in order of their distance.
  const Mesh m = bumpy_sphere(5);
  const int n = m.num_vertices();
  for (const int source : {0, 777, 5000})
    for (const double radius : {0.05, 0.3, 1.0, 10.0}) {
      std::vector<double> dist(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
      using Item = std::pair<double, int>;
      std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
      dist[static_cast<std::size_t>(source)] = 0;
      heap.emplace(0.0, source);
      while (!heap.empty()) {
        const auto [d, v] = heap.top();
        heap.pop();
        if (d > dist[static_cast<std::size_t>(v)]) continue;
        for (int w : m.neighbors(v)) {
          const double dw = d + (m.positions().row(v) - m.positions().row(w)).norm();
          if (dw < dist[static_cast<std::size_t>(w)]) {
            dist[static_cast<std::size_t>(w)] = dw;
            heap.emplace(dw, w);
          }
        }
      }
      const std::vector<int> ball = geodesic_ball(m, source, radius);
      std::vector<int> expected;
      for (int v = 0; v < n; ++v)
        if (dist[static_cast<std::size_t>(v)] < radius) expected.push_back(v);
      ASSERT_FALSE(ball.empty());
      EXPECT_EQ(ball.front(), source);
      for (std::size_t k = 1; k < ball.size(); ++k)
        EXPECT_LE(dist[static_cast<std::size_t>(ball[k - 1])], dist[static_cast<std::size_t>(ball[k])]);
      std::vector<int> sorted = ball;
      std::sort(sorted.begin(), sorted.end());
      EXPECT_EQ(sorted, expected) << "source " << source << ", radius " << radius;
    }
}
