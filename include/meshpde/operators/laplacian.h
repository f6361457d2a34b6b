// The one factory of Laplacians: which stiffness K and mass M a solver runs on, the
// plain cotangent ones (operators/fem_operators.h) or the intrinsic Delaunay ones
// (operators/intrinsic_delaunay.h), by name or chosen from the mesh's shape. Shapes,
// units and signs are those of fem_operators.h (K symmetric positive semi-definite,
// K 1 = 0, the opposite sign of libigl's cotmatrix; M lumped, length^2).
#pragma once

#include <memory>
#include <string>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/intrinsic_delaunay.h"

namespace meshpde {

/// Which stiffness a solver uses. Auto picks intrinsic Delaunay when the mesh is
/// badly shaped (smallest angle below 1 degree or area ratio above 1e4, the
/// thresholds of analyze()) or non-manifold, and the plain cotangent otherwise.
enum class LaplacianKind { Auto, Cotan, IntrinsicDelaunay };

/// "auto", "cotan", "intrinsic" (or "intrinsic-delaunay"). \throw InputError otherwise.
LaplacianKind parse_laplacian_kind(const std::string& text);
const char* to_string(LaplacianKind kind);

/// The operators a solver runs on, with the connectivity they are defined on.
struct MeshOperators {
  Mesh mesh;  ///< the input mesh (cotan) or the intrinsic operator mesh
  FemOperators ops;
  LaplacianKind kind = LaplacianKind::Cotan;  ///< the kind actually used (never Auto)
  std::string reason;                         ///< why Auto chose it
  IntrinsicDelaunayStats stats;               ///< intrinsic only
};

/// Builds K and M of the requested kind. vertex_weights: a per-vertex stiffness
/// multiplier (#V, >= 0), as IntrinsicDelaunayOptions::vertex_weights
/// (for the cotangent kind it is averaged per input triangle).
MeshOperators build_mesh_operators(const Mesh& mesh, LaplacianKind kind,
                                   const Eigen::VectorXd& vertex_weights = Eigen::VectorXd());

/// One surface's operators, built on first use and kept until the surface changes
/// (geometry-central's require/refresh): the one cache of a surface that every session
/// on it shares (the editor's probe, heat and wave, painting). Handed out as shared
/// pointers, so a session keeps the bundle it was built on alive after a refresh, and
/// can tell that it is stale by comparing pointers.
class OperatorCache {
 public:
  explicit OperatorCache(LaplacianKind kind = LaplacianKind::Auto) : kind_(kind) {}
  /// The operators of the chosen kind for `mesh` at its current positions (built now
  /// if there are none since the last refresh()).
  std::shared_ptr<const MeshOperators> operators(const Mesh& mesh);
  /// The cotangent operators on the mesh's own triangles, for methods that need them
  /// (the connection Laplacian transports vectors across the input triangles).
  std::shared_ptr<const MeshOperators> cotan(const Mesh& mesh);
  /// The surface changed (positions or triangles): the next requests rebuild.
  void refresh();
  int builds() const { return builds_; }  ///< operator bundles built so far

 private:
  LaplacianKind kind_;
  std::shared_ptr<const MeshOperators> operators_, cotan_;
  int builds_ = 0;
};

}  // namespace meshpde
