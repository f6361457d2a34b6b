#include "meshpde/operators/intrinsic_delaunay.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/triangle_lengths.h"

namespace meshpde {
namespace {

// Triangle soup with corner-table gluing. Triangle t has corners tri[3t..3t+2];
// halfedge h = 3t + c runs from corner c to corner c+1 (opposite corner c+2),
// twin[h] is the glued halfedge running the other way, len[h] its length.
struct Cover {
  std::vector<int> tri;
  std::vector<int> twin;
  std::vector<double> len;
  int num_triangles() const { return static_cast<int>(tri.size() / 3); }
};

inline int next(int h) {
  return h - h % 3 + (h % 3 + 1) % 3;
}
inline int prev(int h) {
  return h - h % 3 + (h % 3 + 2) % 3;
}

// Cotangent of the angle opposite halfedge h inside its triangle.
double cot_opposite(const Cover& c, int h) {
  return meshpde::cot_opposite(c.len[h], c.len[next(h)], c.len[prev(h)]);
}

// Builds the tufted cover: triangle 2f is face f's front (v0, v1, v2), 2f+1 its
// back (v0, v2, v1). Around every edge the triangles are ordered by angle about
// the edge, and consecutive ones glued: the side of one whose halfedge runs
// i -> j (i < j) to the side of the next running j -> i. With one triangle that
// glues its front to its back; with two, the ordinary manifold gluing.
Cover tufted_cover(const Mesh& mesh, IntrinsicDelaunayStats& stats) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  const int nf = mesh.num_faces();
  Cover c;
  c.tri.resize(6 * static_cast<std::size_t>(nf));
  c.twin.assign(6 * static_cast<std::size_t>(nf), -1);
  c.len.resize(6 * static_cast<std::size_t>(nf));
  for (int f = 0; f < nf; ++f) {
    const int v0 = F(f, 0), v1 = F(f, 1), v2 = F(f, 2);
    const int front[3] = {v0, v1, v2}, back[3] = {v0, v2, v1};
    for (int k = 0; k < 3; ++k) {
      c.tri[6 * f + k] = front[k];
      c.tri[6 * f + 3 + k] = back[k];
    }
  }
  for (std::size_t h = 0; h < c.tri.size(); ++h) {
    const int i = c.tri[h], j = c.tri[static_cast<std::size_t>(next(static_cast<int>(h)))];
    c.len[h] = (V.row(i) - V.row(j)).norm();
  }
  // Group halfedges by undirected edge through the mesh's edge ids.
  const int ne = mesh.num_edges();
  std::vector<std::vector<int>> forward(ne);  // per edge: halfedges running low -> high
  std::vector<std::vector<int>> backward(ne);
  for (std::size_t h = 0; h < c.tri.size(); ++h) {
    const int i = c.tri[h], j = c.tri[static_cast<std::size_t>(next(static_cast<int>(h)))];
    if (i == j) continue;  // repeated index: no edge, degenerate triangle
    const int e = mesh.edge_ids()[mesh.find_slot(i, j)];
    (i < j ? forward : backward)[e].push_back(static_cast<int>(h));
  }
  for (int e = 0; e < ne; ++e) {
    auto& fw = forward[e];
    auto& bw = backward[e];
    // Each original triangle on the edge contributes one forward and one backward
    // halfedge (front and back sides). Order the triangles about the edge.
    const int m = static_cast<int>(fw.size());
    if (m >= 3) ++stats.nonmanifold_edges;
    if (m == 0 || bw.size() != fw.size()) continue;
    if (m > 2) {
      const int i = mesh.edges()(e, 0), j = mesh.edges()(e, 1);
      const Eigen::Vector3d pi = V.row(i).transpose();
      const Eigen::Vector3d u = (V.row(j).transpose() - pi).normalized();
      auto perp = [&](int h) {
        const int k = c.tri[static_cast<std::size_t>(prev(h))];
        Eigen::Vector3d w = V.row(k).transpose() - pi;
        return Eigen::Vector3d(w - w.dot(u) * u);
      };
      const Eigen::Vector3d ref = perp(fw[0]).normalized();
      const Eigen::Vector3d ref2 = u.cross(ref);
      auto angle = [&](int h) {
        const Eigen::Vector3d w = perp(h);
        return std::atan2(w.dot(ref2), w.dot(ref));
      };
      std::vector<double> key(static_cast<std::size_t>(m));
      std::vector<int> order(static_cast<std::size_t>(m));
      std::iota(order.begin(), order.end(), 0);
      for (int t = 0; t < m; ++t) key[static_cast<std::size_t>(t)] = angle(fw[static_cast<std::size_t>(t)]);
      std::sort(order.begin(), order.end(), [&](int a, int b) { return key[a] < key[b]; });
      std::vector<int> f2(static_cast<std::size_t>(m));
      for (int t = 0; t < m; ++t) f2[static_cast<std::size_t>(t)] = fw[static_cast<std::size_t>(order[t])];
      fw = f2;
    }
    // The backward halfedge of the same original face as fw[t]: same face = same
    // h / 6 (front and back share it).
    auto back_of = [&](int h) {
      for (int g : bw)
        if (g / 6 == h / 6) return g;
      return -1;
    };
    for (int t = 0; t < m; ++t) {
      const int h = fw[static_cast<std::size_t>(t)];
      const int g = back_of(fw[static_cast<std::size_t>((t + 1) % m)]);
      c.twin[static_cast<std::size_t>(h)] = g;
      c.twin[static_cast<std::size_t>(g)] = h;
    }
  }
  return c;
}

// Flips the edge of halfedge h (twin g): triangles (a, b, x) and (b, a, y) become
// (x, a, y) and (y, b, x). Returns false when the flip is not possible.
bool flip(Cover& c, int h) {
  const int g = c.twin[static_cast<std::size_t>(h)];
  const int t = h / 3, u = g / 3;
  if (g < 0 || t == u) return false;
  const int h_bx = next(h), h_xa = prev(h), h_ay = next(g), h_yb = prev(g);
  const int a = c.tri[static_cast<std::size_t>(h)], b = c.tri[static_cast<std::size_t>(h_bx)];
  const int x = c.tri[static_cast<std::size_t>(h_xa)], y = c.tri[static_cast<std::size_t>(h_yb)];
  const double l_ab = c.len[static_cast<std::size_t>(h)], l_bx = c.len[static_cast<std::size_t>(h_bx)];
  const double l_xa = c.len[static_cast<std::size_t>(h_xa)], l_ay = c.len[static_cast<std::size_t>(h_ay)];
  const double l_yb = c.len[static_cast<std::size_t>(h_yb)];
  if (!(l_ab > 0)) return false;
  // Lay the quad out with a = (0, 0), b = (l_ab, 0), x above and y below.
  const double xx = (l_ab * l_ab + l_xa * l_xa - l_bx * l_bx) / (2 * l_ab);
  const double xy = std::sqrt(std::max(0.0, l_xa * l_xa - xx * xx));
  const double yx = (l_ab * l_ab + l_ay * l_ay - l_yb * l_yb) / (2 * l_ab);
  const double yy = -std::sqrt(std::max(0.0, l_ay * l_ay - yx * yx));
  const double l_xy = std::hypot(xx - yx, xy - yy);
  // New halfedge ids: t = (x, a, y), u = (y, b, x).
  const int n_xa = 3 * t, n_ay = 3 * t + 1, n_yx = 3 * t + 2;
  const int n_yb = 3 * u, n_bx = 3 * u + 1, n_xy = 3 * u + 2;
  const int old_ids[4] = {h_xa, h_ay, h_yb, h_bx};
  const int new_ids[4] = {n_xa, n_ay, n_yb, n_bx};
  const double lens[4] = {l_xa, l_ay, l_yb, l_bx};
  int old_twin[4];
  for (int k = 0; k < 4; ++k) old_twin[k] = c.twin[static_cast<std::size_t>(old_ids[k])];
  auto remap = [&](int id) {
    for (int k = 0; k < 4; ++k)
      if (old_ids[k] == id) return new_ids[k];
    return id;
  };
  const int tri_t[3] = {x, a, y}, tri_u[3] = {y, b, x};
  for (int k = 0; k < 3; ++k) {
    c.tri[static_cast<std::size_t>(3 * t + k)] = tri_t[k];
    c.tri[static_cast<std::size_t>(3 * u + k)] = tri_u[k];
  }
  for (int k = 0; k < 4; ++k) {
    const int n = new_ids[k], tw = remap(old_twin[k]);
    c.len[static_cast<std::size_t>(n)] = lens[k];
    c.twin[static_cast<std::size_t>(n)] = tw;
    if (tw >= 0) c.twin[static_cast<std::size_t>(tw)] = n;
  }
  c.len[static_cast<std::size_t>(n_yx)] = c.len[static_cast<std::size_t>(n_xy)] = l_xy;
  c.twin[static_cast<std::size_t>(n_yx)] = n_xy;
  c.twin[static_cast<std::size_t>(n_xy)] = n_yx;
  return true;
}

bool is_delaunay(const Cover& c, int h) {
  const int g = c.twin[static_cast<std::size_t>(h)];
  if (g < 0) return true;
  // cot alpha + cot beta >= 0, with slack for rounding (cotangents are dimensionless).
  return cot_opposite(c, h) + cot_opposite(c, g) >= -1e-10;
}

}  // namespace

