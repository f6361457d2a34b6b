// Linear-element FEM operators on a triangle mesh (Kim and Rossignac 2004 sections 3.2-3.4):
//
//   K   stiffness, #V x #V, symmetric positive semi-definite, K 1 = 0.
//       K = -L where L is the cotangent Laplacian (libigl's cotmatrix convention,
//       negative semi-definite). Element matrix Ke[a][b] = w_t (e_a . e_b) / (4 A_t),
//       e_a the edge opposite corner a. Units: dimensionless (length^0) for weight 1.
//   M   lumped mass, diagonal, M_ii = A~_i / 3 with A~_i the total area of the
//       triangles at i. Units: length^2.
//   D   = M^-1 = diag(3 / A~_i). Units: length^-2.
//   K D K  bi-Laplacian, applied matrix-free, never assembled (units: length^-2).
//
// Storage follows the mesh: K_ii per vertex and K_ij per CSR slot of the mesh
// adjacency (each edge's value appears in both of its rows, so an apply streams
// through memory without gathering edge values).
//
// Degenerate geometry (tested): a triangle with a repeated index
// or an area <= 1e-14 * (longest edge)^2 contributes nothing to K or M and is
// counted in `degenerate_faces`. A vertex whose incident area is zero (unreferenced,
// or touching only degenerate triangles) has M_ii = 0 and D_ii = 0 (not infinity);
// the solvers hold such vertices fixed. No operator ever produces NaN or Inf from
// finite input.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <span>

#include "meshpde/mesh/field.h"
#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct OperatorOptions {
  /// Optional per-triangle multiplier of the element stiffness (length #F), for
  /// example face_areas() for Kim and Rossignac's area-weighted membrane regularization, or
  /// vertex_to_face_average(stiffness field). Empty: weight 1 everywhere.
  Eigen::VectorXd face_weights;
};

/// K and M of one Laplacian, whichever built them: the cotangent one on the input
/// triangles (build_cotan_operators), the intrinsic Delaunay one on its own triangles
/// (build_intrinsic_delaunay_operators, operators/intrinsic_delaunay.h), or the one a
/// LaplacianKind names (build_mesh_operators, operators/laplacian.h, which keeps the
/// mesh the operators' connectivity belongs to beside them).
struct FemOperators {
  Eigen::VectorXd Kii;   ///< #V diagonal of K
  Eigen::VectorXd Kij;   ///< one value per CSR slot of Mesh::neighbors() (2 #E)
  Eigen::VectorXd mass;  ///< #V lumped mass M_ii = A~_i / 3 (0 for zero-area vertices)
  int degenerate_faces = 0;
  int zero_area_vertices = 0;

  /// D_ii = 3 / A~_i, or 0 where the incident area is zero.
  double D(int i) const { return mass[i] > 0 ? 1.0 / mass[i] : 0.0; }
  /// Bytes held (K, M).
  std::size_t bytes() const { return sizeof(double) * (Kii.size() + Kij.size() + mass.size()); }
};

/// Assembles the cotangent K and the lumped M on the mesh's own triangles. \throw
/// InputError if face_weights has the wrong length or a negative or non-finite entry.
FemOperators build_cotan_operators(const Mesh& mesh, const OperatorOptions& options = {});
[[deprecated("build_operators is now build_cotan_operators")]] inline FemOperators build_operators(
    const Mesh& mesh, const OperatorOptions& options = {}) {
  return build_cotan_operators(mesh, options);
}

/// Area of each triangle (length^2); 0 for degenerate ones.
Eigen::VectorXd face_areas(const Mesh& mesh);

/// Mean of a per-vertex field over each triangle's three corners (length #F).
Eigen::VectorXd vertex_to_face_average(const Mesh& mesh, const Eigen::VectorXd& vertex_field);

/// Diagonal of K D K: (K D K)_ii = sum_j K_ij^2 D_jj over j = i and its neighbours.
double bilaplacian_diagonal(const Mesh& mesh, const FemOperators& ops, int i);

