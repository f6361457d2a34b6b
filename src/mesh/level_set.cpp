#include "meshpde/mesh/level_set.h"

#include <fmt/format.h>

#include <cmath>

#include "meshpde/core/errors.h"

namespace meshpde {

std::vector<LevelSetSegment> level_set_segments(const Mesh& mesh, const std::function<double(int)>& value, double level,
                                                std::span<const int> faces) {
  const Positions& V = mesh.positions();
  const Triangles& F = mesh.triangles();
  if (!std::isfinite(level)) throw InputError("level set: the level is not finite");
  std::vector<LevelSetSegment> out;
  const auto one = [&](int f) {
    if (f < 0 || f >= F.rows()) throw InputError(fmt::format("level set: triangle {} is out of range", f));
    const int c[3] = {F(f, 0), F(f, 1), F(f, 2)};
    const double u[3] = {value(c[0]), value(c[1]), value(c[2])};
    if (!std::isfinite(u[0]) || !std::isfinite(u[1]) || !std::isfinite(u[2])) return;
    Eigen::Vector3d ends[2];
    int n = 0;
    for (int k = 0; k < 3; ++k) {
      const int i = k, j = (k + 1) % 3;
      // One corner below and one above: the edge crosses the level (once, linearly).
      if ((u[i] < level) == (u[j] < level)) continue;
      const double t = (level - u[i]) / (u[j] - u[i]);
      if (n < 2) ends[n] = (1 - t) * V.row(c[i]).transpose() + t * V.row(c[j]).transpose();
      ++n;
    }
    if (n == 2) out.push_back({ends[0], ends[1], f});
  };
  if (faces.empty())
    for (int f = 0; f < F.rows(); ++f) one(f);
  else
    for (const int f : faces) one(f);
  return out;
}

std::vector<LevelSetSegment> level_set_segments(const Mesh& mesh, const Eigen::VectorXd& values, double level,
                                                std::span<const int> faces) {
  if (values.size() != mesh.positions().rows())
    throw InputError(fmt::format("level set: {} values for {} vertices", values.size(), mesh.positions().rows()));
  return level_set_segments(
      mesh, [&](int v) { return values[v]; }, level, faces);
}

}  // namespace meshpde
