// Regions of a mesh: the edge-path ball and the ring ball, a region of influence given
// by surface distance or by rings (RegionSpec), and brushes that paint a per-vertex
// field over a ball. The one home of these rules for drags, corrections, the editor's
// brushes and the selection specs.
#pragma once

#include <Eigen/Core>
#include <span>
#include <unordered_map>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Vertices whose shortest edge-path distance from `source` is below `radius` (mesh
/// units), found by Dijkstra restricted to that neighbourhood (cost ~ its size), in the
/// order they were reached (nearest first; the source first).
std::vector<int> geodesic_ball(const Mesh& mesh, int source, double radius);

/// Edge-path distance from the nearest of `sources` for every vertex nearer than
/// `radius` (mesh units): (vertex, distance) pairs in the order Dijkstra reaches them
/// (the sources first, at 0). Cost ~ the ball's size.
std::vector<std::pair<int, double>> geodesic_distances(const Mesh& mesh, std::span<const int> sources, double radius);

/// Vertices within k rings of `source` (the source included), ring by ring.
std::vector<int> ring_ball(const Mesh& mesh, int source, int rings);

/// A region around a vertex, by distance or by rings: exactly one of the two is > 0.
struct RegionSpec {
  double radius = 0;  ///< surface distance (mesh units, mm for vessels; mesh/geodesic_distance.h); 0: use rings
  int rings = 0;      ///< rings of neighbours (the thesis's "level of influence"); 0: use radius
};

/// As `spec` says: the vertices nearer than the radius on the surface
/// (geodesic_distances_from, nearest first), or ring_ball. The region of DragSession
/// and drag_vertex. \throw InputError for a bad vertex, or unless exactly one of
/// radius and rings is > 0 (the message names both).
std::vector<int> region_around(const Mesh& mesh, int source, const RegionSpec& spec);

/// The region of influence of one or more handles under the correction's older rules
/// (RegionBoundary::Clamp and Fade, apps/vessel_correction.h), kept as they were for
/// comparison: the union of every handle's edge-path ball (geodesic_ball) or ring
/// ball, the handles first, then in the order reached.
/// With `clamp_at_radius` (the bi-Laplacian's rule) a ball given by radius R is taken
/// within R - h instead, h the mean edge length inside it (when R > 2h): the two rings
/// held at zero outside the free set then clamp the field about one edge beyond its
/// last free vertex, i.e. at R whatever the resolution (measured on tubes of 32, 64 and
/// 128 segments: the Hausdorff distance between the results halves).
/// \throw InputError as region_around.
std::vector<int> influence_region(const Mesh& mesh, std::span<const int> handles, const RegionSpec& spec,
                                  bool clamp_at_radius);

/// Mean length of the edges with both ends among `vertices` (0 if there are none).
double mean_edge_length_among(const Mesh& mesh, const std::vector<int>& vertices);

/// A region and `margin_rings` rings of neighbours around it, copied as a mesh of its
/// own (the triangles with all three corners in the copy): what a correction and the
/// editor's preview solve on, so that their cost follows the region, not the mesh, and
/// both build the very same operators. When the copy would hold every vertex, it is
/// the mesh itself with its own numbering.
struct RegionCopy {
  Mesh mesh;                 ///< the copy (or the whole mesh)
  std::vector<int> to_mesh;  ///< copy vertex -> mesh vertex: the region first, in its order, then ring by ring
  std::unordered_map<int, int> from_mesh;  ///< mesh vertex -> copy vertex (empty for the whole mesh)
  bool whole = false;                      ///< the copy is the mesh itself
  int local(int v) const { return whole ? v : from_mesh.at(v); }
};
RegionCopy copy_region(const Mesh& mesh, const std::vector<int>& region, int margin_rings);

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