/// (K w)_i for one vertex, the field read through value(j) -> double. For the few rows
/// that reaction forces and right-hand sides need, without a whole-mesh apply.
template <class Value>
double stiffness_row(const Mesh& mesh, const FemOperators& ops, int i, Value&& value) {
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  double y = ops.Kii[i] * value(i);
  for (int s = off[i]; s < off[i + 1]; ++s) y += ops.Kij[s] * value(nbr[s]);
  return y;
}

/// (K D K w)_i for one vertex (reads w two rings out).
template <class Value>
double bilaplacian_row(const Mesh& mesh, const FemOperators& ops, int i, Value&& value) {
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  double y = ops.Kii[i] * ops.D(i) * stiffness_row(mesh, ops, i, value);
  for (int s = off[i]; s < off[i + 1]; ++s) y += ops.Kij[s] * ops.D(nbr[s]) * stiffness_row(mesh, ops, nbr[s], value);
  return y;
}

/// Y = K U, Y = M U, Y = K D K U over the whole mesh; U is #V x m.
Field apply_stiffness(const Mesh& mesh, const FemOperators& ops, const Field& U);
Field apply_mass(const FemOperators& ops, const Field& U);
Field apply_bilaplacian(const Mesh& mesh, const FemOperators& ops, const Field& U);

/// Assembled sparse forms, for direct solvers and cross-checks.
Eigen::SparseMatrix<double> stiffness_matrix(const Mesh& mesh, const FemOperators& ops);

/// Number of stored entries of K: #V diagonal entries plus one per CSR slot (2 #E).
std::size_t stiffness_nonzeros(const Mesh& mesh);

/// K in compressed-row form, written into caller-provided arrays: row_offsets (#V + 1),
/// columns and values (stiffness_nonzeros() each). Rows hold their columns in ascending
/// order, the diagonal in its place. K is symmetric, so these are also its
/// compressed-column arrays. For bindings that hand the arrays on without a copy
/// (scipy.sparse.csr_matrix), and for stiffness_matrix().
void stiffness_csr(const Mesh& mesh, const FemOperators& ops, std::span<int> row_offsets, std::span<int> columns,
                   std::span<double> values);
Eigen::SparseMatrix<double> mass_matrix(const FemOperators& ops);

/// Y(rows) = K U on the listed rows only (other rows of Y untouched). U and Y are
/// row-major with `m` components, indexed by vertex. This is the kernel the
/// localized solvers use.
void apply_stiffness_rows(const Mesh& mesh, const FemOperators& ops, const double* U, double* Y, int m,
                          std::span<const int> rows);

/// Y = K D K u for a scalar field over the whole mesh, with T (length #V) as scratch.
/// The D scaling is fused into the first sweep, so memory is streamed twice.
void apply_bilaplacian_scalar(const Mesh& mesh, const FemOperators& ops, const double* u, double* T, double* Y);

/// Plain (V, F) forms of the whole-mesh products and matrices: each builds the mesh and
/// its cotangent operators first (for repeated use, build them once and call the
/// forms above). Shapes, units and signs as above.
inline Field apply_stiffness(const Positions& V, const Triangles& F, const Field& U) {
  const Mesh mesh(V, F);
  return apply_stiffness(mesh, build_cotan_operators(mesh), U);
}
inline Field apply_bilaplacian(const Positions& V, const Triangles& F, const Field& U) {
  const Mesh mesh(V, F);
  return apply_bilaplacian(mesh, build_cotan_operators(mesh), U);
}
inline Eigen::SparseMatrix<double> stiffness_matrix(const Positions& V, const Triangles& F) {
  const Mesh mesh(V, F);
  return stiffness_matrix(mesh, build_cotan_operators(mesh));
}
inline Eigen::SparseMatrix<double> mass_matrix(const Positions& V, const Triangles& F) {
  const Mesh mesh(V, F);
  return mass_matrix(build_cotan_operators(mesh));
}

}  // namespace meshpde
