// Helpers of the correction tests on generated vessels (tests/test_correction_*.cpp).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/mesh/generators.h"
#include "test_support.h"

namespace meshpde::test {

// The vertex nearest p.
inline int nearest_vertex(const Mesh& m, const Eigen::Vector3d& p) {
  int best = 0;
  (m.positions().rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&best);
  return best;
}

// Moves the wall point at `at` to `at + d`: the handle is the nearest vertex, and
// its displacement lands it exactly on the target, whatever the resolution.
inline CorrectionParams drag_to(const Mesh& m, const Eigen::Vector3d& at, const Eigen::Vector3d& d, double radius) {
  CorrectionParams p;
  const int v = nearest_vertex(m, at);
  p.handles = {{v, at + d - m.positions().row(v).transpose()}};
  p.radius = radius;
  return p;
}

// A tube of radius 5 mm and length 60 mm whose edges are about h long.
inline Mesh tube_at(int segments) {
  const double h = 2 * M_PI * 5 / segments;
  const int half = static_cast<int>(std::round(30 / h));
  return make(tube(5.0, 60.0, 2 * half + 1, segments));
}

// The vertices within `radius` of `centre`, and how much the displacement's length
// varies over them (a patch that bends less has a smaller spread).
inline std::vector<int> patch_near(const Mesh& m, const Eigen::Vector3d& centre, double radius) {
  std::vector<int> patch;
  for (int i = 0; i < m.num_vertices(); ++i)
    if ((m.positions().row(i).transpose() - centre).norm() < radius) patch.push_back(i);
  return patch;
}
inline double spread(const CorrectionResult& r, const std::vector<int>& patch) {
  double lo = 1e300, hi = -1e300;
  for (int i : patch) {
    lo = std::min(lo, r.displacement.row(i).norm());
    hi = std::max(hi, r.displacement.row(i).norm());
  }
  return hi - lo;
}

// The carina of the generated bifurcation: the lowest wall vertex between the branches.
inline int carina(const Mesh& m) {
  int best = -1;
  for (int i = 0; i < m.num_vertices(); ++i) {
    const auto p = m.positions().row(i);
    if (std::abs(p.x()) < 0.6 && std::abs(p.y()) < 0.6 && p.z() > 0 && (best < 0 || p.z() < m.positions()(best, 2)))
      best = i;
  }
  return best;
}

}  // namespace meshpde::test
