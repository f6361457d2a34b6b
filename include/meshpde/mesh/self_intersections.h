// Triangle-triangle self-intersections, found with a bounding-volume hierarchy.
//
// A correction moves a small region of a large mesh, so the checker is built once
// for the mesh (an AABB tree over every triangle at its original position, about
// 50 bytes a triangle) and each check then costs what the moved region costs:
// every triangle with a moved corner is tested, at its new position, against
//  - the tree, for triangles that did not move (their boxes are still right), and
//  - the other moved triangles, through a small tree built for the check.
// Triangles that share a corner are never counted as intersecting (they touch by
// construction); a fold of two neighbours onto each other is therefore not
// reported. Coplanar overlaps are not reported either (measure-zero in practice).
// A checker is not thread-safe (queries share scratch space); use one per thread.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// True if the closed triangles (a0, a1, a2) and (b0, b1, b2) intersect
/// (non-coplanar case; an edge of one crossing the other).
bool triangles_intersect(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& a2,
                         const Eigen::Vector3d& b0, const Eigen::Vector3d& b1, const Eigen::Vector3d& b2);

class SelfIntersectionChecker {
 public:
  /// Builds the tree over `mesh`'s triangles at their current positions.
  explicit SelfIntersectionChecker(const Mesh& mesh);
  ~SelfIntersectionChecker();
  SelfIntersectionChecker(SelfIntersectionChecker&&) noexcept;
  SelfIntersectionChecker& operator=(SelfIntersectionChecker&&) noexcept;

  /// Intersecting triangle pairs (i < j) that involve a triangle with a corner in
  /// `moved`, with the mesh's vertices at V (#V x 3; only moved rows may differ
  /// from the positions the checker was built with).
  std::vector<std::pair<int, int>> intersecting_pairs(const Positions& V, std::span<const int> moved) const;

  /// Every intersecting pair of the mesh at the positions it was built with.
  std::vector<std::pair<int, int>> all_pairs() const;

  /// Pairs present at V but not at the build positions, among the triangles
  /// touching `moved`: what a correction created.
  int count_new(const Positions& V, std::span<const int> moved) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace meshpde
