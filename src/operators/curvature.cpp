#include "meshpde/operators/curvature.h"

#include <cmath>

namespace meshpde {

namespace {

// H_i = 1/2 c_i |row_i(K x)| with K on `operator_mesh` (the input or its intrinsic
// connectivity; same vertices and positions), valences from `mesh`.
Eigen::VectorXd curvature_from(const Mesh& mesh, const Mesh& operator_mesh, const FemOperators& ops,
                               CurvatureScale scale) {
  const Field X = operator_mesh.positions();
  const Field KX = apply_stiffness(operator_mesh, ops, X);
  Eigen::VectorXd H(mesh.num_vertices());
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const double area = 3.0 * ops.mass[i];  // A~_i
    if (!(area > 0)) {
      H[i] = 0;
      continue;
    }
    double c = 3.0 / area;
    if (scale == CurvatureScale::Valence) {
      const double cs = std::cos(M_PI / mesh.degree(i));
      c = 4.0 * cs * cs / area;
    }
    H[i] = 0.5 * c * KX.row(i).norm();
  }
  return H;
}

}  // namespace

Eigen::VectorXd mean_curvature(const Mesh& mesh, const FemOperators& ops, CurvatureScale scale) {
  return curvature_from(mesh, mesh, ops, scale);
}

CurvatureResult mean_curvature(const Mesh& mesh, CurvatureScale scale, LaplacianKind kind) {
  const bool automatic = kind == LaplacianKind::Auto;
  MeshOperators mo = build_mesh_operators(mesh, automatic ? LaplacianKind::Cotan : kind);
  if (automatic)
    mo.reason = "curvature: K x of the input triangles (an intrinsic K interpolates x across intrinsic triangles)";
  return {curvature_from(mesh, mo.mesh, mo.ops, scale), mo.kind, mo.reason};
}

}  // namespace meshpde
