// Reading a vertex field at a point inside a triangle to second order
// (mesh/surface_point_reading.h): exact on quadratics, third order on a sphere where the
// corners' linear interpolation is second order, never across to another sheet.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/surface_point_reading.h"
#include "test_support.h"

using namespace meshpde;
using test::make;

namespace {

double read(const std::vector<std::pair<int, double>>& weights, const Eigen::VectorXd& f) {
  double s = 0;
  for (const auto& [v, w] : weights) s += w * f[v];
  return s;
}

// A jittered grid of the unit square, tilted out of the z = 0 plane.
Mesh tilted_plane(int n, unsigned seed) {
  GeneratedMesh g = plane_grid(n, n, 1.0, 1.0);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.2 / n, 0.2 / n);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (Eigen::Index i = 0; i < g.V.rows(); ++i) {
    Eigen::Vector3d y = g.V.row(i).transpose();
    if (y[0] > 0 && y[0] < 1 && y[1] > 0 && y[1] < 1) y += Eigen::Vector3d(jitter(rng), jitter(rng), 0);
    g.V.row(i) = (R * y).transpose();
  }
  return make(g);
}

}  // namespace

TEST(SurfacePointReading, IsExactOnQuadraticFieldsAndSumsToOne) {
  const Mesh m = tilted_plane(12, 4);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  // A field quadratic in the plane's own coordinates, read at points all over the square
  // (corners and edges included, where the fit reaches only to one side).
  Eigen::VectorXd f(m.num_vertices());
  auto field = [](const Eigen::Vector3d& q) {
    return 1.5 - 2 * q[0] + 0.5 * q[1] + 3 * q[0] * q[0] - q[0] * q[1] + 2 * q[1] * q[1];
  };
  for (int v = 0; v < m.num_vertices(); ++v) f[v] = field(R.transpose() * m.positions().row(v).transpose());
  int read_points = 0;
  for (int face = 0; face < m.num_faces(); face += 7) {
    const SurfacePoint p{face, Eigen::Vector3d(0.2, 0.3, 0.5)};
    const auto weights = quadratic_reading(m, p);
    ASSERT_TRUE(weights) << "face " << face;
    double sum = 0;
    for (const auto& [v, w] : *weights) sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_NEAR(read(*weights, f), field(R.transpose() * position(m, p)), 1e-11) << "face " << face;
    ++read_points;
  }
  EXPECT_GT(read_points, 30);
}

// f = z on a sphere of radius 1, read at one point of three icospheres: the quadratic
// reading's error falls at about third order (2.8 and 2.2 here) and is 50 to 200 times
// below the corners' linear interpolation's.
TEST(SurfacePointReading, ReadsASmoothFieldOnASphereToThirdOrder) {
  const Eigen::Vector3d target = Eigen::Vector3d(0.31, -0.42, 0.85).normalized();
  std::vector<double> fit, linear;
  for (const int level : {3, 4, 5}) {
    const Mesh m = make(icosphere(level, 1.0));
    const Eigen::VectorXd f = m.positions().col(2);
    const SurfacePoint p = closest_surface_points(m, std::span<const Eigen::Vector3d>(&target, 1))[0];
    const Eigen::Vector3d x = position(m, p);
    // The exact value at the surface point: the sphere's z straight out from x.
    const double exact = x.normalized()[2];
    const auto weights = quadratic_reading(m, p);
    ASSERT_TRUE(weights);
    fit.push_back(std::abs(read(*weights, f) - exact));
    linear.push_back(std::abs(x[2] - exact));
  }
  RecordProperty("fit", ::testing::PrintToString(fit));
  RecordProperty("linear", ::testing::PrintToString(linear));
  std::printf("quadratic reading error %.3g %.3g %.3g, linear %.3g %.3g %.3g\n", fit[0], fit[1], fit[2], linear[0],
              linear[1], linear[2]);
  for (std::size_t k = 0; k < fit.size(); ++k) EXPECT_LT(fit[k], 0.05 * linear[k]) << "level " << k + 3;
  EXPECT_GT(std::log2(fit[0] / fit[2]) / 2, 2.2);
}

// Two parallel sheets a fifth of an edge apart (a thin wall): a point on one reads only
// vertices of its own sheet.
TEST(SurfacePointReading, NeverReadsTheOtherSheetOfAThinWall) {
  GeneratedMesh a = plane_grid(10, 10, 1.0, 1.0), b = a;
  b.V.col(2).array() += 0.02;
  GeneratedMesh both;
  both.V.resize(a.V.rows() * 2, 3);
  both.V << a.V, b.V;
  both.F.resize(a.F.rows() * 2, 3);
  both.F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  const Mesh m = make(both);
  const auto weights =
      quadratic_reading(m, SurfacePoint{static_cast<int>(a.F.rows()) / 2, Eigen::Vector3d(0.3, 0.3, 0.4)});
  ASSERT_TRUE(weights);
  for (const auto& [v, w] : *weights) EXPECT_LT(v, a.V.rows()) << "read vertex " << v << " of the other sheet";
}

TEST(SurfacePointReading, GivesNothingWhereNoFitIsPossible) {
  GeneratedMesh g;
  g.V.resize(3, 3);
  g.V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  g.F.resize(1, 3);
  g.F << 0, 1, 2;
  const Mesh m = make(g);
  EXPECT_FALSE(quadratic_reading(m, SurfacePoint{0, Eigen::Vector3d(0.3, 0.3, 0.4)}));
  EXPECT_FALSE(quadratic_reading(m, SurfacePoint{5, Eigen::Vector3d(0.3, 0.3, 0.4)}));
}

// A tube only six edges round turns by 60 degrees from one edge to the next: no quadratic
// over the triangle's plane fits it, so there is no reading (the caller reads the
// corners); the same tube 48 edges round is read.
TEST(SurfacePointReading, GivesNothingWhereTheSurfaceTurnsWithinTheBall) {
  const Mesh thin = make(tube(1.0, 10.0, 10, 6));
  const Mesh round = make(tube(1.0, 10.0, 80, 48));
  const Eigen::Vector3d x(0.97, 0.2, 5.03);
  for (const Mesh* m : {&thin, &round}) {
    const SurfacePoint p = closest_surface_points(*m, std::span<const Eigen::Vector3d>(&x, 1))[0];
    EXPECT_EQ(quadratic_reading(*m, p).has_value(), m == &round);
  }
}
