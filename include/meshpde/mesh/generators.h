// Meshes the project generates for tests, benchmarks and demos. All return plain
// (V, F) with outward-facing, consistently oriented triangles.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct GeneratedMesh {
  Positions V;
  Triangles F;
  /// A label per triangle for meshes with flat caps, as VMTK's capper numbers them
  /// (CellEntityIds): 1 the wall, 2, 3, ... the caps; empty otherwise.
  Eigen::VectorXi face_labels;
};

/// Latitude-longitude sphere: two poles and n-1 rings of 2n vertices
/// (n = 2, 3, 4, 5, 15 give 6, 14, 26, 42, 422 vertices, Kim and Rossignac 2004, Table 1).
/// Ring k sits at polar angle k*pi/n; each band of quads is split along one diagonal.
/// \pre n >= 2
GeneratedMesh latlong_sphere(int n, double radius = 1.0);

/// Platonic solid whose faces are split into frequency^2 triangles and projected to
/// the sphere: icosahedron (10 f^2 + 2 vertices) or tetrahedron (2 f^2 + 2).
enum class BaseSolid { Icosahedron, Tetrahedron };
GeneratedMesh geodesic_sphere(BaseSolid base, int frequency, double radius = 1.0);

/// Icosphere of a subdivision level (frequency 2^level): level 5 has 10,242 vertices,
/// level 8 has 655,362.
GeneratedMesh icosphere(int level, double radius = 1.0);

/// Open cylinder along z from 0 to length: `rings` rings of `segments` vertices. With
/// `caps`, closed by two flat fans (face labels: wall 1, the cap at z = 0 2, at z = length 3).
GeneratedMesh tube(double radius, double length, int rings, int segments, bool caps = false);

/// Planar grid in z = 0 covering [0, size_x] x [0, size_y] with nx x ny quads.
GeneratedMesh plane_grid(int nx, int ny, double size_x = 1.0, double size_y = 1.0);

/// k rectangular sheets of n x n quads sharing their edge on the z axis (z in [0, 1]):
/// every interior vertex of that edge is non-manifold.
GeneratedMesh fins(int k, int n);

/// A vessel stand-in: trunk of radius `trunk_radius` along -z joining two branches
/// of radius `branch_radius` that leave the origin at +-`angle_deg`/2 from +z.
/// Closed (capped ends), smooth at the carina, optionally with an inward dent in the
/// trunk wall. Built as the zero level set of a smooth union of capsules
/// (marching tetrahedra on a grid of spacing `cell`, then relaxed onto the surface).
/// Units: millimetres by convention.
struct BifurcationParams {
  double trunk_radius = 4.0;
  double branch_radius = 3.0;
  double trunk_length = 20.0;
  double branch_length = 18.0;
  double angle_deg = 60.0;
  double blend = 2.0;         ///< smooth-union radius at the carina
  double cell = 0.8;          ///< grid spacing: mean edge length is about this
  bool dent = false;          ///< push a dent into the trunk wall
  double dent_depth = 1.5;    ///< how far the dent reaches in
  double dent_radius = 3.0;   ///< lateral size of the dent
  int relax_iterations = 10;  ///< tangential smoothing + reprojection passes
  /// Flat caps instead of round ends: the vessels cut square at their lengths, with face
  /// labels wall 1, trunk cap 2, branch caps 3 and 4 (a CFD model's inlet and outlets).
  bool caps = false;
};
GeneratedMesh y_bifurcation(const BifurcationParams& params = {});

/// The correction of a dented bifurcation (`meshpde demo`): the wall vertex nearest the
/// bottom of the dent, and the move (mm) that puts it back on the trunk's cylinder,
/// radially outward from the trunk's axis (z).
struct DentHandle {
  int vertex = 0;
  Eigen::Vector3d move = Eigen::Vector3d::Zero();
};
/// \pre V comes from y_bifurcation(params) with params.dent.
DentHandle dent_handle(const Positions& V, const BifurcationParams& params = {});

/// Every generator under one name, with one set of defaults: the table that
/// `meshpde generate`, the editor and Python's `meshpde.generate` share.
struct GeneratorParams {
  int n = 15;                                  ///< latlong: rings of latitude; fins: quads per side
  int level = 3;                               ///< icosphere: subdivision level (5: 10,242 vertices)
  BaseSolid base = BaseSolid::Icosahedron;     ///< geodesic: solid projected to the sphere
  int frequency = 4;                           ///< geodesic: each base edge split into this many
  double radius = 1.0;                         ///< latlong, icosphere, geodesic, tube: radius
  double length = 10.0;                        ///< tube: length along z
  int rings = 20;                              ///< tube: rings along the axis
  int segments = 24;                           ///< tube: vertices per ring
  bool caps = false;                           ///< tube, bifurcation: flat caps with face labels
  int nx = 20, ny = 20;                        ///< plane: quads along x and y
  double size = 1.0;                           ///< plane: side length (both sides)
  int k = 3;                                   ///< fins: sheets sharing the axis edge
  BifurcationParams bifurcation{.cell = 0.6};  ///< bifurcation (mm); a finer grid than y_bifurcation's default
};

/// The names generate() takes: latlong, icosphere, geodesic, tube, bifurcation, plane, fins.
const std::vector<std::string>& generator_names();

/// The mesh `kind` (one of generator_names()) with `params`.
/// \throw InputError naming the kinds for an unknown one, or for a bad parameter.
GeneratedMesh generate(const std::string& kind, const GeneratorParams& params = {});

/// Splits every triangle into four (midpoint subdivision); positions unchanged.
GeneratedMesh subdivide_midpoint(const Positions& V, const Triangles& F);

}  // namespace meshpde
