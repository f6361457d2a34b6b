// Distances between triangle surfaces: point to surface and the symmetric
// Hausdorff distance, for comparing corrections (the resolution-independence
// tests) and for users checking a result against a reference; points on a surface
// (a triangle and barycentric coordinates), found as the closest to a point in space.
//
// The Hausdorff distance is sampled at every vertex and triangle centroid of each
// surface and measured exactly to the other surface (closest point on a triangle,
// found through a bounding-volume hierarchy): it can miss a maximum inside a
// triangle of the sampled side by at most about half that triangle's size.
// Units: those of the positions (mm for vessels).
#pragma once

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// A point on a triangle mesh: triangle `face` and barycentric coordinates `bary` (one
/// weight per corner F(face, k), each >= 0, summing to 1). It stays on the surface when
/// the vertices move, which is what a handle needs.
struct SurfacePoint {
  int face = -1;
  Eigen::Vector3d bary = Eigen::Vector3d(1, 0, 0);
};

/// \throw InputError, the message starting with `what`, unless the point's triangle exists
///        and its barycentric coordinates are finite, >= 0 and sum to 1 (to 1e-9).
void check_surface_point(const Mesh& mesh, const SurfacePoint& point, const std::string& what);

/// The point's position: the barycentric combination of its triangle's corners.
Eigen::Vector3d position(const Mesh& mesh, const SurfacePoint& point);

/// The corner of the point's triangle with the largest weight (the vertex a handle at
/// the point falls back to where a vertex is needed).
int nearest_corner(const Mesh& mesh, const SurfacePoint& point);

/// Barycentric coordinates (weights of a, b, c) of the point of the closed triangle
/// (a, b, c) nearest to p.
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c);

/// The surface point nearest to each of `points` (a bounding-volume hierarchy built once
/// over the triangles; of equally near ones, the first found). \throw InputError for a mesh
/// without triangles or a point that is not finite (the message gives its index).
std::vector<SurfacePoint> closest_surface_points(const Mesh& mesh, std::span<const Eigen::Vector3d> points);

/// Distance from point p to the closed triangle (a, b, c).
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c);

/// max over samples of A (vertices and centroids) of the distance to surface B.
double directed_hausdorff(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB);

/// max(directed(A, B), directed(B, A)).
double hausdorff_distance(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB);

}  // namespace meshpde
