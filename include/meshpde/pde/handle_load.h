// Handles with a size: the load that pulls a handle to its displacement and where its
// displacement is read. Shared by corrections (apps/vessel_correction.h) and drag
// sessions (apps/local_drag.h), so that a handle means the same in both.
//
// A handle is a vertex or a point of the surface (mesh/surface_distance.h). A handle of
// size r > 0 is moved by a force spread over the surface within r of its point with the
// smooth profile (1 - (d / r)^2)^2, d the straight-line distance to the point, so that
// a drag makes a smooth bump rather than the cusp of a point load; the force's size is
// whatever puts the handle's point on its displacement (a Lagrange multiplier: the
// bordered system of a point constraint). The load is integrated against each corner's
// hat function, triangle by triangle, walking from the point's own triangles across
// shared corners (so it stays on the sheet of the surface the point is on).
//
// Where the point's motion is read: at a vertex, the vertex; at a point of size 0, the
// barycentric combination of its triangle's corners; at a point whose bump the mesh
// resolves (r at least kSmoothReadingSize of its triangle's mean edge), the quadratic
// fitted to the vertices around it (mesh/surface_point_reading.h): the corners' linear
// interpolation reads a bump's peak low by an amount that depends on where the point
// falls in its triangle, and would scale the whole field differently on every
// triangulation.
//
// Units: r in the mesh's length unit. Load and reading weights are unit-free; each sums to 1.
#pragma once

#include <optional>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/surface_distance.h"

namespace meshpde {

/// A handle's size by default with the smooth boundary (pde/region_boundary.h): this
/// fraction of the region's radius (`--handle-radius`, Python's handle_radius).
inline constexpr double kHandleRadiusFraction = 0.25;

/// A point handle whose size is at least this fraction of its triangle's mean edge is
/// read to second order; below it the load is about a point load, whose field has a cusp
/// at the handle that a quadratic fit would read wrongly.
inline constexpr double kSmoothReadingSize = 0.5;

/// A handle's terms, as (vertex, weight) pairs in the mesh's numbering.
struct HandleLoad {
  /// The force's profile over the vertices (sums to 1): the right-hand side of the
  /// handle's column. A size too small to integrate against the edges gives the point
  /// load itself (the reading's weights).
  std::vector<std::pair<int, double>> load;
  /// Where the handle's displacement is read: sum of weight x displacement over these
  /// vertices is the handle point's motion.
  std::vector<std::pair<int, double>> reading;
  /// The vertices the handle lies on: its vertex, or its triangle's corners.
  std::vector<int> corners;
};

/// The terms of a handle at `vertex` (when `point` is empty) or at `point`, of size
/// `size` >= 0 (0: a point load). \throw InputError for a vertex in no triangle.
HandleLoad handle_load(const Mesh& mesh, int vertex, const std::optional<SurfacePoint>& point, double size);

}  // namespace meshpde
