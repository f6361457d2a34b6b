#include "meshpde/mesh/self_intersections.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numeric>
#include <set>

#include "aabb_tree.h"

namespace meshpde {
namespace {

using detail::Box;
using detail::Tree;
using detail::Vec;
using Vec2 = Eigen::Vector2d;

// Relative tolerances of the floating-point predicates. Both are far below any real
// geometry (a 1 mm vessel: 1e-10 mm is an atom's size): they decide what "exactly
// coplanar" and "exactly on the line" mean for doubles, in the direction that reports
// a touching configuration rather than miss it.
constexpr double kCoplanar = 1e-10;  // a vertex this far from a plane, times the pair's size, lies on it
constexpr double kOnLine = 1e-12;    // |cross| below this times the lengths: collinear

// Segment p-q against the closed triangle (a, b, c), Moller-Trumbore. Parallel
// segments (coplanar configurations) count as not crossing: the coplanar test
// below handles those.
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

double cross2(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Orientation of c against the line a-b: +1 left, -1 right, 0 on it (within kOnLine).
int side(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 u = b - a, w = c - a;
  const double x = cross2(u, w);
  if (std::abs(x) <= kOnLine * u.norm() * w.norm()) return 0;
  return x > 0 ? 1 : -1;
}

// Closed segments a-b and c-d in the plane meet (touching and collinear overlap count).
bool segments_meet(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const int s1 = side(a, b, c), s2 = side(a, b, d), s3 = side(c, d, a), s4 = side(c, d, b);
  if (s1 * s2 < 0 && s3 * s4 < 0) return true;
  auto within = [](const Vec2& p, const Vec2& q, const Vec2& x) {  // x on the line p-q: between them?
    return (x - p).dot(x - q) <= 0;
  };
  return (s1 == 0 && within(a, b, c)) || (s2 == 0 && within(a, b, d)) || (s3 == 0 && within(c, d, a)) ||
         (s4 == 0 && within(c, d, b));
}

// p inside or on the closed triangle (a, b, c) of either orientation.
bool point_in_triangle(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const int s1 = side(a, b, p), s2 = side(b, c, p), s3 = side(c, a, p);
  const bool neg = s1 < 0 || s2 < 0 || s3<0, pos = s1> 0 || s2 > 0 || s3 > 0;
  return !(neg && pos);
}

// The plane coordinates of points of the plane with normal n (the two axes other
// than n's largest).
struct Projection {
  int i = 0, j = 1;
  explicit Projection(const Vec& n) {
    int k = 0;
    n.cwiseAbs().maxCoeff(&k);
    i = (k + 1) % 3;
    j = (k + 2) % 3;
  }
  Vec2 operator()(const Vec& p) const { return {p[i], p[j]}; }
};

// Unit normal of (a, b, c), or zero for a degenerate triangle.
Vec unit_normal(const Vec& a, const Vec& b, const Vec& c) {
  const Vec n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Vec(n / len) : Vec::Zero();
}

double size_of(const Vec* a, const Vec* b) {
  double s = 0;
  for (int k = 0; k < 3; ++k) s = std::max({s, (a[k] - a[(k + 1) % 3]).norm(), (b[k] - b[(k + 1) % 3]).norm()});
  return s;
}

// Both triangles lie in one plane (each one's corners within kCoplanar of the other's
// plane); `n` is then the normal to project along.
bool coplanar(const Vec* a, const Vec* b, Vec& n) {
  const double tol = kCoplanar * size_of(a, b);
  const Vec na = unit_normal(a[0], a[1], a[2]), nb = unit_normal(b[0], b[1], b[2]);
  auto on = [&](const Vec& normal, const Vec& origin, const Vec* pts) {
    if (normal.isZero()) return false;
    for (int k = 0; k < 3; ++k)
      if (std::abs(normal.dot(pts[k] - origin)) > tol) return false;
    return true;
  };
  if (on(na, a[0], b)) {
    n = na;
    return true;
  }
  if (on(nb, b[0], a)) {
    n = nb;
    return true;
  }
  return false;
}

// Closed coplanar triangles overlap: an edge pair meets or a corner is inside.
bool coplanar_overlap(const Vec* a, const Vec* b, const Vec& n) {
  const Projection proj(n);
  Vec2 p[3], q[3];
  for (int k = 0; k < 3; ++k) {
    p[k] = proj(a[k]);
    q[k] = proj(b[k]);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (segments_meet(p[i], p[(i + 1) % 3], q[j], q[(j + 1) % 3])) return true;
  return point_in_triangle(p[0], q[0], q[1], q[2]) || point_in_triangle(q[0], p[0], p[1], p[2]);
}

// The ray from the origin along x lies in the closed cone spanned by y1 and y2 (an
// angle below 180 degrees): the two coplanar fans of a shared corner overlap beyond it.
bool ray_in_cone(const Vec2& x, const Vec2& y1, const Vec2& y2) {
  const Vec2 o = Vec2::Zero();
  const int s = side(o, y1, y2);
  const int s1 = side(o, y1, x), s2 = side(o, x, y2);
  if (s == 0) {  // a degenerate cone: the ray y1 (= y2's direction)
    return s1 == 0 && x.dot(y1) > 0;
  }
  if (s1 == 0 && x.dot(y1) > 0) return true;
  if (s2 == 0 && x.dot(y2) > 0) return true;
  return s1 == s && s2 == s;
}

// Whether the points p[0..n) lie clearly on one side of the plane through `o` with
// normal `n` (each farther than 1e-8 of its distance from o, far above the tolerances
// above): then a triangle of them meets that plane nowhere, or only at `o` when o is
// its corner. The quick rejection of Moller's test, which most pairs of a smooth
// surface's neighbouring triangles take.
bool strictly_one_side(const Vec& nrm, const Vec& o, std::initializer_list<const Vec*> pts) {
  const double len = nrm.norm();
  if (!(len > 0)) return false;
  int sign = 0;
  for (const Vec* q : pts) {
    const Vec w = *q - o;
    const double d = nrm.dot(w);
    if (!(std::abs(d) > 1e-8 * len * w.norm())) return false;
    const int s = d > 0 ? 1 : -1;
    if (sign != 0 && s != sign) return false;
    sign = s;
  }
  return true;
}

}  // namespace

bool triangles_intersect(const Vec& a0, const Vec& a1, const Vec& a2, const Vec& b0, const Vec& b1, const Vec& b2) {
  if (strictly_one_side((a1 - a0).cross(a2 - a0), a0, {&b0, &b1, &b2}) ||
      strictly_one_side((b1 - b0).cross(b2 - b0), b0, {&a0, &a1, &a2}))
    return false;
  if (segment_hits_triangle(a0, a1, b0, b1, b2) || segment_hits_triangle(a1, a2, b0, b1, b2) ||
      segment_hits_triangle(a2, a0, b0, b1, b2) || segment_hits_triangle(b0, b1, a0, a1, a2) ||
      segment_hits_triangle(b1, b2, a0, a1, a2) || segment_hits_triangle(b2, b0, a0, a1, a2))
    return true;
  const Vec a[3] = {a0, a1, a2}, b[3] = {b0, b1, b2};
  Vec n;
  return coplanar(a, b, n) && coplanar_overlap(a, b, n);
}

bool corner_triangles_overlap(const Vec& v, const Vec& a1, const Vec& a2, const Vec& b1, const Vec& b2) {
  // One triangle's far corners clearly on one side of the other's plane: they meet at v only.
  if (strictly_one_side((a1 - v).cross(a2 - v), v, {&b1, &b2}) ||
      strictly_one_side((b1 - v).cross(b2 - v), v, {&a1, &a2}))
    return false;
  // Not coplanar: the triangles meet in a segment from v that leaves v only if an
  // opposite edge crosses the other triangle.
  if (segment_hits_triangle(a1, a2, v, b1, b2) || segment_hits_triangle(b1, b2, v, a1, a2)) return true;
  const Vec a[3] = {v, a1, a2}, b[3] = {v, b1, b2};
  Vec n;
  if (!coplanar(a, b, n)) return false;
  // Coplanar: the two fans at v overlap, or an opposite edge crosses the other triangle.
  const Projection proj(n);
  const Vec2 o = proj(v), p1 = proj(a1) - o, p2 = proj(a2) - o, q1 = proj(b1) - o, q2 = proj(b2) - o;
  if (ray_in_cone(p1, q1, q2) || ray_in_cone(p2, q1, q2) || ray_in_cone(q1, p1, p2) || ray_in_cone(q2, p1, p2))
    return true;
  const Vec2 z = Vec2::Zero();
  return segments_meet(p1, p2, q1, q2) || segments_meet(p1, p2, z, q1) || segments_meet(p1, p2, z, q2) ||
         segments_meet(q1, q2, z, p1) || segments_meet(q1, q2, z, p2);
}

double fold_angle(const Vec& p, const Vec& q, const Vec& r, const Vec& s) {
  const Vec e = (q - p).normalized();
  Vec ur = (r - p) - e * e.dot(r - p), us = (s - p) - e * e.dot(s - p);
  const double lr = ur.norm(), ls = us.norm();
  if (!(lr > 0) || !(ls > 0) || !std::isfinite(lr + ls)) return 0;  // a degenerate wing: folded by definition
  ur /= lr;
  us /= ls;
  return std::atan2(e.dot(ur.cross(us)), ur.dot(us));
}

struct SelfIntersectionChecker::Impl {
  Positions V0;
  Triangles F;
  std::vector<int> vf_offset, vf;  // vertex -> incident triangles
  Tree tree;
  mutable std::vector<int> stamp;  // per triangle: last call that marked it moved
  mutable int call = 0;

  Box box(const Positions& V, int t) const { return detail::triangle_box(V, F, t); }
  Vec at(const Positions& V, int v) const { return V.row(v).transpose(); }

  // Whether triangles s and t overlap at positions V beyond the corners they share;
  // for two triangles of one edge also whether the fold between them has flipped
  // through zero since the build positions V0.
  bool overlap(const Positions& V, int s, int t) const {
    int shared_s[3], shared_t[3], n = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (F(s, a) == F(t, b) && n < 3) {
          shared_s[n] = a;
          shared_t[n] = b;
          ++n;
        }
    auto p = [&](int f, int c) { return at(V, F(f, c)); };
    // A triangle with a repeated corner index is a segment or a point: it overlaps
    // whatever it shares a corner with (the same before and after a correction).
    const auto repeated = [&](int f) { return F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 2) == F(f, 0); };
    if (n > 0 && (repeated(s) || repeated(t))) return true;
    if (n == 0) return triangles_intersect(p(s, 0), p(s, 1), p(s, 2), p(t, 0), p(t, 1), p(t, 2));
    if (n == 1) {
      const int a = shared_s[0], b = shared_t[0];
      return corner_triangles_overlap(p(s, a), p(s, (a + 1) % 3), p(s, (a + 2) % 3), p(t, (b + 1) % 3),
                                      p(t, (b + 2) % 3));
    }
    if (n >= 3) return true;  // the same three corners twice
    // One edge (e0, e1): the wings r of s and w of t around it.
    const int e0 = F(s, shared_s[0]), e1 = F(s, shared_s[1]);
    const int r = F(s, 3 - shared_s[0] - shared_s[1]), w = F(t, 3 - shared_t[0] - shared_t[1]);
    const double now = fold_angle(at(V, e0), at(V, e1), at(V, r), at(V, w));
    if (std::abs(now) <= kFoldAngle) return true;  // folded onto each other
    const double before = fold_angle(at(V0, e0), at(V0, e1), at(V0, r), at(V0, w));
    // Flipped through 0: the shorter turn from before to now crosses 0, not 180 degrees.
    return (before > 0) != (now > 0) && std::abs(before) + std::abs(now) < M_PI;
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
  // Moved triangles against the unmoved ones, through the mesh's tree (an unmoved
  // neighbour's box is still right, so folds against it are found here too).
  for (const int t : moved_tris)
    m.tree.query(m.box(V, t), [&](int s) {
      if (m.stamp[static_cast<std::size_t>(s)] == call) return;
      if (m.overlap(V, s, t)) pairs.emplace_back(std::min(s, t), std::max(s, t));
    });
  // Moved triangles among themselves, through a tree of their new boxes.
  Tree local;
  local.build(moved_tris, [&](int t) { return m.box(V, t); });
  for (const int t : moved_tris)
    local.query(m.box(V, t), [&](int s) {
      if (s <= t) return;
      if (m.overlap(V, s, t)) pairs.emplace_back(t, s);
    });
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

std::vector<std::pair<int, int>> SelfIntersectionChecker::overlapping_among(
    const Positions& V, std::span<const std::pair<int, int>> pairs) const {
  std::vector<std::pair<int, int>> out;
  for (const auto& [s, t] : pairs)
    if (impl_->overlap(V, s, t)) out.emplace_back(s, t);
  return out;
}

std::vector<std::pair<int, int>> SelfIntersectionChecker::all_pairs() const {
  const Impl& m = *impl_;
  std::vector<std::pair<int, int>> pairs;
  for (int t = 0; t < static_cast<int>(m.F.rows()); ++t)
    m.tree.query(m.box(m.V0, t), [&](int s) {
      if (s <= t) return;
      if (m.overlap(m.V0, s, t)) pairs.emplace_back(t, s);
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
