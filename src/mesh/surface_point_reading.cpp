#include "meshpde/mesh/surface_point_reading.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <unordered_set>

namespace meshpde {

namespace {

constexpr double kStartRadius = 1.5, kGrowth = 1.1, kLargestRadius = 4.0;
constexpr std::size_t kFewestVertices = 12;
// The fit is a function over the triangle's plane: no vertex may stand farther off that
// plane than kSteepest times its distance from the point (about 27 degrees), or the
// surface turns too much within the ball (a vessel a few edges round) for one.
constexpr double kSteepest = 0.5;
// sum |w| of a sound fit is 1.3-1.6 (1 for the corners'); a far larger one amplifies
// the field's noise (a one-sided fit at an open end extrapolating, near-coincident
// vertices), so the corners read there instead.
constexpr double kLargestWeightSum = 3.0;

// The vertices within rho of x reached from `start` along edges inside that ball. The
// set of visited vertices is the ball's size, not the mesh's: a reading costs the same
// on any mesh.
std::vector<int> ball_on_sheet(const Mesh& mesh, const std::vector<int>& start, const Eigen::Vector3d& x, double rho) {
  const auto& V = mesh.positions();
  std::unordered_set<int> seen;
  std::vector<int> out, stack;
  auto visit = [&](int v) {
    if (!seen.insert(v).second) return;
    if ((V.row(v).transpose() - x).norm() >= rho) return;  // the ring just outside the ball
    out.push_back(v);
    stack.push_back(v);
  };
  for (const int v : start) visit(v);
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    for (const int w : mesh.neighbors(v)) visit(w);
  }
  return out;
}

}  // namespace

std::optional<std::vector<std::pair<int, double>>> quadratic_reading(const Mesh& mesh, const SurfacePoint& point) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  if (point.face < 0 || point.face >= F.rows()) return std::nullopt;
  std::vector<int> corners;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    corners.push_back(F(point.face, k));
    x += point.bary[k] * V.row(F(point.face, k)).transpose();
  }
  const Eigen::Vector3d a = V.row(corners[0]).transpose(), b = V.row(corners[1]).transpose(),
                        c = V.row(corners[2]).transpose();
  const double edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3;
  const Eigen::Vector3d n = (b - a).cross(c - a);
  if (!(edge > 0) || !(n.norm() > 1e-12 * edge * edge) || !x.allFinite()) return std::nullopt;
  // An orthonormal frame of the triangle's plane, lengths in units of its edge.
  const Eigen::Vector3d normal = n.normalized(), t1 = (b - a).normalized(), t2 = normal.cross(t1);
  for (double rho = kStartRadius * edge; rho <= kLargestRadius * edge * (1 + 1e-12); rho *= kGrowth) {
    const std::vector<int> near = ball_on_sheet(mesh, corners, x, rho);
    if (near.size() < kFewestVertices) continue;
    const auto m = static_cast<Eigen::Index>(near.size());
    Eigen::MatrixXd A(m, 6);
    Eigen::VectorXd w(m);
    for (Eigen::Index i = 0; i < m; ++i) {
      const Eigen::Vector3d y = V.row(near[static_cast<std::size_t>(i)]).transpose() - x;
      if (std::abs(y.dot(normal)) > kSteepest * y.norm()) return std::nullopt;
      const double u = y.dot(t1) / edge, v = y.dot(t2) / edge, q = y.squaredNorm() / (rho * rho);
      A.row(i) << 1, u, v, u * u, u * v, v * v;
      w[i] = (1 - q) * (1 - q);
    }
    const Eigen::MatrixXd M = A.transpose() * w.asDiagonal() * A;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(M);
    const Eigen::VectorXd lambda = eig.eigenvalues();  // ascending
    if (!(lambda[0] > 1e-8 * lambda[5])) continue;     // the vertices lie on a conic: no unique quadratic
    // The fit's value at the point (u = v = 0) is the first row of M^-1 A^T W applied to f.
    const Eigen::MatrixXd& Q = eig.eigenvectors();
    const Eigen::VectorXd e0 = Q * Q.row(0).transpose().cwiseQuotient(lambda);
    const Eigen::VectorXd weights = (A * e0).cwiseProduct(w);
    if (!weights.allFinite() || !(weights.lpNorm<1>() <= kLargestWeightSum)) return std::nullopt;
    std::vector<std::pair<int, double>> out;
    for (Eigen::Index i = 0; i < m; ++i) out.emplace_back(near[static_cast<std::size_t>(i)], weights[i]);
    std::sort(out.begin(), out.end());
    return out;
  }
  return std::nullopt;
}

}  // namespace meshpde
