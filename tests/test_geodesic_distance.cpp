// mesh/geodesic_distance.h and surface points (mesh/surface_distance.h): distances on
// the surface against analytic ones (plane, sphere, cylinder), their convergence
// order, and the cut-off and errors.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

namespace {

// Largest error against `exact` over the vertices with exact distance in [lo, hi].
template <class Exact>
double worst_error(const Mesh& m, const Eigen::VectorXd& d, Exact&& exact, double lo, double hi) {
  double worst = 0;
  for (int v = 0; v < m.num_vertices(); ++v) {
    const double e = exact(v);
    if (e >= lo && e <= hi) worst = std::max(worst, std::abs(d[v] - e));
  }
  return worst;
}

}  // namespace

// On a plane, distance from a point inside a triangle is the straight line: exact to
// rounding on a regular grid and on a jittered one (obtuse triangles included), where
// edge paths are off by several per cent.
TEST(GeodesicDistance, OnAPlaneItIsTheStraightLineFromAPointInATriangle) {
  for (const double jitter : {0.0, 0.3}) {
    const int n = 40;
    const GeneratedMesh g = test::jittered_plane(n, jitter / n, 7);
    const Mesh m = make(g);
    const Eigen::Vector3d x(0.4137, 0.5261, 0);
    const SurfacePoint p = closest_surface_points(m, std::span<const Eigen::Vector3d>(&x, 1))[0];
    ASSERT_LT((position(m, p) - x).norm(), 1e-12);
    const Eigen::VectorXd d = geodesic_distance(m, GeodesicSources{.points = {p}});
    auto exact = [&](int v) { return (m.positions().row(v).transpose() - x).norm(); };
    const double h = 1.0 / n;
    const double err = worst_error(m, d, exact, 0, 0.35);
    // Edge paths from the nearest vertex, for comparison (plus that vertex's offset).
    int nearest = 0;
    for (int v = 0; v < m.num_vertices(); ++v)
      if (exact(v) < exact(nearest)) nearest = v;
    std::vector<int> src{nearest};
    Eigen::VectorXd edge = Eigen::VectorXd::Constant(m.num_vertices(), 1e9);
    for (const auto& [v, dv] : geodesic_distances(m, src, 10.0)) edge[v] = dv + exact(nearest);
    const double edge_err = worst_error(m, edge, exact, 0, 0.35);
    RecordProperty(fmt::format("jitter{}_error_over_h", jitter), fmt::format("{:.3g}", err / h));
    EXPECT_LT(err, 1e-12) << "jitter " << jitter;
    EXPECT_GT(edge_err, 0.1 * h) << "edge paths should be worse";
  }
}

// A sphere of radius 1 (icospheres, distance from a vertex): against the great-circle
// distance within 1 (a region as wide as the sphere is curved), the error falls like the
// edge length (the unfolding treats each triangle's wavefront as a planar circle's) and
// stays a few hundredths of an edge, while edge paths stay off by about 0.15 whatever
// the resolution.
TEST(GeodesicDistance, OnASphereItConvergesToTheGreatCircleDistance) {
  std::vector<double> err, hs, edge_err;
  for (int level = 3; level <= 5; ++level) {
    const Mesh m = make(icosphere(level));
    const Eigen::RowVector3d s = m.positions().row(0);
    auto exact = [&](int v) { return std::acos(std::clamp(m.positions().row(v).dot(s), -1.0, 1.0)); };
    const Eigen::VectorXd d = geodesic_distance(m, GeodesicSources{.vertices = {0}});
    err.push_back(worst_error(m, d, exact, 0, 1.0));
    std::vector<int> src{0};
    Eigen::VectorXd edge = Eigen::VectorXd::Constant(m.num_vertices(), 1e9);
    for (const auto& [v, dv] : geodesic_distances(m, src, 10.0)) edge[v] = dv;
    edge_err.push_back(worst_error(m, edge, exact, 0, 1.0));
    hs.push_back(mean_edge_length(m));
  }
  for (std::size_t k = 0; k < err.size(); ++k) {
    EXPECT_LT(err[k], 0.05 * hs[k]) << "level " << k + 3;
    EXPECT_GT(edge_err[k], 0.1) << "level " << k + 3;
  }
  for (std::size_t k = 0; k + 1 < err.size(); ++k) {
    const double order = std::log(err[k] / err[k + 1]) / std::log(hs[k] / hs[k + 1]);
    RecordProperty(fmt::format("sphere_order_{}", k), fmt::format("{:.2f}", order));
    EXPECT_GE(order, 0.9) << "errors " << err[k] << " -> " << err[k + 1];
  }
}

