// Image guidance: where a vertex finds the edge it is pulled to.
#include <algorithm>
#include <cmath>
#include <memory>

#include "correction_internal.h"

namespace meshpde {

std::shared_ptr<const Volume> edge_map(const Volume& image, double sigma_mm) {
  return std::make_shared<const Volume>(gradient_magnitude(image, sigma_mm));
}

}  // namespace meshpde

namespace meshpde::correction {

Eigen::Vector3d strongest_in_cube(const ImageGuidance& g, const Eigen::Vector3d& q) {
  const Volume& E = *g.edges;
  const Eigen::Vector3d idx = E.lps_to_index(to_lps(q, g.space));
  const int h = g.cube_size / 2;
  double best_value = -1;
  Eigen::Vector3d best = q;
  for (int dk = -h; dk <= h; ++dk)
    for (int dj = -h; dj <= h; ++dj)
      for (int di = -h; di <= h; ++di) {
        const int ii = static_cast<int>(std::lround(idx[0])) + di, jj = static_cast<int>(std::lround(idx[1])) + dj,
                  kk = static_cast<int>(std::lround(idx[2])) + dk;
        if (ii < 0 || jj < 0 || kk < 0 || ii >= E.dims[0] || jj >= E.dims[1] || kk >= E.dims[2]) continue;
        if (E.at(ii, jj, kk) > best_value) {
          best_value = E.at(ii, jj, kk);
          best = to_lps(E.index_to_lps(Eigen::Vector3d(ii, jj, kk)), g.space);  // LPS <-> RAS is an involution
        }
      }
  return best;
}

ImageTargets find_targets(const ImageGuidance& g, const std::vector<int>& pulled, const Positions& Q,
                          const Eigen::MatrixX3d& normals) {
  ImageTargets t;
  const Volume& E = *g.edges;
  const double step = std::min(0.1, 0.25 * E.spacing.minCoeff());
  for (const int i : pulled) {
    const Eigen::Vector3d q = Q.row(i).transpose();
    if (!E.sample(q, g.space)) continue;
    Eigen::Vector3d best = q;
    if (g.cube_size >= 3) {
      best = strongest_in_cube(g, q);
    } else {
      // The nearest ridge of E along the normal: interior local maxima only (a
      // maximum at the end of the window belongs to something farther away), the
      // nearest of those at least half as strong as the strongest.
      const Eigen::Vector3d n = normals.row(i).transpose();
      const int half = static_cast<int>(std::ceil(g.search_radius / step));
      std::vector<double> e(static_cast<std::size_t>(2 * half + 1), -1.0);
      for (int k = -half; k <= half; ++k)
        if (const auto v = E.sample(q + k * step * n, g.space)) e[static_cast<std::size_t>(k + half)] = *v;
      double strongest = -1;
      std::vector<int> ridges;
      for (int k = 1; k + 1 < static_cast<int>(e.size()); ++k)
        if (e[k] > 0 && e[k] >= e[k - 1] && e[k] >= e[k + 1]) {
          ridges.push_back(k);
          strongest = std::max(strongest, e[static_cast<std::size_t>(k)]);
        }
      int chosen = -1;
      for (const int k : ridges)
        if (e[static_cast<std::size_t>(k)] >= 0.5 * strongest &&
            (chosen < 0 || std::abs(k - half) < std::abs(chosen - half)))
          chosen = k;
      if (chosen < 0) continue;  // no edge in reach: the vertex is not pulled
      best = q + (chosen - half) * step * n;
    }
    t.vertices.push_back(i);
    t.target.push_back(best);
  }
  return t;
}

double mean_edge_strength(const ImageGuidance& g, const std::vector<int>& vertices, const Positions& Q) {
  double sum = 0;
  int n = 0;
  for (int i : vertices)
    if (const auto e = g.edges->sample(Q.row(i).transpose(), g.space)) {
      sum += *e;
      ++n;
    }
  return n ? sum / n : 0.0;
}

}  // namespace meshpde::correction
