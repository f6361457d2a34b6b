// The thesis's method (Schoenmaker, 3D Interactive Mesh Deformation), the baseline of
// the comparisons: ring by ring, each vertex moved once to where its springs to
// already-placed neighbours relax down to a stability threshold.
#include <algorithm>
#include <cmath>

#include "correction_internal.h"

namespace meshpde::correction {

Field springs(const Mesh& mesh, const CorrectionParams& p, const std::vector<int>& region) {
  const auto& V = mesh.positions();
  Field d = Field::Zero(mesh.num_vertices(), 3);
  std::vector<char> placed(static_cast<std::size_t>(mesh.num_vertices()), 0);
  for (const int v : p.held) placed[static_cast<std::size_t>(v)] = 1;  // anchors that stay put
  for (const auto& h : p.handles) {
    d.row(h.vertex) = h.displacement.transpose();
    placed[static_cast<std::size_t>(h.vertex)] = 1;
  }
  double scale = 0;
  for (const auto& h : p.handles) scale = std::max(scale, h.displacement.norm());
  for (const int j : region) {
    if (placed[static_cast<std::size_t>(j)]) continue;
    const double c = std::max(tissue_at(p.tissue.elasticity_field, p.tissue.elasticity, j), 1e-3);
    const double viscosity = tissue_at(p.tissue.viscosity_field, p.tissue.viscosity, j);
    const Eigen::Vector3d p0 = V.row(j).transpose();
    std::vector<Eigen::Vector3d> q;
    std::vector<double> rest;
    double mean_rest = 0;
    for (const int i : mesh.neighbors(j))
      if (placed[static_cast<std::size_t>(i)]) {
        q.push_back(V.row(i).transpose() + d.row(i).transpose());
        rest.push_back((V.row(i) - V.row(j)).norm());
        mean_rest += rest.back();
      }
    placed[static_cast<std::size_t>(j)] = 1;
    if (q.empty()) continue;
    mean_rest /= static_cast<double>(q.size());
    // "Stable" when the net spring force is below c * tol: each ring is left that
    // much stretched, so the displacement decays ring by ring (faster with more
    // viscosity), as the thesis reports.
    const double tol = std::max(1e-4 * scale, 0.1 * viscosity * mean_rest);
    const double n = static_cast<double>(q.size());
    auto spring_force = [&](const Eigen::Vector3d& x) {
      Eigen::Vector3d f = Eigen::Vector3d::Zero();
      for (std::size_t k = 0; k < q.size(); ++k) {
        const Eigen::Vector3d r = q[k] - x;
        const double len = r.norm();
        if (len > 0) f += c * (len - rest[k]) / len * r;
      }
      return f;
    };
    // The image step (eq. 13.7), read as a force: towards the strongest voxel of the
    // direction cube around the vertex, c n 0.006 |d| strong, so that the overdamped
    // step moves the vertex 0.003 |d| a step towards it (the thesis moves it by the
    // image's 0.6 of its factor, 0.006 |d|); "stable" then means the springs and the
    // image balance.
    auto image_force = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d {
      if (!p.image.edges) return Eigen::Vector3d::Zero();
      const Eigen::Vector3d to = strongest_in_cube(p.image, x) - x;
      const double len = to.norm();
      return len > 1e-3 * mean_rest ? Eigen::Vector3d(c * n * 0.006 * scale / len * to) : Eigen::Vector3d::Zero();
    };
    Eigen::Vector3d x = p0;
    if (!p.dynamic) {
      const double eta = 0.5 / (c * n);  // overdamped step, stable for unit springs
      for (int it = 0; it < 2000; ++it) {
        const Eigen::Vector3d f = spring_force(x) + image_force(x);
        if (f.norm() <= c * tol) break;
        x += eta * f;
      }
    } else {
      // The thesis's dynamic version: eq. 12.1 with its inertia, m x'' + gamma x' = f,
      // from rest (semi-implicit Euler, dt a tenth of the vertex's period sqrt(m / (c n))),
      // gamma = 2 viscosity sqrt(m c n): viscosity 1 damps the vertex critically between
      // its springs, 0 leaves it ringing until the step limit, where it stays.
      const double m = std::max(tissue_at(p.tissue.mass_field, p.tissue.mass, j), 1e-3);
      const double gamma = 2 * viscosity * std::sqrt(m * c * n);
      const double dt = 0.1 * std::sqrt(m / (c * n));
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (int it = 0; it < 4000; ++it) {
        const Eigen::Vector3d f = spring_force(x) + image_force(x);
        if (f.norm() <= c * tol && v.norm() * 10 * dt <= tol) break;  // at rest within a period
        v += dt / m * (f - gamma * v);
        x += dt * v;
      }
    }
    d.row(j) = (x - p0).transpose();
  }
  return d;
}

}  // namespace meshpde::correction
