#include "meshpde/mesh/self_intersections.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <numeric>
#include <set>

#include "aabb_tree.h"

namespace meshpde {
namespace {

using detail::Box;
using detail::Tree;
using detail::Vec;

// Segment p-q against the closed triangle (a, b, c), Moller-Trumbore. Parallel
// segments (coplanar configurations) count as not crossing.
bool segment_hits_triangle(const Vec& p, const Vec& q, const Vec& a, const Vec& b, const Vec& c) {
  const Vec d = q - p, e1 = b - a, e2 = c - a;
  const Vec h = d.cross(e2);
  const double det = e1.dot(h);
  const double scale = d.norm() * e1.norm() * e2.norm();
  if (std::abs(det) <= 1e-12 * scale) return false;
  const double inv = 1.0 / det;
  const Vec s = p - a;
  const double u = inv * s.dot(h);
  if (u < 0 || u > 1) return false;
  const Vec qv = s.cross(e1);
  const double v = inv * d.dot(qv);
  if (v < 0 || u + v > 1) return false;
  const double t = inv * e2.dot(qv);
  return t >= 0 && t <= 1;
}

}  // namespace

bool triangles_intersect(const Vec& a0, const Vec& a1, const Vec& a2, const Vec& b0, const Vec& b1, const Vec& b2) {
  return segment_hits_triangle(a0, a1, b0, b1, b2) || segment_hits_triangle(a1, a2, b0, b1, b2) ||
         segment_hits_triangle(a2, a0, b0, b1, b2) || segment_hits_triangle(b0, b1, a0, a1, a2) ||
         segment_hits_triangle(b1, b2, a0, a1, a2) || segment_hits_triangle(b2, b0, a0, a1, a2);
}

struct SelfIntersectionChecker::Impl {
  Positions V0;
  Triangles F;
  std::vector<int> vf_offset, vf;  // vertex -> incident triangles
  Tree tree;
  mutable std::vector<int> stamp;  // per triangle: last call that marked it moved
  mutable int call = 0;

  Box box(const Positions& V, int t) const {
    Box b;
    for (int c = 0; c < 3; ++c) b.add(V.row(F(t, c)).transpose());
    return b;
  }
  bool share_corner(int s, int t) const {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (F(s, a) == F(t, b)) return true;
    return false;
  }
  bool intersect(const Positions& V, int s, int t) const {
    auto p = [&](int f, int c) { return Vec(V.row(F(f, c)).transpose()); };
    return triangles_intersect(p(s, 0), p(s, 1), p(s, 2), p(t, 0), p(t, 1), p(t, 2));
  }
};

SelfIntersectionChecker::SelfIntersectionChecker(const Mesh& mesh) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.V0 = mesh.positions();
  m.F = mesh.triangles();
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  m.vf_offset.assign(static_cast<std::size_t>(nv) + 1, 0);
  for (int f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c) ++m.vf_offset[static_cast<std::size_t>(m.F(f, c)) + 1];
  std::partial_sum(m.vf_offset.begin(), m.vf_offset.end(), m.vf_offset.begin());
  m.vf.resize(static_cast<std::size_t>(m.vf_offset.back()));
  std::vector<int> fill(m.vf_offset.begin(), m.vf_offset.end() - 1);
  for (int f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c) m.vf[static_cast<std::size_t>(fill[static_cast<std::size_t>(m.F(f, c))]++)] = f;
  std::vector<int> all(static_cast<std::size_t>(nf));
  std::iota(all.begin(), all.end(), 0);
  m.tree.build(all, [&](int t) { return m.box(m.V0, t); });
  m.stamp.assign(static_cast<std::size_t>(nf), -1);
}

SelfIntersectionChecker::~SelfIntersectionChecker() = default;
SelfIntersectionChecker::SelfIntersectionChecker(SelfIntersectionChecker&&) noexcept = default;
SelfIntersectionChecker& SelfIntersectionChecker::operator=(SelfIntersectionChecker&&) noexcept = default;

std::vector<std::pair<int, int>> SelfIntersectionChecker::intersecting_pairs(const Positions& V,
                                                                             std::span<const int> moved) const {
  const Impl& m = *impl_;
  const int call = ++m.call;
  std::vector<int> moved_tris;
  for (const int v : moved)
    for (int k = m.vf_offset[static_cast<std::size_t>(v)]; k < m.vf_offset[static_cast<std::size_t>(v) + 1]; ++k) {
      const int t = m.vf[static_cast<std::size_t>(k)];
      if (m.stamp[static_cast<std::size_t>(t)] != call) {
        m.stamp[static_cast<std::size_t>(t)] = call;
        moved_tris.push_back(t);
      }
    }
  std::vector<std::pair<int, int>> pairs;
  // Moved triangles against the unmoved ones, through the mesh's tree.
  for (const int t : moved_tris)
    m.tree.query(m.box(V, t), [&](int s) {
      if (m.stamp[static_cast<std::size_t>(s)] == call || m.share_corner(s, t)) return;
      if (m.intersect(V, s, t)) pairs.emplace_back(std::min(s, t), std::max(s, t));
    });
  // Moved triangles among themselves, through a tree of their new boxes.
  Tree local;
  local.build(moved_tris, [&](int t) { return m.box(V, t); });
  for (const int t : moved_tris)
    local.query(m.box(V, t), [&](int s) {
      if (s <= t || m.share_corner(s, t)) return;
      if (m.intersect(V, s, t)) pairs.emplace_back(t, s);
    });
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

std::vector<std::pair<int, int>> SelfIntersectionChecker::all_pairs() const {
  const Impl& m = *impl_;
  std::vector<std::pair<int, int>> pairs;
  for (int t = 0; t < static_cast<int>(m.F.rows()); ++t)
    m.tree.query(m.box(m.V0, t), [&](int s) {
      if (s <= t || m.share_corner(s, t)) return;
      if (m.intersect(m.V0, s, t)) pairs.emplace_back(t, s);
    });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

int SelfIntersectionChecker::count_new(const Positions& V, std::span<const int> moved) const {
  const auto after = intersecting_pairs(V, moved);
  if (after.empty()) return 0;
  const auto before = intersecting_pairs(impl_->V0, moved);
  const std::set<std::pair<int, int>> old(before.begin(), before.end());
  int n = 0;
  for (const auto& p : after) n += !old.count(p);
  return n;
}

}  // namespace meshpde
