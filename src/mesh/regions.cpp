#include "meshpde/mesh/regions.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <queue>
#include <unordered_map>

#include "../core/index_map.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

namespace {

// A radix heap (Ahuja, Mehlhorn, Orlin and Tarjan 1990) for Dijkstra's non-negative,
// never decreasing keys: a double >= 0 orders as its bit pattern does, and an item sits
// in the bucket of the highest bit where its key differs from the last key taken out.
// Pushing is an append; taking out empties the lowest bucket by redistributing the next
// non-empty one around its minimum. On a 10k-vertex ball this took 1.35-1.7 ms where
// std::priority_queue took 2.0 ms (set-up of a drag region, docs/solvers-measurements.md).
class MonotoneQueue {
 public:
  void push(double key, int value) {
    const std::uint64_t k = bits(key);
    buckets_[bucket(k)].emplace_back(k, value);
    ++size_;
  }
  bool empty() const { return size_ == 0; }
  /// The item with the smallest key; \pre !empty().
  std::pair<double, int> pop() {
    if (buckets_[0].empty()) {
      std::size_t b = 1;
      while (buckets_[b].empty()) ++b;
      std::uint64_t smallest = buckets_[b][0].first;
      for (const auto& item : buckets_[b]) smallest = std::min(smallest, item.first);
      last_ = smallest;
      for (const auto& item : buckets_[b]) buckets_[bucket(item.first)].push_back(item);  // all into lower buckets
      buckets_[b].clear();
    }
    const auto [k, value] = buckets_[0].back();
    buckets_[0].pop_back();
    --size_;
    return {std::bit_cast<double>(k), value};
  }

 private:
  static std::uint64_t bits(double key) { return std::bit_cast<std::uint64_t>(key); }
  std::size_t bucket(std::uint64_t k) const {
    return k == last_ ? 0 : static_cast<std::size_t>(64 - std::countl_zero(k ^ last_));
  }
  std::array<std::vector<std::pair<std::uint64_t, int>>, 65> buckets_;
  std::uint64_t last_ = 0;
  std::size_t size_ = 0;
};

}  // namespace

std::vector<int> geodesic_ball(const Mesh& mesh, int source, double radius) {
  const double* P = mesh.positions().data();  // row-major: x, y, z of vertex v at 3 v
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  // Room for about as many vertices as a flat disc of the radius holds at the source's
  // edge length, at most 64k (an estimate only: the map grows when it is short): growing
  // a map from 16 to 10k entries cost a third of the search.
  double h = 0;
  for (int q = off[source]; q < off[source + 1]; ++q)
    h += (mesh.positions().row(source) - mesh.positions().row(nbr[q])).norm();
  h /= std::max(1, off[source + 1] - off[source]);
  const double disc = 3.7 * radius * radius / (h * h);  // pi r^2 / (sqrt(3)/2 h^2)
  const std::size_t expected =
      disc >= 16 ? static_cast<std::size_t>(std::min({disc, 65536.0, static_cast<double>(mesh.num_vertices())})) : 16;
  // Tentative distances of the vertices reached so far, by local index (sized to the
  // ball, not the mesh); -1 once a vertex is taken out (its distance is final).
  IndexMap index(expected);
  std::vector<double> dist;
  dist.reserve(expected);
  index.insert(source);
  dist.push_back(0.0);
  MonotoneQueue queue;
  queue.push(0.0, source);
  std::vector<int> out;
  while (!queue.empty()) {
    const auto [d, v] = queue.pop();
    double& dv = dist[static_cast<std::size_t>(index.find(v))];
    if (dv < 0 || d > dv) continue;  // taken out before, or a stale entry
    dv = -1;
    out.push_back(v);
    const double* pv = P + 3 * static_cast<std::ptrdiff_t>(v);
    for (int q = off[v]; q < off[v + 1]; ++q) {
      const int w = nbr[q];
      const int k = index.find(w);
      if (k >= 0 && dist[static_cast<std::size_t>(k)] < 0) continue;
      const double* pw = P + 3 * static_cast<std::ptrdiff_t>(w);
      const double dx = pv[0] - pw[0], dy = pv[1] - pw[1], dz = pv[2] - pw[2];
      const double dw = d + std::sqrt(dx * dx + dy * dy + dz * dz);
      if (dw >= radius) continue;
      if (k < 0) {
        index.insert(w);
        dist.push_back(dw);
      } else if (dw < dist[static_cast<std::size_t>(k)]) {
        dist[static_cast<std::size_t>(k)] = dw;
      } else {
        continue;
      }
      queue.push(dw, w);
    }
  }
  return out;
}

