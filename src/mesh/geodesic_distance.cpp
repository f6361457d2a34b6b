#include "meshpde/mesh/geodesic_distance.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <queue>
#include <tuple>

#include "../core/index_map.h"
#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

// c's distance through the triangle (a, b, c) from a point source at distances da from a
// and db from b, unfolded across ab away from c: |S c| when the segment S c crosses the
// edge ab, else infinity (the path then runs through a or b, which the edge candidates
// give).
double through_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double da,
                        double db) {
  constexpr double kNone = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const double L2 = ab.squaredNorm();
  if (!(L2 > 0)) return kNone;
  const double L = std::sqrt(L2);
  // The triangle in the plane: a at 0, b at (L, 0), c at (cx, cy) with cy > 0.
  const double cx = ac.dot(ab) / L;
  const double cy2 = ac.squaredNorm() - cx * cx;
  if (!(cy2 > 0)) return kNone;
  const double cy = std::sqrt(cy2);
  // The source at (sx, sy), sy < 0, at distances da and db from a and b.
  const double sx = (da * da - db * db + L2) / (2 * L);
  const double sy2 = da * da - sx * sx;
  if (sy2 < 0) return kNone;  // da + db < L: no such source
  const double sy = -std::sqrt(sy2);
  // Where S c meets the line of ab (y = 0).
  const double x = sx + (-sy / (cy - sy)) * (cx - sx);
  if (x < 0 || x > L) return kNone;
  const double dx = cx - sx, dy = cy - sy;
  return std::sqrt(dx * dx + dy * dy);
}

// About how many vertices lie within `radius` of the sources: a flat disc of that radius
// at the mean edge length h around the first source, pi R^2 / (sqrt(3)/2 h^2), for each
// source, between 64 and the mesh's vertex count (at most 2^20). An estimate for sizing
// the search's tables: growing them from a few entries to a region's thousands cost
// about a sixth of the search (a 9.6k-vertex region: 7.2 against 6.0 ms).
std::size_t expected_reach(const Mesh& mesh, const GeodesicSources& sources, double radius) {
  constexpr double kFew = 64;
  const int nv = mesh.num_vertices();
  if (!std::isfinite(radius) || radius <= 0 || nv == 0) return static_cast<std::size_t>(kFew);
  const auto& V = mesh.positions();
  double h = 0;
  if (!sources.vertices.empty() && sources.vertices[0] >= 0 && sources.vertices[0] < nv) {
    const int s = sources.vertices[0];
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    for (int q = off[s]; q < off[s + 1]; ++q) h += (V.row(s) - V.row(nbr[q])).norm();
    h /= std::max(1, off[s + 1] - off[s]);
  } else if (!sources.points.empty() && sources.points[0].face >= 0 && sources.points[0].face < mesh.num_faces()) {
    const auto& F = mesh.triangles();
    const int f = sources.points[0].face;
    for (int k = 0; k < 3; ++k) h += (V.row(F(f, k)) - V.row(F(f, (k + 1) % 3))).norm() / 3;
  }
  if (!(h > 0)) return static_cast<std::size_t>(kFew);
  const auto count = static_cast<double>(sources.vertices.size() + sources.points.size());
  const double disc = 3.7 * (radius / h) * (radius / h) * count;
  return static_cast<std::size_t>(std::clamp(disc, kFew, std::max(kFew, std::min(1048576.0, static_cast<double>(nv)))));
}

// Most rounds of corrections after the first pass (each one over the vertices whose
// neighbours changed in the round before).
constexpr int kGeodesicRounds = 64;

}  // namespace

