// Flat caps that close a vessel model's open ends: the faces that VMTK's capper and
// SimVascular mark with their own label (CellEntityIds, ModelFaceID), or flat patches
// with a sharp rim found by their shape. A correction holds a cap's vertices, its rim
// included, so that an end stays flat and in its plane (a CFD model's inlet and outlets).
//
// Lengths are in the mesh's units; angles in degrees.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct Cap {
  int label = -1;                                     ///< the face label that marks it; -1 for a cap found by its shape
  std::vector<int> faces;                             ///< its triangles
  std::vector<int> vertices;                          ///< its vertices, the rim included, ascending
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();   ///< mean of its vertices
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit normal of its least-squares plane
  double flatness = 0;                                ///< largest distance of a vertex from that plane
  double area = 0;
  double rim_turn_deg = 0;  ///< find_flat_caps: mean angle the surface turns by across the rim
};

/// How a correction finds caps (`--caps`):
///  - Labels (default): the labelled patches of a face-label array that are flat (every
///    vertex within 1 % of the patch's diameter of its plane), other than the label of
///    the largest area (the wall, which is never flat); none without face labels.
///  - Auto: as Labels with face labels; without them, flat patches found by shape.
///  - Off: no caps: every vertex may move.
enum class CapRule { Labels, Auto, Off };
/// "labels", "auto" or "off". \throw InputError otherwise.
CapRule parse_cap_rule(const std::string& text);
const char* to_string(CapRule rule);

/// The caps among the labelled patches of `face_labels` (#F entries; see Labels above).
/// \throw InputError when face_labels has another length than the mesh's faces.
std::vector<Cap> caps_from_labels(const Mesh& mesh, const Eigen::VectorXi& face_labels);

/// Flat patches with a sharp rim: triangles within 5 degrees of a common normal, grown
/// across edges, whose vertices lie within 1 % of the patch's diameter of its plane,
/// whose boundary is one loop of edges where the surface turns by 30 degrees or more and
/// by 60 on average (a cap meets its wall square; the flat facets of a marching-cubes
/// surface turn by about 45), and whose area is under a quarter of the surface's.
std::vector<Cap> find_flat_caps(const Mesh& mesh);

/// The caps of `rule`: caps_from_labels() when face labels are given (Labels, Auto),
/// find_flat_caps() for Auto without them, none otherwise.
std::vector<Cap> find_caps(const Mesh& mesh, const Eigen::VectorXi& face_labels, CapRule rule);

/// Every vertex of the caps, ascending, once.
std::vector<int> cap_vertices(const std::vector<Cap>& caps);

}  // namespace meshpde
