// Where a per-vertex field crosses a value: the curve {x : u(x) = level} of the field
// interpolated linearly on each triangle, as straight segments, one per triangle it
// crosses. The editor draws the rim of a drag's region of influence this way (the
// level set of the surface distance at the radius); it serves iso-lines of any field.
//
// A corner counts as below the level when u < level, else above: a triangle whose
// corners are not all on one side gives one segment between the two points where its
// edges cross (linear along each edge). Exact for a field linear on the surface.
// Corners with a value that is not finite make their triangles skipped.
// Units: the segments' ends are positions (mm for vessels).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <span>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// One piece of a level set: the segment from a to b across triangle `face`.
struct LevelSetSegment {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  int face = -1;
};

/// The level set of `values` (#V entries) at `level`, over the triangles `faces` (empty:
/// every triangle), in the order of the triangles.
/// \throw InputError when values has not #V entries, the level is not finite or a face
///        index is out of range.
std::vector<LevelSetSegment> level_set_segments(const Mesh& mesh, const Eigen::VectorXd& values, double level,
                                                std::span<const int> faces = {});

/// The same for a field known near the curve only: `value(v)` for each corner of
/// `faces` (a region's surface distances kept by vertex, say), so that a small curve on
/// a large mesh costs what its triangles cost, not an array of #V values.
/// \throw InputError when the level is not finite or a face index is out of range.
std::vector<LevelSetSegment> level_set_segments(const Mesh& mesh, const std::function<double(int)>& value, double level,
                                                std::span<const int> faces);

}  // namespace meshpde