IntrinsicOperators build_intrinsic_delaunay_operators(const Mesh& mesh, const IntrinsicDelaunayOptions& options) {
  const int nv = mesh.num_vertices();
  if (options.vertex_weights.size() != 0) {
    if (options.vertex_weights.size() != nv)
      throw InputError(fmt::format("vertex weights have {} values for {} vertices", options.vertex_weights.size(), nv));
    for (int i = 0; i < nv; ++i)
      if (!(options.vertex_weights[i] >= 0) || !std::isfinite(options.vertex_weights[i]))
        throw InputError(fmt::format("vertex weight {} of vertex {} is not a finite non-negative number",
                                     options.vertex_weights[i], i));
  }
  IntrinsicOperators out;
  Cover c = tufted_cover(mesh, out.stats);

  // Mollify: grow every length by delta so each triangle has margin epsilon.
  double mean = 0;
  for (double l : c.len) mean += l;
  mean = c.len.empty() ? 0 : mean / static_cast<double>(c.len.size());
  const double eps = options.mollify_epsilon * mean;
  double delta = 0;
  for (int t = 0; t < c.num_triangles(); ++t) {
    const int* v = &c.tri[static_cast<std::size_t>(3 * t)];
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) continue;
    for (int k = 0; k < 3; ++k) {
      const double a = c.len[static_cast<std::size_t>(3 * t + k)];
      const double b = c.len[static_cast<std::size_t>(3 * t + (k + 1) % 3)];
      const double d = c.len[static_cast<std::size_t>(3 * t + (k + 2) % 3)];
      delta = std::max(delta, eps - (b + d - a));
    }
  }
  if (delta > 0)
    for (double& l : c.len) l += delta;
  out.stats.mollify_delta = delta;

  // Flip until Delaunay. Each edge is queued once at a time, from its lower halfedge.
  const int nh = static_cast<int>(c.tri.size());
  std::vector<char> queued(static_cast<std::size_t>(nh), 0);
  std::vector<int> stack;
  stack.reserve(static_cast<std::size_t>(nh) / 2);
  for (int h = 0; h < nh; ++h) {
    const int g = c.twin[static_cast<std::size_t>(h)];
    if (g > h) {
      stack.push_back(h);
      queued[static_cast<std::size_t>(h)] = 1;
      // Each input edge appears on both sheets of the cover; count it once.
      if (!is_delaunay(c, h) && c.tri[static_cast<std::size_t>(h)] < c.tri[static_cast<std::size_t>(next(h))])
        ++out.stats.non_delaunay_edges_before;
    }
  }
  // Flips strictly decrease a bounded energy (Bobenko-Springborn), so this ends;
  // the cap only guards against rounding cycles.
  const long long max_flips = 100LL * nh + 1000;
  long long flips = 0;
  while (!stack.empty()) {
    const int h = stack.back();
    stack.pop_back();
    queued[static_cast<std::size_t>(h)] = 0;
    const int g = c.twin[static_cast<std::size_t>(h)];
    if (g < 0 || is_delaunay(c, h)) continue;
    if (flips >= max_flips) {
      out.stats.delaunay = false;
      break;
    }
    const int t = h / 3, u = g / 3;
    if (!flip(c, h)) continue;
    ++flips;
    for (int k = 0; k < 3; ++k)
      for (const int tri : {t, u}) {
        const int e = 3 * tri + k;
        const int lo = std::min(e, c.twin[static_cast<std::size_t>(e)]);
        if (!queued[static_cast<std::size_t>(lo)]) {
          queued[static_cast<std::size_t>(lo)] = 1;
          stack.push_back(lo);
        }
      }
  }
  out.stats.flips = static_cast<int>(flips);

  // Operator connectivity: the intrinsic triangles (both sheets) on the input positions.
  const int nt = c.num_triangles();
  Triangles Fi(nt, 3);
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) Fi(t, k) = c.tri[static_cast<std::size_t>(3 * t + k)];
  out.operator_mesh = Mesh(mesh.positions(), Fi);
  const Mesh& om = out.operator_mesh;

  FemOperators& ops = out.ops;
  ops.Kii = Eigen::VectorXd::Zero(nv);
  ops.mass = Eigen::VectorXd::Zero(nv);
  Eigen::VectorXd edge_value = Eigen::VectorXd::Zero(om.num_edges());
  for (int t = 0; t < nt; ++t) {
    const int v[3] = {Fi(t, 0), Fi(t, 1), Fi(t, 2)};
    // l[a]: length of the edge opposite corner a (halfedge 3t + a + 1).
    const double l[3] = {c.len[static_cast<std::size_t>(3 * t + 1)], c.len[static_cast<std::size_t>(3 * t + 2)],
                         c.len[static_cast<std::size_t>(3 * t)]};
    const double A = heron_area(l[0], l[1], l[2]);
    if (!(A > 0)) {
      ++ops.degenerate_faces;
      continue;
    }
    double w = 0.5;  // the cover counts every triangle twice
    if (options.vertex_weights.size())
      w *= (options.vertex_weights[v[0]] + options.vertex_weights[v[1]] + options.vertex_weights[v[2]]) / 3.0;
    const double s = w / (4.0 * A);
    for (int a = 0; a < 3; ++a) {
      const int b = (a + 1) % 3, d = (a + 2) % 3;
      ops.mass[v[a]] += 0.5 * A / 3.0;
      // Same element matrix as fem_operators.cpp, written with lengths:
      // e_a . e_a = l_a^2 and e_b . e_d = (l_a^2 - l_b^2 - l_d^2) / 2.
      ops.Kii[v[a]] += s * l[a] * l[a];
      if (v[b] == v[d]) {
        // A loop edge (b and d the same vertex) couples the vertex to itself:
        // its entry lands on the diagonal.
        ops.Kii[v[b]] += 2 * s * 0.5 * (l[a] * l[a] - l[b] * l[b] - l[d] * l[d]);
        continue;
      }
      edge_value[om.edge_ids()[om.find_slot(v[b], v[d])]] += s * 0.5 * (l[a] * l[a] - l[b] * l[b] - l[d] * l[d]);
    }
  }
  ops.Kij.resize(static_cast<Eigen::Index>(om.neighbors().size()));
  for (std::size_t s = 0; s < om.neighbors().size(); ++s)
    ops.Kij[static_cast<Eigen::Index>(s)] = edge_value[om.edge_ids()[s]];
  for (int i = 0; i < nv; ++i) ops.zero_area_vertices += ops.mass[i] <= 0;
  return out;
}

}  // namespace meshpde
