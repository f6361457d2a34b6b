// Mesh diagnostics: what `meshpde info` reports, and the shape-quality warnings the
// solvers print before working on a badly shaped mesh.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Relative area below which a triangle is treated as degenerate:
/// area <= kDegenerateAreaRelTol * (longest edge)^2. Such triangles (and triangles
/// with a repeated vertex index) contribute nothing to the operators.
inline constexpr double kDegenerateAreaRelTol = 1e-14;

/// Area of triangle f (0 for a repeated index); units: length^2.
double triangle_area(const Mesh& mesh, int f);

/// True if triangle f has a repeated index or an area below the relative tolerance.
bool is_degenerate(const Mesh& mesh, int f);

/// Everything `meshpde info` prints. Counts refer to the mesh as given.
struct MeshReport {
  int vertices = 0;
  int faces = 0;
  int edges = 0;
  int boundary_edges = 0;
  int boundary_loops = 0;        ///< connected components of the boundary-edge graph
  int nonmanifold_edges = 0;     ///< edges with three or more incident triangles
  int nonmanifold_vertices = 0;  ///< vertices whose incident triangles form more than one fan
  int components = 0;            ///< edge-connected components of referenced vertices
  int degenerate_faces = 0;      ///< repeated index or (near-)zero area
  int duplicate_vertices = 0;    ///< vertices at exactly the position of an earlier vertex
  int unreferenced_vertices = 0;
  int inconsistent_edges = 0;  ///< two-triangle edges traversed in the same direction twice
  bool orientation_consistent = true;
  int euler_characteristic = 0;  ///< V - E + F over referenced vertices
  double area = 0;               ///< total triangle area
  double signed_volume = 0;      ///< divergence-theorem volume; < 0 means inward normals on a closed mesh
  double min_angle_deg = 0;      ///< over non-degenerate triangles
  double max_angle_deg = 0;
  double area_ratio = 0;  ///< largest over smallest non-degenerate triangle area
  double mean_edge_length = 0;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  std::vector<std::string> warnings;  ///< human-readable findings (badly shaped, non-manifold, ...)
};

/// Thresholds for the "badly shaped" warning. Marching-cubes segmentation surfaces
/// reach 0.02 degrees and area ratios of 1e7; FEM operators lose accuracy well before.
struct ShapeWarningThresholds {
  double min_angle_deg = 1.0;  ///< warn below this smallest angle
  double area_ratio = 1e4;     ///< warn above this largest/smallest area ratio
};

MeshReport analyze(const Mesh& mesh, const ShapeWarningThresholds& thresholds = {});

/// The report as one JSON object, keyed by the field names above (bbox_min and bbox_max
/// as [x, y, z]): what `meshpde info --json` prints and Python's meshpde.info returns.
std::string to_json(const MeshReport& report);

/// Mean length of the unique edges (0 for a mesh without edges).
double mean_edge_length(const Mesh& mesh);

/// The smallest interior angle, in degrees, of the listed triangles (all of them when
/// `faces` is empty), skipping triangles of zero area; 180 when none is left.
double smallest_angle_deg(const Positions& V, const Triangles& F, const std::vector<int>& faces = {});

/// Unit vertex normals (#V x 3), area-weighted, oriented as the triangles are
/// (inward on an inward-oriented mesh); zero rows where a vertex has no area.
Eigen::MatrixX3d vertex_normals(const Mesh& mesh);

/// Unit vertex normals that point out of the surface: for a closed mesh (no boundary
/// loop) away from the enclosed volume, whichever way its triangles are oriented
/// (vmtk's aortas are inward-oriented: signed volume < 0); for an open mesh, as its
/// triangles orient it. #V x 3; zero rows where a vertex has no incident area.
/// This is the one rule for "outward" used by `normal:D` moves, the editor and Python.
Eigen::MatrixX3d outward_vertex_normals(const Mesh& mesh);

/// Connected-component label per vertex (unreferenced vertices get their own label).
std::vector<int> vertex_components(const Mesh& mesh, int* count = nullptr);

}  // namespace meshpde
