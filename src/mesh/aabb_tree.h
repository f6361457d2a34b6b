// Internal: axis-aligned bounding boxes and a bounding-volume hierarchy over
// triangles (median split on the longest axis, four triangles a leaf), shared by
// the self-intersection checker, the surface distance and the vessel-radius estimate.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <numeric>
#include <vector>

namespace meshpde::detail {

using Vec = Eigen::Vector3d;

struct Box {
  Vec lo = Vec::Constant(std::numeric_limits<double>::infinity());
  Vec hi = Vec::Constant(-std::numeric_limits<double>::infinity());
  void add(const Vec& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  double distance(const Vec& p) const { return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm(); }
  bool overlaps(const Box& b) const { return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all(); }
};

// AABB tree over a list of triangles (ids into F), median split on the longest axis.
struct Tree {
  struct Node {
    Box box;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int begin = 0, end = 0;     // leaf: range in items
  };
  std::vector<Node> nodes;
  std::vector<int> items;

  template <class BoxOf>
  void build(std::vector<int> ids, BoxOf&& box_of) {
    items = std::move(ids);
    nodes.clear();
    if (items.empty()) return;
    std::vector<Box> boxes(items.size());
    std::vector<Vec> centre(items.size());
    for (std::size_t k = 0; k < items.size(); ++k) {
      boxes[k] = box_of(items[k]);
      centre[k] = 0.5 * (boxes[k].lo + boxes[k].hi);
    }
    std::vector<int> order(items.size());
    std::iota(order.begin(), order.end(), 0);
    nodes.reserve(2 * items.size() / 4 + 2);
    build_node(order, 0, static_cast<int>(order.size()), boxes, centre);
    std::vector<int> permuted(items.size());
    for (std::size_t k = 0; k < order.size(); ++k) permuted[k] = items[static_cast<std::size_t>(order[k])];
    items = std::move(permuted);
  }

  int build_node(std::vector<int>& order, int begin, int end, const std::vector<Box>& boxes,
                 const std::vector<Vec>& centre) {
    const int id = static_cast<int>(nodes.size());
    nodes.emplace_back();
    Box box, cbox;
    for (int k = begin; k < end; ++k) {
      box.add(boxes[static_cast<std::size_t>(order[k])]);
      cbox.add(centre[static_cast<std::size_t>(order[k])]);
    }
    nodes[id].box = box;
    if (end - begin <= 4) {
      nodes[id].begin = begin;
      nodes[id].end = end;
      return id;
    }
    int axis = 0;
    (cbox.hi - cbox.lo).maxCoeff(&axis);
    const int mid = (begin + end) / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](int a, int b) {
      return centre[static_cast<std::size_t>(a)][axis] < centre[static_cast<std::size_t>(b)][axis];
    });
    const int l = build_node(order, begin, mid, boxes, centre);
    const int r = build_node(order, mid, end, boxes, centre);
    nodes[id].left = l;
    nodes[id].right = r;
    return id;
  }

  template <class Visit>
  void query(const Box& b, Visit&& visit) const {
    if (nodes.empty()) return;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top) {
      const Node& n = nodes[static_cast<std::size_t>(stack[--top])];
      if (!n.box.overlaps(b)) continue;
      if (n.left < 0) {
        for (int k = n.begin; k < n.end; ++k) visit(items[static_cast<std::size_t>(k)]);
      } else {
        stack[top++] = n.left;
        stack[top++] = n.right;
      }
    }
  }

  /// Smallest hit(item) (a ray parameter t > 0, infinity for a miss) over the items whose
  /// boxes the ray origin + t dir meets before the best hit so far.
  template <class Hit>
  double first_hit(const Vec& origin, const Vec& dir, Hit&& hit) const {
    double best = std::numeric_limits<double>::infinity();
    if (nodes.empty()) return best;
    auto enters = [&](const Box& b) {  // slab test: where the ray enters the box, or infinity
      double t0 = 0, t1 = best;
      for (int a = 0; a < 3; ++a) {
        if (dir[a] == 0) {
          if (origin[a] < b.lo[a] || origin[a] > b.hi[a]) return std::numeric_limits<double>::infinity();
          continue;
        }
        double ta = (b.lo[a] - origin[a]) / dir[a], tb = (b.hi[a] - origin[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
    };
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top) {
      const Node& n = nodes[static_cast<std::size_t>(stack[--top])];
      if (!(enters(n.box) < best)) continue;
      if (n.left < 0) {
        for (int k = n.begin; k < n.end; ++k) best = std::min(best, hit(items[static_cast<std::size_t>(k)]));
      } else {
        stack[top++] = n.left;
        stack[top++] = n.right;
      }
    }
    return best;
  }

  /// Smallest dist(item) over all items, skipping boxes farther from p than the
  /// best so far (dist(item) must be >= the distance from p to the item's box).
  template <class Dist>
  double nearest(const Vec& p, Dist&& dist) const {
    double best = std::numeric_limits<double>::infinity();
    if (nodes.empty()) return best;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top) {
      const Node& n = nodes[static_cast<std::size_t>(stack[--top])];
      if (n.box.distance(p) >= best) continue;
      if (n.left < 0) {
        for (int k = n.begin; k < n.end; ++k) best = std::min(best, dist(items[static_cast<std::size_t>(k)]));
      } else {
        // Visit the nearer child first (pushed last).
        const bool left_first = nodes[static_cast<std::size_t>(n.left)].box.distance(p) <=
                                nodes[static_cast<std::size_t>(n.right)].box.distance(p);
        stack[top++] = left_first ? n.right : n.left;
        stack[top++] = left_first ? n.left : n.right;
      }
    }
    return best;
  }
};

// The box of triangle f of (V, F).
template <class PointRows, class TriangleRows>
Box triangle_box(const PointRows& V, const TriangleRows& F, int f) {
  Box b;
  for (int k = 0; k < 3; ++k) b.add(Vec(V.row(F(f, k)).transpose()));
  return b;
}

// A tree over all of (V, F)'s triangles.
template <class PointRows, class TriangleRows>
Tree triangle_tree(const PointRows& V, const TriangleRows& F) {
  Tree tree;
  std::vector<int> all(static_cast<std::size_t>(F.rows()));
  std::iota(all.begin(), all.end(), 0);
  tree.build(all, [&](int f) { return triangle_box(V, F, f); });
  return tree;
}

}  // namespace meshpde::detail
