// Reading a per-vertex field at a point inside a triangle, to second order.
//
// The linear interpolation of a triangle's three corners underestimates a smooth peak
// by about h^2 |f''| / 8 (h the edge length), and by an amount that depends on where in
// its triangle the point happens to fall: on two triangulations of one surface the same
// point reads differently. A weighted least-squares quadratic fitted to the field at the
// vertices around the point, in the point's tangent plane, reads it to third order and
// almost independently of where the vertices are (patch recovery: Zienkiewicz and Zhu,
// "The superconvergent patch recovery and a posteriori error estimates", IJNME 1992).
// The reading is linear in the field: a list of weights, one per vertex used.
#pragma once

#include <optional>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/surface_distance.h"

namespace meshpde {

/// Weights (vertex, w) such that sum w f[vertex] is the value at `point` of the quadratic
/// a + b u + c v + d u^2 + e u v + g v^2 fitted to f by least squares, (u, v) coordinates
/// in the plane of the point's triangle. The vertices used: those within a radius rho of
/// the point, reached from its triangle's corners along edges without leaving that ball
/// (so the other sheet of a thin wall is never read), rho = 1.5 times the triangle's mean
/// edge, grown by 10 % at a time until at least 12 vertices are in it; each weighted by
/// (1 - (d / rho)^2)^2, d its distance to the point.
///
/// Exact (to rounding) for fields that are quadratic in (u, v); the weights sum to 1.
/// Returns nullopt where no sound fit exists: fewer than 12 vertices within 4 mean edges
/// (a mesh too small around the point), a degenerate triangle, a vertex of the ball more
/// than about 27 degrees off the triangle's plane as seen from the point (the surface
/// turns too much within it: a vessel only a few edges round), or weights whose absolute
/// values sum to more than 3 (a fit that amplifies the field's noise, as a one-sided one
/// at an open end can). The caller then reads the corners linearly. Cost: a few dozen
/// vertices and one 6 x 6 solve.
std::optional<std::vector<std::pair<int, double>>> quadratic_reading(const Mesh& mesh, const SurfacePoint& point);

}  // namespace meshpde
