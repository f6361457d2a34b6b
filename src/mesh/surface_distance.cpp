#include "meshpde/mesh/surface_distance.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <numeric>

#include "aabb_tree.h"
#include "meshpde/core/errors.h"

namespace meshpde {

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c) {
  // By Voronoi regions of the triangle (Ericson, Real-Time Collision Detection, section
  // 5.1.5); the result is the weights of a, b and c.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) {  // degenerate: the nearest corner
    const double da = (p - a).squaredNorm(), db = (p - b).squaredNorm(), dc = (p - c).squaredNorm();
    if (da <= db && da <= dc) return {1, 0, 0};
    return db <= dc ? Eigen::Vector3d(0, 1, 0) : Eigen::Vector3d(0, 0, 1);
  }
  const double v = vb / denom, w = vc / denom;
  return {1 - v - w, v, w};
}

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c) {
  const Eigen::Vector3d w = closest_point_on_triangle(p, a, b, c);
  return (p - (w[0] * a + w[1] * b + w[2] * c)).norm();
}

void check_surface_point(const Mesh& mesh, const SurfacePoint& p, const std::string& what) {
  if (p.face < 0 || p.face >= mesh.num_faces())
    throw InputError(
        fmt::format("{}: triangle {} does not exist (the mesh has {} triangles)", what, p.face, mesh.num_faces()));
  if (!p.bary.allFinite() || p.bary.minCoeff() < -1e-9 || std::abs(p.bary.sum() - 1) > 1e-9)
    throw InputError(fmt::format("{}: barycentric coordinates ({}, {}, {}) must be >= 0 and sum to 1", what, p.bary[0],
                                 p.bary[1], p.bary[2]));
}

Eigen::Vector3d position(const Mesh& mesh, const SurfacePoint& point) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) x += point.bary[k] * V.row(F(point.face, k)).transpose();
  return x;
}

int nearest_corner(const Mesh& mesh, const SurfacePoint& point) {
  int k = 0;
  point.bary.maxCoeff(&k);
  return mesh.triangles()(point.face, k);
}

std::vector<SurfacePoint> closest_surface_points(const Mesh& mesh, std::span<const Eigen::Vector3d> points) {
  if (points.empty()) return {};  // no tree to build (a command with vertex handles only)
  if (mesh.num_faces() == 0) throw InputError("the mesh has no triangles to place a surface point on");
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  auto corner = [&](int f, int k) { return Eigen::Vector3d(V.row(F(f, k)).transpose()); };
  const detail::Tree tree = detail::triangle_tree(V, F);
  std::vector<SurfacePoint> out;
  out.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[i];
    if (!p.allFinite()) throw InputError(fmt::format("surface point {} is not finite", i));
    SurfacePoint best;
    double best_dist = std::numeric_limits<double>::infinity();
    tree.nearest(p, [&](int f) {
      const Eigen::Vector3d w = closest_point_on_triangle(p, corner(f, 0), corner(f, 1), corner(f, 2));
      const double d = (p - (w[0] * corner(f, 0) + w[1] * corner(f, 1) + w[2] * corner(f, 2))).norm();
      if (d < best_dist || (d == best_dist && f < best.face)) {
        best_dist = d;
        best = {f, w};
      }
      return d;
    });
    out.push_back(best);
  }
  return out;
}

double directed_hausdorff(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB) {
  auto corner = [&](int f, int k) { return Eigen::Vector3d(VB.row(FB(f, k)).transpose()); };
  const detail::Tree tree = detail::triangle_tree(VB, FB);
  auto to_b = [&](const Eigen::Vector3d& p) {
    return tree.nearest(p, [&](int f) { return point_triangle_distance(p, corner(f, 0), corner(f, 1), corner(f, 2)); });
  };
  double worst = 0;
  for (Eigen::Index i = 0; i < VA.rows(); ++i) worst = std::max(worst, to_b(VA.row(i).transpose()));
  for (Eigen::Index f = 0; f < FA.rows(); ++f) {
    const Eigen::Vector3d c = (VA.row(FA(f, 0)) + VA.row(FA(f, 1)) + VA.row(FA(f, 2))).transpose() / 3.0;
    worst = std::max(worst, to_b(c));
  }
  return worst;
}

double hausdorff_distance(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB) {
  return std::max(directed_hausdorff(VA, FA, VB, FB), directed_hausdorff(VB, FB, VA, FA));
}

}  // namespace meshpde
