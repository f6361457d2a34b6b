// A handle's load and reading (pde/handle_load.h).
#include "meshpde/pde/handle_load.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/surface_point_reading.h"

namespace meshpde {

// The handle's load: (1 - (d / r)^2)^2 over the surface within r of its point x, d = |y - x|,
// integrated against each corner's hat function triangle by triangle (each triangle cut
// into n^2 pieces, n = 2 * longest edge / r at most 32, one point each: the profile is
// resolved whatever r is against the edges). The triangles are found by walking from the
// point's own across corners, so the load stays on the sheet of the surface the point is
// on. A load too small to integrate (r far below the edges) is the point load itself.
HandleLoad handle_load(const Mesh& mesh, int vertex, const std::optional<SurfacePoint>& point, double size) {
  const VertexFaces& around = mesh.vertex_faces();
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  HandleLoad out;
  std::vector<int> start;
  Eigen::Vector3d x;
  if (point) {
    for (int k = 0; k < 3; ++k) {
      out.reading.emplace_back(F(point->face, k), point->bary[k]);
      out.corners.push_back(F(point->face, k));
    }
    start.push_back(point->face);
    x = position(mesh, *point);
  } else {
    out.reading.emplace_back(vertex, 1.0);
    out.corners.push_back(vertex);
    for (int q = around.offsets[static_cast<std::size_t>(vertex)];
         q < around.offsets[static_cast<std::size_t>(vertex) + 1]; ++q)
      start.push_back(around.faces[static_cast<std::size_t>(q)]);
    x = V.row(vertex).transpose();
  }
  if (start.empty()) throw InputError(fmt::format("handle vertex {} belongs to no triangle", vertex));
  std::unordered_map<int, double> load;
  if (size > 0) {
    std::unordered_set<int> seen(start.begin(), start.end());
    std::vector<int> stack(start.begin(), start.end());
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(),
                            c = V.row(F(f, 2)).transpose();
      if (point_triangle_distance(x, a, b, c) >= size) continue;
      const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
      // Clamped as a double: a tiny size would overflow the conversion to int.
      const int n = static_cast<int>(std::clamp(std::ceil(2 * longest / size), 1.0, 32.0));
      const double piece = 0.5 * (b - a).cross(c - a).norm() / (n * n);
      Eigen::Vector3d w = Eigen::Vector3d::Zero();  // the triangle's load on its corners
      auto add = [&](double lb, double lc) {
        const Eigen::Vector3d l(1 - lb - lc, lb, lc);
        const double t = ((l[0] * a + l[1] * b + l[2] * c) - x).squaredNorm() / (size * size);
        if (t < 1) w += piece * (1 - t) * (1 - t) * l;
      };
      for (int i = 0; i < n; ++i)
        for (int j = 0; i + j < n; ++j) {
          add((i + 1.0 / 3) / n, (j + 1.0 / 3) / n);                      // the piece pointing up
          if (i + j + 2 <= n) add((i + 2.0 / 3) / n, (j + 2.0 / 3) / n);  // and the one pointing down
        }
      for (int k = 0; k < 3; ++k) {
        if (w[k] > 0) load[F(f, k)] += w[k];
        const int v = F(f, k);
        for (int q = around.offsets[static_cast<std::size_t>(v)]; q < around.offsets[static_cast<std::size_t>(v) + 1];
             ++q)
          if (seen.insert(around.faces[static_cast<std::size_t>(q)]).second)
            stack.push_back(around.faces[static_cast<std::size_t>(q)]);
      }
    }
  }
  double total = 0;
  for (const auto& [v, w] : load) total += w;
  if (!(total > 0)) {
    out.load = out.reading;
    return out;
  }
  for (const auto& [v, w] : load) out.load.emplace_back(v, w / total);
  std::sort(out.load.begin(), out.load.end());
  // A bump that the mesh resolves is read to second order: its linear interpolation
  // would read the peak low by an amount that depends on where in its triangle the point
  // falls, and the whole field would scale up by that much, differently on every
  // triangulation. A load far smaller than the edges keeps the point load's reading
  // (its field has a cusp, which no quadratic reads).
  if (point) {
    const Eigen::Vector3d a = V.row(F(point->face, 0)).transpose(), b = V.row(F(point->face, 1)).transpose(),
                          c = V.row(F(point->face, 2)).transpose();
    const double edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3;
    if (size >= kSmoothReadingSize * edge)
      if (auto reading = quadratic_reading(mesh, *point)) out.reading = std::move(*reading);
  }
  return out;
}

}  // namespace meshpde