std::vector<std::pair<int, double>> geodesic_distances_from(const Mesh& mesh, const GeodesicSources& sources,
                                                            double radius) {
  const int nv = mesh.num_vertices();
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  // Tentative distances and states of the vertices met so far, by local index (sized to
  // the region, not the mesh): a region of a few thousand vertices in a mesh of millions
  // costs what the region does.
  const std::size_t expected = expected_reach(mesh, sources, radius);
  IndexMap index(expected);
  std::vector<double> dist;
  std::vector<char> state;  // 0 tentative, 1 final, 2 final and a source's (kept as it is)
  dist.reserve(expected);
  state.reserve(expected);
  auto slot = [&](int v) {
    const auto [k, inserted] = index.insert(v);
    if (inserted) {
      dist.push_back(std::numeric_limits<double>::infinity());
      state.push_back(0);
    }
    return static_cast<std::size_t>(k);
  };
  auto distance_of = [&](int v) {
    const int k = index.find(v);
    return k < 0 ? std::numeric_limits<double>::infinity() : dist[static_cast<std::size_t>(k)];
  };
  auto is_done = [&](int v) {
    const int k = index.find(v);
    return k >= 0 && state[static_cast<std::size_t>(k)] != 0;
  };
  std::priority_queue<std::pair<double, int>, std::vector<std::pair<double, int>>, std::greater<>> queue;
  auto offer = [&](int v, double d) {
    if (!(d < radius)) return;
    const std::size_t k = slot(v);
    if (state[k] == 0 && d < dist[k]) {
      dist[k] = d;
      queue.emplace(d, v);
    }
  };
  std::vector<int> fixed;  // the sources' vertices and the corners of the sources' triangles
  for (const int v : sources.vertices) {
    if (v < 0 || v >= nv)
      throw InputError(fmt::format("source vertex {} does not exist (the mesh has {} vertices)", v, nv));
    offer(v, 0.0);
    fixed.push_back(v);
  }
  for (std::size_t i = 0; i < sources.points.size(); ++i) {
    const SurfacePoint& p = sources.points[i];
    check_surface_point(mesh, p, fmt::format("source point {}", i));
    const Eigen::Vector3d x = position(mesh, p);
    for (int k = 0; k < 3; ++k) {
      offer(F(p.face, k), (V.row(F(p.face, k)).transpose() - x).norm());
      fixed.push_back(F(p.face, k));
    }
  }
  const VertexFaces& around = mesh.vertex_faces();
  // c's best candidate through the triangles around it, from its final neighbours.
  auto candidate = [&](int c) {
    const Eigen::Vector3d pc = V.row(c).transpose();
    double best = std::numeric_limits<double>::infinity();
    for (int q = around.offsets[static_cast<std::size_t>(c)]; q < around.offsets[static_cast<std::size_t>(c) + 1];
         ++q) {
      const int f = around.faces[static_cast<std::size_t>(q)];
      const int k = F(f, 0) == c ? 0 : F(f, 1) == c ? 1 : 2;
      const int a = F(f, (k + 1) % 3), b = F(f, (k + 2) % 3);
      const bool ka = a != c && is_done(a), kb = b != c && is_done(b);
      const double da = ka ? distance_of(a) : 0, db = kb ? distance_of(b) : 0;
      if (ka) best = std::min(best, da + (V.row(a).transpose() - pc).norm());
      if (kb) best = std::min(best, db + (V.row(b).transpose() - pc).norm());
      if (ka && kb && a != b)
        best = std::min(best, through_triangle(V.row(a).transpose(), V.row(b).transpose(), pc, da, db));
    }
    return best;
  };
  // Final vertices that a later corner may bring nearer, each listed once (by slot).
  std::vector<int> marked;
  std::vector<char> in_marked;
  auto recheck = [&](int v) {
    const std::size_t k = static_cast<std::size_t>(index.find(v));
    if (in_marked.size() < dist.size()) in_marked.resize(dist.size(), 0);
    if (!in_marked[k]) {
      in_marked[k] = 1;
      marked.push_back(v);
    }
  };
  std::vector<std::pair<int, double>> out;
  out.reserve(expected);
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    const std::size_t kv = static_cast<std::size_t>(index.find(v));
    if (state[kv] != 0 || d > dist[kv]) continue;  // stale
    state[kv] = 1;
    out.emplace_back(v, d);
    // The triangles at v give their other corners the candidates that v's distance
    // makes possible (those from the corners known before were offered when they
    // became known).
    const Eigen::Vector3d pv = V.row(v).transpose();
    for (int q = around.offsets[static_cast<std::size_t>(v)]; q < around.offsets[static_cast<std::size_t>(v) + 1];
         ++q) {
      const int f = around.faces[static_cast<std::size_t>(q)];
      const int k = F(f, 0) == v ? 0 : F(f, 1) == v ? 1 : 2;
      const int a = F(f, (k + 1) % 3), b = F(f, (k + 2) % 3);
      if (a == v || b == v || a == b) continue;  // a degenerate triangle (a corner repeated)
      const int ka = index.find(a), kb = index.find(b);
      const bool known_a = ka >= 0 && state[static_cast<std::size_t>(ka)] != 0,
                 known_b = kb >= 0 && state[static_cast<std::size_t>(kb)] != 0;
      for (const auto& [c, kc, known_c, o, ko, known_o] :
           {std::tuple{a, ka, known_a, b, kb, known_b}, std::tuple{b, kb, known_b, a, ka, known_a}}) {
        // Along the edge from v, and through the triangle when its third corner is known.
        const Eigen::Vector3d pc = V.row(c).transpose();
        double best = d + (pc - pv).norm();
        if (known_o)
          best = std::min(best, through_triangle(pv, V.row(o).transpose(), pc, d, dist[static_cast<std::size_t>(ko)]));
        if (!known_c)
          offer(c, best);
        else if (best < dist[static_cast<std::size_t>(kc)] * (1 - 1e-14))
          // Final already: Dijkstra's order made it so before v was known (the far
          // corner of an obtuse triangle, which the straight line to it crosses).
          // Corrected after the pass.
          recheck(c);
      }
    }
  }
  // The corrections: each vertex marked takes the best candidate of its triangles, and
  // a vertex that changed marks the other corners of its triangles for the next round,
  // until nothing changes (a few rounds over a few vertices; sources keep their values).
  for (const int v : fixed)
    if (const int k = index.find(v); k >= 0) state[static_cast<std::size_t>(k)] = 2;
  for (int round = 0; round < kGeodesicRounds && !marked.empty(); ++round) {
    std::vector<int> work;
    work.swap(marked);
    // Nearest first, as the pass went: a correction reaches the vertices behind it in
    // the same round.
    std::sort(work.begin(), work.end(), [&](int x, int y) { return distance_of(x) < distance_of(y); });
    for (const int v : work) {
      const std::size_t kv = static_cast<std::size_t>(index.find(v));
      in_marked[kv] = 0;
      if (state[kv] == 2) continue;
      const double better = candidate(v);
      if (!(better < dist[kv] * (1 - 1e-14))) continue;
      dist[kv] = better;
      for (int q = around.offsets[static_cast<std::size_t>(v)]; q < around.offsets[static_cast<std::size_t>(v) + 1];
           ++q)
        for (int k = 0; k < 3; ++k)
          if (const int w = F(around.faces[static_cast<std::size_t>(q)], k); w != v && index.find(w) >= 0) recheck(w);
    }
  }
  for (auto& [v, d] : out) d = dist[static_cast<std::size_t>(index.find(v))];
  // Only corrections can put the pass's order out of increasing distance.
  const auto nearer = [](const auto& x, const auto& y) { return x.second < y.second; };
  if (!std::is_sorted(out.begin(), out.end(), nearer)) std::stable_sort(out.begin(), out.end(), nearer);
  return out;
}

Eigen::VectorXd geodesic_distance(const Mesh& mesh, const GeodesicSources& sources, double radius) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(mesh.num_vertices(), std::numeric_limits<double>::infinity());
  for (const auto& [v, d] : geodesic_distances_from(mesh, sources, radius)) out[v] = d;
  return out;
}

}  // namespace meshpde
