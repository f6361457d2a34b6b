#include "meshpde/mesh/surface_distance.h"

#include <numeric>

#include "aabb_tree.h"

namespace meshpde {

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c) {
  // Closest point by Voronoi regions of the triangle (Ericson, Real-Time Collision
  // Detection, section 5.1.5).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return std::min({(p - a).norm(), (p - b).norm(), (p - c).norm()});  // degenerate
  const double v = vb / denom, w = vc / denom;
  return (p - (a + ab * v + ac * w)).norm();
}

double directed_hausdorff(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB) {
  auto corner = [&](int f, int k) { return Eigen::Vector3d(VB.row(FB(f, k)).transpose()); };
  detail::Tree tree;
  std::vector<int> all(static_cast<std::size_t>(FB.rows()));
  std::iota(all.begin(), all.end(), 0);
  tree.build(all, [&](int f) {
    detail::Box b;
    for (int k = 0; k < 3; ++k) b.add(corner(f, k));
    return b;
  });
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
