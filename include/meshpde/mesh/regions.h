// Regions of a mesh by graph distance: the geodesic (edge-path) ball and the ring
// ball, a region given either way (RegionSpec), and brushes that paint a per-vertex
// field over a ball. The one home of these rules for drags, corrections, the editor's
// brushes and the selection specs.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Vertices whose shortest edge-path distance from `source` is below `radius` (mesh
/// units), found by Dijkstra restricted to that neighbourhood (cost ~ its size), in the
/// order they were reached (nearest first; the source first).
std::vector<int> geodesic_ball(const Mesh& mesh, int source, double radius);

/// Vertices within k rings of `source` (the source included), ring by ring.
std::vector<int> ring_ball(const Mesh& mesh, int source, int rings);

/// A region around a vertex, by distance or by rings: exactly one of the two is > 0.
struct RegionSpec {
  double radius = 0;  ///< edge-path distance (mesh units, mm for vessels); 0: use rings
  int rings = 0;      ///< rings of neighbours (the thesis's "level of influence"); 0: use radius
};

/// geodesic_ball or ring_ball as `spec` says. \throw InputError for a bad vertex, or
/// unless exactly one of radius and rings is > 0 (the message names both).
std::vector<int> region_around(const Mesh& mesh, int source, const RegionSpec& spec);

/// The ring count that reaches about as far as `radius`: radius over the mean edge
/// length, rounded, at least 1. For methods counted in rings (the thesis's springs)
/// given a distance.
int rings_for_radius(const Mesh& mesh, double radius);

/// A brush stroke: every vertex within `radius` (edge-path distance) of `vertex` gets
/// `value`. The editor's and `--brush V:RADIUS:VALUE`'s stroke on a per-vertex field.
struct Brush {
  int vertex = 0;
  double radius = 0;  ///< mesh units, > 0
  double value = 1;   ///< > 0 for tissue properties
};

/// Applies `brush` to `field` (#V entries; an empty field starts as 1 everywhere).
/// \throw InputError for a bad vertex, a radius or value <= 0 or not finite, or a field of
///        the wrong length.
void apply_brush(const Mesh& mesh, Eigen::VectorXd& field, const Brush& brush);

}  // namespace meshpde
