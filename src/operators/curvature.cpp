#include "meshpde/operators/curvature.h"

#include <cmath>

namespace meshpde {

Eigen::VectorXd mean_curvature(const Mesh& mesh, const FemOperators& ops, CurvatureScale scale) {
  const Field X = mesh.positions();
  const Field KX = apply_stiffness(mesh, ops, X);
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

}  // namespace meshpde
