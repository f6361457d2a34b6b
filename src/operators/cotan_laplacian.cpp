#include "meshpde/operators/cotan_laplacian.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "meshpde/mesh/topology.h"
#include "meshpde/operators/triangle_lengths.h"

namespace meshpde {

Eigen::SparseMatrix<double> cotan_laplacian(const Mesh& mesh, CotanFormula formula) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(12 * static_cast<std::size_t>(mesh.num_faces()));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (is_degenerate(mesh, f)) continue;
    double l2[3];  // squared length of the edge opposite corner k
    double l[3];
    for (int k = 0; k < 3; ++k) {
      l2[k] = (V.row(F(f, (k + 1) % 3)) - V.row(F(f, (k + 2) % 3))).squaredNorm();
      l[k] = std::sqrt(l2[k]);
    }
    const double A = heron_area(l[0], l[1], l[2]);
    if (!(A > 0)) continue;
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      // The angle at corner k faces edge (i, j).
      double half_cot;
      if (formula == CotanFormula::EdgeLengths) {
        half_cot = 0.5 * cot_opposite(l[k], l[(k + 1) % 3], l[(k + 2) % 3]);
      } else {
        const Eigen::Vector3d u = V.row(i) - V.row(F(f, k)), w = V.row(j) - V.row(F(f, k));
        half_cot = 0.5 / std::tan(std::atan2(u.cross(w).norm(), u.dot(w)));
      }
      t.emplace_back(i, j, half_cot);
      t.emplace_back(j, i, half_cot);
      t.emplace_back(i, i, -half_cot);
      t.emplace_back(j, j, -half_cot);
    }
  }
  Eigen::SparseMatrix<double> L(mesh.num_vertices(), mesh.num_vertices());
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

}  // namespace meshpde