// A cylinder of radius 1 unrolls to a plane: the distance from a vertex is
// sqrt((r theta)^2 + z^2), theta the angle around the axis.
TEST(GeodesicDistance, OnACylinderItIsTheUnrolledStraightLine) {
  std::vector<double> err, hs;
  for (const int segments : {32, 64, 128}) {
    const double r = 1, length = 6;
    const int rings = static_cast<int>(std::lround(length / (2 * std::numbers::pi * r / segments))) + 1;
    const Mesh m = make(tube(r, length, rings, segments));
    int source = 0;  // the vertex nearest the middle of the tube at angle 0
    for (int v = 0; v < m.num_vertices(); ++v) {
      const auto p = m.positions().row(v);
      const auto q = m.positions().row(source);
      if (std::abs(p.z() - length / 2) + std::abs(std::atan2(p.y(), p.x())) <
          std::abs(q.z() - length / 2) + std::abs(std::atan2(q.y(), q.x())))
        source = v;
    }
    const Eigen::RowVector3d s = m.positions().row(source);
    auto exact = [&](int v) {
      const auto p = m.positions().row(v);
      const double dtheta = std::remainder(std::atan2(p.y(), p.x()) - std::atan2(s.y(), s.x()), 2 * std::numbers::pi);
      return std::hypot(r * dtheta, p.z() - s.z());
    };
    const Eigen::VectorXd d = geodesic_distance(m, GeodesicSources{.vertices = {source}}, 2.5);
    for (int v = 0; v < m.num_vertices(); ++v) {
      if (std::isinf(d[v])) {
        EXPECT_GE(exact(v), 2.5 - 0.05) << "vertex " << v << " within the radius was not reached";
      } else {
        EXPECT_LT(d[v], 2.5);
      }
    }
    // Away from the ends (the tube's polygon is inside the cylinder: compare at < 2.5).
    err.push_back(worst_error(m, d, exact, 0, 2.4));
    hs.push_back(mean_edge_length(m));
  }
  for (std::size_t k = 0; k + 1 < err.size(); ++k) {
    const double order = std::log(err[k] / err[k + 1]) / std::log(hs[k] / hs[k + 1]);
    RecordProperty(fmt::format("cylinder_order_{}", k), fmt::format("{:.2f}", order));
    EXPECT_GE(order, 1.5) << "errors " << err[k] << " -> " << err[k + 1];
  }
  EXPECT_LT(err.back(), 0.02 * hs.back());
}

TEST(GeodesicDistance, TheRadiusCutsTheSearchAndSeveralSourcesTakeTheNearest) {
  const Mesh m = make(icosphere(4));
  const int a = 0, b = m.num_vertices() / 2;
  const auto both = geodesic_distances_from(m, GeodesicSources{.vertices = {a, b}}, 0.8);
  const Eigen::VectorXd da = geodesic_distance(m, GeodesicSources{.vertices = {a}});
  const Eigen::VectorXd db = geodesic_distance(m, GeodesicSources{.vertices = {b}});
  double last = 0;
  int inside = 0;
  for (const auto& [v, d] : both) {
    EXPECT_GE(d, last);
    last = d;
    EXPECT_LT(d, 0.8);
    // The union's distance is the smaller one, up to where their fronts meet.
    EXPECT_LE(d, std::min(da[v], db[v]) + 1e-12);
    EXPECT_GE(d, std::min(da[v], db[v]) - 0.02);
  }
  for (int v = 0; v < m.num_vertices(); ++v) inside += std::min(da[v], db[v]) < 0.8 - 0.02;
  EXPECT_GE(static_cast<int>(both.size()), inside);
}

// The search sizes its tables from the radius (a disc at the source's edge length):
// radii far below an edge, about a region, and beyond the whole mesh, from a vertex and
// from a point, all give the whole search's distances inside the radius, in order.
TEST(GeodesicDistance, EveryRadiusGivesTheWholeSearchsDistancesInsideIt) {
  const Mesh m = make(icosphere(4));
  const SurfacePoint p{.face = 7, .bary = {0.2, 0.3, 0.5}};
  for (const GeodesicSources& sources : {GeodesicSources{.vertices = {3}}, GeodesicSources{.points = {p}},
                                         GeodesicSources{.vertices = {3, 100}, .points = {p}}}) {
    const Eigen::VectorXd whole = geodesic_distance(m, sources);
    for (const double radius : {1e-3, 0.05, 0.7, 10.0}) {
      const auto within = geodesic_distances_from(m, sources, radius);
      int inside = 0;
      for (int v = 0; v < m.num_vertices(); ++v) inside += whole[v] < radius;
      EXPECT_EQ(static_cast<int>(within.size()), inside) << "radius " << radius;
      double last = 0;
      for (const auto& [v, d] : within) {
        EXPECT_NEAR(d, whole[v], 1e-12) << "vertex " << v << ", radius " << radius;
        EXPECT_GE(d, last);
        last = d;
      }
    }
  }
}

TEST(GeodesicDistance, SurfacePointsAreTheClosestAndBadSourcesAreRefused) {
  const Mesh m = make(icosphere(3));
  const Eigen::Vector3d far(0.3, -2.0, 0.1);
  const SurfacePoint p = closest_surface_points(m, std::span<const Eigen::Vector3d>(&far, 1))[0];
  // Independent: the nearest over every triangle by brute force.
  double best = 1e9;
  for (int f = 0; f < m.num_faces(); ++f)
    best = std::min(best, point_triangle_distance(far, m.positions().row(m.triangles()(f, 0)).transpose(),
                                                  m.positions().row(m.triangles()(f, 1)).transpose(),
                                                  m.positions().row(m.triangles()(f, 2)).transpose()));
  EXPECT_NEAR((position(m, p) - far).norm(), best, 1e-12);
  EXPECT_NEAR(p.bary.sum(), 1.0, 1e-12);
  EXPECT_GE(p.bary.minCoeff(), 0.0);
  EXPECT_NE(error_of([&] { geodesic_distance(m, GeodesicSources{.vertices = {m.num_vertices()}}); }).find("vertex"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              geodesic_distance(m, GeodesicSources{.points = {SurfacePoint{.face = 0, .bary = {0.5, 0.6, 0}}}});
            }).find("barycentric"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              geodesic_distance(m, GeodesicSources{.points = {SurfacePoint{.face = -1}}});
            }).find("triangle -1"),
            std::string::npos);
  const Eigen::Vector3d nan(std::nan(""), 0, 0);
  EXPECT_NE(error_of([&] { closest_surface_points(m, std::span<const Eigen::Vector3d>(&nan, 1)); }).find("not finite"),
            std::string::npos);
}
