// Discrete Levi-Civita connection on the vertex tangent spaces (as in Sharp, Soliman
// and Crane, "The Vector Heat Method", 2019; Knöppel et al. 2013).
//
// Each vertex gets a tangent frame: its normal (area-weighted) and a reference
// direction (towards its first neighbour in fan order). An outgoing edge ij has the
// angle phi_ij: the sum of the corner angles swept from the reference edge,
// rescaled by 2 pi / Theta_i (Theta_i the total angle; pi / Theta_i at boundary
// vertices). Transport from j to i rotates by rho_ij = phi_ij - phi_ji + pi.
// A tangent vector is a complex number in its vertex's frame (radians,
// counter-clockwise about the normal).
//
// Requires an edge-manifold, consistently oriented mesh (each vertex a single fan).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <complex>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct Connection {
  Eigen::MatrixX3d normal;  ///< unit vertex normals
  Eigen::MatrixX3d e1;      ///< unit reference tangent per vertex
  Eigen::MatrixX3d e2;      ///< normal x e1
  Eigen::VectorXd phi;      ///< angle of each CSR slot's edge (i -> neighbour) in i's frame
  Eigen::VectorXd theta;    ///< total corner angle at each vertex
  std::vector<char> boundary;

  /// Rotation (radians) taking a vector at neighbour j = neighbors()[slot] into i's frame.
  double transport(const Mesh& mesh, int i, int slot) const;
};

/// \throw InputError if the mesh is not edge-manifold and consistently oriented around every vertex.
Connection build_connection(const Mesh& mesh);

/// Angle (radians) of a 3D vector projected into vertex i's tangent plane.
double tangent_angle(const Connection& c, int i, const Eigen::Vector3d& v);
/// 3D tangent vector of length r at angle a in vertex i's frame (using the embedded frame).
Eigen::Vector3d tangent_vector(const Connection& c, int i, double a, double r);

/// Connection Laplacian as a real 2#V x 2#V matrix (each complex entry a 2 x 2
/// rotation-scaling block), positive semi-definite like K: diagonal K_ii, off-diagonal
/// K_ij times the rotation by rho_ij. `cot_weights` are the K_ij of fem_operators.h.
Eigen::SparseMatrix<double> connection_laplacian(const Mesh& mesh, const Connection& c, const Eigen::VectorXd& Kii,
                                                 const Eigen::VectorXd& Kij);

}  // namespace meshpde
