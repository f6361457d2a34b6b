// The region of influence of a correction and its handles' terms (held vertices, or
// loads spread over the handle's size).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_map>

#include "correction_internal.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/surface_point_reading.h"

namespace meshpde::correction {

namespace {

// The handle's load: (1 - (d / r)^2)^2 over the surface within r of its point x, d = |y - x|,
// integrated against each corner's hat function triangle by triangle (each triangle cut
// into n^2 pieces, n = 2 * longest edge / r at most 32, one point each: the profile is
// resolved whatever r is against the edges). The triangles are found by walking from the
// point's own across corners, so the load stays on the sheet of the surface the point is
// on. A load too small to integrate (r far below the edges) is the point load itself.
LoadedHandle loaded_handle(const Mesh& mesh, const VertexFaces& around, const CorrectionHandle& h, double size) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  LoadedHandle out;
  out.displacement = h.displacement;
  std::vector<int> start;
  Eigen::Vector3d x;
  if (h.point) {
    for (int k = 0; k < 3; ++k) {
      out.point.emplace_back(F(h.point->face, k), h.point->bary[k]);
      out.corners.push_back(F(h.point->face, k));
    }
    start.push_back(h.point->face);
    x = position(mesh, *h.point);
  } else {
    out.point.emplace_back(h.vertex, 1.0);
    out.corners.push_back(h.vertex);
    for (int q = around.offsets[static_cast<std::size_t>(h.vertex)];
         q < around.offsets[static_cast<std::size_t>(h.vertex) + 1]; ++q)
      start.push_back(around.faces[static_cast<std::size_t>(q)]);
    x = V.row(h.vertex).transpose();
  }
  if (start.empty()) throw InputError(fmt::format("handle vertex {} belongs to no triangle", h.vertex));
  std::unordered_map<int, double> load;
  if (size > 0) {
    std::set<int> seen(start.begin(), start.end());
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
    out.load = out.point;
    return out;
  }
  for (const auto& [v, w] : load) out.load.emplace_back(v, w / total);
  std::sort(out.load.begin(), out.load.end());
  // A bump that the mesh resolves is read to second order: its linear interpolation
  // would read the peak low by an amount that depends on where in its triangle the point
  // falls, and the whole field would scale up by that much, differently on every
  // triangulation. A load far smaller than the edges keeps the point load's reading
  // (its field has a cusp, which no quadratic reads).
  if (h.point) {
    const Eigen::Vector3d a = V.row(F(h.point->face, 0)).transpose(), b = V.row(F(h.point->face, 1)).transpose(),
                          c = V.row(F(h.point->face, 2)).transpose();
    const double edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3;
    if (size >= kSmoothReadingSize * edge)
      if (auto reading = quadratic_reading(mesh, *h.point)) out.point = std::move(*reading);
  }
  return out;
}

}  // namespace

// The region of influence and the handles' terms. Smooth: the surface within the radius
// of the handles' points (mesh/geodesic_distance.h). Clamp and Fade: mesh/regions.h's
// edge-path rule from the handles' vertices, clamped at the radius for Fem; with the
// fade, the free set reaches kFadeReach times the radius. Held vertices stay out of the
// region, so that they are held at zero like its outside; a loaded handle's own
// triangle is always in it.
FemProblem fem_problem(const Mesh& mesh, const CorrectionParams& p) {
  FemProblem out;
  const double size = handle_size(p);
  const int nv = mesh.num_vertices();
  std::vector<char> is_held(static_cast<std::size_t>(nv), 0);
  for (const int v : p.held) is_held[static_cast<std::size_t>(v)] = 1;
  std::vector<char> in(static_cast<std::size_t>(nv), 0);
  auto add = [&](int v, double dist) {
    if (is_held[static_cast<std::size_t>(v)] || in[static_cast<std::size_t>(v)]++) return;
    out.region.push_back(v);
    if (smooth(p)) out.distance.push_back(dist);
  };
  for (const auto& h : p.handles) {
    out.reading.push_back({{h.vertex, 1.0}});
    out.sources.push_back(h.vertex);
    if (held_handle(h, size)) {
      out.held.push_back(h);
      add(h.vertex, 0.0);
    }
  }
  if (smooth(p)) {
    GeodesicSources sources;
    for (const auto& h : p.handles) {
      if (h.point)
        sources.points.push_back(*h.point);
      else
        sources.vertices.push_back(h.vertex);
    }
    for (const auto& [v, dist] : geodesic_distances_from(mesh, sources, p.radius)) add(v, dist);
  } else {
    const std::vector<int> region =
        fades(p) ? influence_region(mesh, out.sources, RegionSpec{.radius = kFadeReach * p.radius}, false)
                 : influence_region(mesh, out.sources, RegionSpec{.radius = p.radius, .rings = p.rings},
                                    p.method == CorrectionMethod::Fem);
    for (const int v : region) add(v, 0.0);
  }
  if (p.method != CorrectionMethod::Fem) return out;
  // A loaded handle's point is read from its triangle's corners (or its vertex): they
  // belong to the region whatever the radius.
  for (const auto& h : p.handles) {
    if (held_handle(h, size)) continue;
    if (!h.point) {
      add(h.vertex, 0.0);
      continue;
    }
    const Eigen::Vector3d x = position(mesh, *h.point);
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles()(h.point->face, k);
      add(v, (mesh.positions().row(v).transpose() - x).norm());
    }
  }
  // A region that no held vertex or foundation anchors (it covers its whole part of the
  // surface) moves with its handles as a rigid body: a load could not do that (the
  // system would be singular), so its handles are held at their vertices instead.
  bool anchored = smooth(p) && std::any_of(out.distance.begin(), out.distance.end(),
                                           [&](double dist) { return dist > kSmoothStart * p.radius; });
  for (std::size_t k = 0; k < out.region.size() && !anchored; ++k)
    for (const int w : mesh.neighbors(out.region[k]))
      if (!in[static_cast<std::size_t>(w)]) anchored = true;
  for (std::size_t k = 0; k < p.handles.size(); ++k) {
    const CorrectionHandle& h = p.handles[k];
    if (held_handle(h, size)) continue;
    if (!anchored) {
      out.held.emplace_back(h.vertex, h.displacement);
      add(h.vertex, 0.0);
      continue;
    }
    out.loaded.push_back(loaded_handle(mesh, mesh.vertex_faces(), h, size));
    out.reading[k] = out.loaded.back().point;
  }
  return out;
}

}  // namespace meshpde::correction
