// Triangle-triangle self-intersections, found with a bounding-volume hierarchy.
//
// A correction moves a small region of a large mesh, so the checker is built once
// for the mesh (an AABB tree over every triangle at its original position, about
// 50 bytes a triangle) and each check then costs what the moved region costs:
// every triangle with a moved corner is tested, at its new position, against
//  - the tree, for triangles that did not move (their boxes are still right), and
//  - the other moved triangles, through a small tree built for the check.
//
// A pair of triangles counts when it overlaps beyond what it shares:
//  - no shared corner: the closed triangles meet (an edge crossing the other, or,
//    coplanar, overlapping areas);
//  - one shared corner: they meet elsewhere than at it (an opposite edge crosses the
//    other triangle, or, coplanar, their fans at the corner overlap);
//  - one shared edge (a fold): the two wings lie on each other (the angle between
//    them at the edge is at most kFoldAngle), or, against the positions the checker
//    was built with, the fold has flipped through zero (one wing has passed through
//    the other);
//  - the same three corners twice.
// These are the pairs CGAL's Polygon_mesh_processing::self_intersections reports
// with exact predicates (tests/test_self_intersections_cgal.cpp compares them), plus
// the flipped folds, which a static solve can create without any pair crossing. The
// predicates are floating-point with tolerances of 1e-10 of the pair's size, set so a
// touching configuration is reported rather than missed.
// A checker is not thread-safe (queries share scratch space); use one per thread.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Two wings of an edge closer than this angle (radians) lie on each other: a fold.
inline constexpr double kFoldAngle = 1e-6;

/// True if the closed triangles (a0, a1, a2) and (b0, b1, b2) intersect (an edge of
/// one crossing the other, or coplanar triangles whose areas overlap or touch).
bool triangles_intersect(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& a2,
                         const Eigen::Vector3d& b0, const Eigen::Vector3d& b1, const Eigen::Vector3d& b2);

/// True if the triangles (v, a1, a2) and (v, b1, b2), which share the corner v, meet
/// anywhere else.
bool corner_triangles_overlap(const Eigen::Vector3d& v, const Eigen::Vector3d& a1, const Eigen::Vector3d& a2,
                              const Eigen::Vector3d& b1, const Eigen::Vector3d& b2);

/// The signed angle (radians, in (-pi, pi]) from the wing r to the wing s of the edge
/// p-q, turning about the axis p -> q: +-pi when the two triangles are flat, 0 when
/// they are folded onto each other; 0 also when a wing is degenerate (on the edge's line).
double fold_angle(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& r,
                  const Eigen::Vector3d& s);

class SelfIntersectionChecker {
 public:
  /// Builds the tree over `mesh`'s triangles at their current positions.
  explicit SelfIntersectionChecker(const Mesh& mesh);
  ~SelfIntersectionChecker();
  SelfIntersectionChecker(SelfIntersectionChecker&&) noexcept;
  SelfIntersectionChecker& operator=(SelfIntersectionChecker&&) noexcept;

  /// Overlapping triangle pairs (i < j, as defined above) that involve a triangle with
  /// a corner in `moved`, with the mesh's vertices at V (#V x 3; only moved rows may
  /// differ from the positions the checker was built with).
  std::vector<std::pair<int, int>> intersecting_pairs(const Positions& V, std::span<const int> moved) const;

  /// Those of `pairs` (triangle indices) that overlap at V, by the same rule: a check of a
  /// few pairs known to matter, much cheaper than intersecting_pairs().
  std::vector<std::pair<int, int>> overlapping_among(const Positions& V,
                                                     std::span<const std::pair<int, int>> pairs) const;
  /// Every overlapping pair of the mesh at the positions it was built with.
  std::vector<std::pair<int, int>> all_pairs() const;

  /// Pairs present at V but not at the build positions, among the triangles
  /// touching `moved`: what a correction created.
  int count_new(const Positions& V, std::span<const int> moved) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace meshpde
