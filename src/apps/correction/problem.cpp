// The region of influence of a correction and its handles' terms (held vertices, or
// loads spread over the handle's size: pde/handle_load.h).
#include <algorithm>

#include "correction_internal.h"
#include "meshpde/mesh/geodesic_distance.h"

namespace meshpde::correction {

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
    out.loaded.push_back(LoadedHandle{handle_load(mesh, h.vertex, h.point, size), h.displacement});
    out.reading[k] = out.loaded.back().reading;
  }
  return out;
}

}  // namespace meshpde::correction