std::vector<int> ring_ball(const Mesh& mesh, int source, int rings) {
  std::unordered_map<int, int> level{{source, 0}};
  std::vector<int> out{source};
  for (std::size_t k = 0; k < out.size(); ++k) {
    const int v = out[k];
    if (level[v] >= rings) continue;
    for (int w : mesh.neighbors(v))
      if (level.emplace(w, level[v] + 1).second) out.push_back(w);
  }
  return out;
}

namespace {

// Whether `spec` gives its region by radius (else by rings). \throw InputError unless
// exactly one of the two is given.
bool by_radius(const RegionSpec& spec) {
  const bool radius = spec.radius > 0 && std::isfinite(spec.radius), rings = spec.rings > 0;
  if (radius == rings)
    throw InputError(fmt::format("give a region as a radius > 0 or as rings > 0, not both (radius {}, rings {})",
                                 spec.radius, spec.rings));
  return radius;
}

}  // namespace

std::vector<int> region_around(const Mesh& mesh, int source, const RegionSpec& spec) {
  if (source < 0 || source >= mesh.num_vertices())
    throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", source, mesh.num_vertices()));
  if (!by_radius(spec)) return ring_ball(mesh, source, spec.rings);
  std::vector<int> out;
  for (const auto& [v, d] : geodesic_distances_from(mesh, GeodesicSources{.vertices = {source}}, spec.radius))
    out.push_back(v);
  return out;
}

std::vector<std::pair<int, double>> geodesic_distances(const Mesh& mesh, std::span<const int> sources, double radius) {
  std::unordered_map<int, double> best;
  std::priority_queue<std::pair<double, int>, std::vector<std::pair<double, int>>, std::greater<>> queue;
  for (const int s : sources) {
    if (s < 0 || s >= mesh.num_vertices())
      throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", s, mesh.num_vertices()));
    if (best.emplace(s, 0.0).second) queue.emplace(0.0, s);
  }
  std::vector<std::pair<int, double>> out;
  std::unordered_map<int, char> done;
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (done.count(v) || d > best.at(v)) continue;
    done.emplace(v, 1);
    out.emplace_back(v, d);
    for (const int w : mesh.neighbors(v)) {
      const double dw = d + (mesh.positions().row(v) - mesh.positions().row(w)).norm();
      if (dw >= radius || done.count(w)) continue;
      const auto it = best.find(w);
      if (it == best.end() || dw < it->second) {
        best[w] = dw;
        queue.emplace(dw, w);
      }
    }
  }
  return out;
}

double mean_edge_length_among(const Mesh& mesh, const std::vector<int>& vertices) {
  std::unordered_map<int, char> in;
  for (int v : vertices) in.emplace(v, 1);
  double sum = 0;
  int n = 0;
  for (int v : vertices)
    for (int w : mesh.neighbors(v))
      if (w > v && in.count(w)) {
        sum += (mesh.positions().row(v) - mesh.positions().row(w)).norm();
        ++n;
      }
  return n ? sum / n : 0.0;
}

