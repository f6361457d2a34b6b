// Distances between triangle surfaces: point to surface and the symmetric
// Hausdorff distance, for comparing corrections (the resolution-independence
// tests) and for users checking a result against a reference.
//
// The Hausdorff distance is sampled at every vertex and triangle centroid of each
// surface and measured exactly to the other surface (closest point on a triangle,
// found through a bounding-volume hierarchy): it can miss a maximum inside a
// triangle of the sampled side by at most about half that triangle's size.
// Units: those of the positions (mm for vessels).
#pragma once

#include <Eigen/Core>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Distance from point p to the closed triangle (a, b, c).
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c);

/// max over samples of A (vertices and centroids) of the distance to surface B.
double directed_hausdorff(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB);

/// max(directed(A, B), directed(B, A)).
double hausdorff_distance(const Positions& VA, const Triangles& FA, const Positions& VB, const Triangles& FB);

}  // namespace meshpde
