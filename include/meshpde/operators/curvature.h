// Mean curvature from the stiffness matrix (Kim and Rossignac 2004 section 3.4.1 and Appendix,
// Table 1): H_i = 1/2 c_i |row_i(K x)|, x the vertex positions. Units: length^-1.
// On a sphere of radius R, H = 1/R, so the radius estimate is rho_i = 1/H_i.
//
// Two scalings c_i:
//   Area    c_i = 3 / A~_i                     (Kim and Rossignac's choice; equals Meyer et al. 2003)
//   Valence c_i = 4 cos^2(pi / n_i) / A~_i     (n_i = number of edges at i; the
//                                               flat-umbrella fit of the Appendix)
// At vertices with zero incident area H is reported as 0.
#pragma once

#include <Eigen/Core>
#include <string>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"

namespace meshpde {

enum class CurvatureScale { Area, Valence };

/// Unsigned mean curvature per vertex (length #V).
Eigen::VectorXd mean_curvature(const Mesh& mesh, const FemOperators& ops, CurvatureScale scale);

/// Mean curvature with the Laplacian of `kind` (operators/laplacian.h). Auto is the
/// cotangent operator here, unlike the solvers' Auto: the intrinsic operator applies
/// K to x interpolated linearly over intrinsic triangles, whose edges cut across the
/// surface's folds, and spikes where the triangulations differ (measured on the
/// marching-cubes aorta-closed-6k: largest H 45.9 against 1.83 with cotan, median
/// 0.111 against 0.102; test Curvature.AutoIsCotanAndIntrinsicIsAvailable). The
/// valence scaling counts the input mesh's edges at each vertex.
struct CurvatureResult {
  Eigen::VectorXd H;                               ///< #V, length^-1
  LaplacianKind laplacian = LaplacianKind::Cotan;  ///< the kind used (never Auto)
  std::string reason;                              ///< why Auto chose it
};
CurvatureResult mean_curvature(const Mesh& mesh, CurvatureScale scale, LaplacianKind kind);

/// The same on plain (V, F): builds the mesh and its cotangent operators first.
inline Eigen::VectorXd mean_curvature(const Positions& V, const Triangles& F, CurvatureScale scale) {
  const Mesh mesh(V, F);
  return mean_curvature(mesh, build_cotan_operators(mesh), scale);
}

}  // namespace meshpde