std::vector<int> influence_region(const Mesh& mesh, std::span<const int> handles, const RegionSpec& spec,
                                  bool clamp_at_radius) {
  std::vector<int> out;
  std::vector<char> seen(static_cast<std::size_t>(mesh.num_vertices()), 0);
  for (const int h : handles) {
    if (h < 0 || h >= mesh.num_vertices())
      throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", h, mesh.num_vertices()));
    if (!seen[static_cast<std::size_t>(h)]++) out.push_back(h);
  }
  for (const int h : handles) {
    // Edge paths, not region_around's surface distance: the rule before the smooth
    // boundary, kept as it was for comparison.
    std::vector<int> ball = by_radius(spec) ? geodesic_ball(mesh, h, spec.radius) : ring_ball(mesh, h, spec.rings);
    if (spec.radius > 0 && clamp_at_radius) {
      const double edge = mean_edge_length_among(mesh, ball);
      if (edge > 0 && spec.radius > 2 * edge) ball = geodesic_ball(mesh, h, spec.radius - edge);
    }
    for (const int v : ball)
      if (!seen[static_cast<std::size_t>(v)]++) out.push_back(v);
  }
  return out;
}

RegionCopy copy_region(const Mesh& mesh, const std::vector<int>& region, int margin_rings) {
  RegionCopy c;
  auto add = [&](int v) {
    if (c.from_mesh.emplace(v, static_cast<int>(c.to_mesh.size())).second) c.to_mesh.push_back(v);
  };
  for (const int v : region) add(v);
  std::size_t begin = 0;
  for (int ring = 0; ring < margin_rings; ++ring) {
    const std::size_t end = c.to_mesh.size();
    for (std::size_t k = begin; k < end; ++k)
      for (const int w : mesh.neighbors(c.to_mesh[k])) add(w);
    begin = end;
  }
  if (static_cast<int>(c.to_mesh.size()) == mesh.num_vertices()) {
    c.mesh = mesh;
    c.whole = true;
    c.to_mesh.resize(static_cast<std::size_t>(mesh.num_vertices()));
    for (int v = 0; v < mesh.num_vertices(); ++v) c.to_mesh[static_cast<std::size_t>(v)] = v;
    c.from_mesh.clear();
    return c;
  }
  std::vector<Eigen::Vector3i> tris;
  const auto& F = mesh.triangles();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto a = c.from_mesh.find(F(f, 0)), b = c.from_mesh.find(F(f, 1)), d = c.from_mesh.find(F(f, 2));
    if (a != c.from_mesh.end() && b != c.from_mesh.end() && d != c.from_mesh.end())
      tris.emplace_back(a->second, b->second, d->second);
  }
  Positions V(static_cast<Eigen::Index>(c.to_mesh.size()), 3);
  for (std::size_t k = 0; k < c.to_mesh.size(); ++k)
    V.row(static_cast<Eigen::Index>(k)) = mesh.positions().row(c.to_mesh[k]);
  Triangles T(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t) T.row(static_cast<Eigen::Index>(t)) = tris[t].transpose();
  c.mesh = Mesh(std::move(V), std::move(T));
  return c;
}

int rings_for_radius(const Mesh& mesh, double radius) {
  const double h = mean_edge_length(mesh);
  if (!(h > 0) || !(radius > 0)) return 1;
  return std::max(1, static_cast<int>(std::lround(radius / h)));
}

void apply_brush(const Mesh& mesh, Eigen::VectorXd& field, const Brush& b) {
  if (b.vertex < 0 || b.vertex >= mesh.num_vertices())
    throw InputError(
        fmt::format("brush vertex {} does not exist (the mesh has {} vertices)", b.vertex, mesh.num_vertices()));
  if (!(b.radius > 0) || !std::isfinite(b.radius) || !(b.value > 0) || !std::isfinite(b.value))
    throw InputError(fmt::format("brush radius and value must be > 0 (got {} and {})", b.radius, b.value));
  if (field.size() == 0) field = Eigen::VectorXd::Ones(mesh.num_vertices());
  if (field.size() != mesh.num_vertices())
    throw InputError(fmt::format("brushed field has {} entries for {} vertices", field.size(), mesh.num_vertices()));
  for (int u : geodesic_ball(mesh, b.vertex, b.radius)) field[u] = b.value;
}

}  // namespace meshpde
