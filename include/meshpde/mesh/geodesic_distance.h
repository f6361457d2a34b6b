// Distance along the surface: from source vertices and surface points to the vertices
// around them, measured across triangles, not along edges. The one rule of regions
// of influence given in millimetres (corrections, their handles' size, drags).
//
// Method: Dijkstra's order with the triangle update of fast marching, done exactly for
// a point source (Novotni and Klein, "Computing geodesic distances on triangular
// meshes", WSCG 2002). When vertices a and b of a triangle (a, b, c) are known, the
// source is unfolded into the triangle's plane, across the edge ab from c, at distances
// d(a) and d(b); if the straight line from it to c crosses the edge ab, |S c| is c's
// candidate, otherwise the path through a or b is. Dijkstra's order can make the far
// corner of an obtuse triangle final before the line to it is known; such corners are
// marked when it becomes known and corrected afterwards, round by round with their
// neighbours, until nothing changes.
// Accuracy: exact to rounding on a plane (regular or jittered triangles) and on
// surfaces that unroll onto one (a cylinder); on a curved surface the unfolding treats
// each wavefront as a planar circle, an error that grows with K d^2 (K the Gaussian
// curvature) and falls like the edge length h: on a unit sphere 0.007 h at distance 0.5
// and 0.03 h at distance 1 (tests/test_geodesic_distance.cpp). Edge paths
// (mesh/regions.h's geodesic_distances) are off by 8-20 % whatever the resolution.
//
// Units: those of the positions (mm for vessels). Cost: the vertices reached (within
// `radius`) times their degree, plus, on a mesh's first call, one pass over its
// triangles for each vertex's (Mesh::vertex_faces, kept with the mesh; 232 ms on a
// 2.6M-vertex mesh). A 9.6k-vertex region of a 655k-vertex mesh takes about 5 ms,
// an edge-path ball of the same radius (8k vertices) 0.6 ms.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/surface_distance.h"

namespace meshpde {

/// Where distances are measured from: vertices (index) and points inside triangles.
struct GeodesicSources {
  std::vector<int> vertices{};
  std::vector<SurfacePoint> points{};
};

/// Surface distance from the nearest source to every vertex nearer than `radius`, as
/// (vertex, distance) pairs in increasing distance (sources' vertices first). A point
/// source's triangle corners start at their straight-line distance to it.
/// \throw InputError for a vertex or triangle out of range or a point whose barycentric
///        coordinates are not finite, non-negative and summing to 1 (to 1e-9).
std::vector<std::pair<int, double>> geodesic_distances_from(const Mesh& mesh, const GeodesicSources& sources,
                                                            double radius = std::numeric_limits<double>::infinity());

/// The same for every vertex: #V entries, +infinity where none was reached (beyond
/// `radius`, or on another connected part).
Eigen::VectorXd geodesic_distance(const Mesh& mesh, const GeodesicSources& sources,
                                  double radius = std::numeric_limits<double>::infinity());

}  // namespace meshpde
