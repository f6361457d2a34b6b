#include "meshpde/solvers/ordering.h"

#include <fmt/format.h>

#include <algorithm>

#include "dissection_recursion.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"

namespace meshpde {

namespace {

// From this many vertices in the two top-level halves they are ordered on two threads.
constexpr std::size_t kParallelHalves = 4000;

// Bisection by the plane through the median vertex along the longest side of the
// part's bounding box (driven by detail::dissect).
struct Dissection {
  const Mesh& mesh;
  const NestedDissectionParams& params;
  std::vector<int> out;
  std::vector<double> coordinate;  // scratch for the median

  Dissection sibling() const { return {mesh, params, {}, {}}; }
  void leaf(const std::vector<int>& part) { out.insert(out.end(), part.begin(), part.end()); }

  bool split(const std::vector<int>& part, std::vector<int>& lower, std::vector<int>& upper,
             std::vector<int>& separator) {
    const auto& V = mesh.positions();
    Eigen::Vector3d lo = V.row(part[0]).transpose(), hi = lo;
    for (int v : part) {
      lo = lo.cwiseMin(V.row(v).transpose());
      hi = hi.cwiseMax(V.row(v).transpose());
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    coordinate.resize(part.size());
    for (std::size_t k = 0; k < part.size(); ++k) coordinate[k] = V(part[k], axis);
    const auto mid = coordinate.begin() + static_cast<std::ptrdiff_t>(part.size() / 2);
    std::nth_element(coordinate.begin(), mid, coordinate.end());
    const double cut = *mid;
    // Sides are defined for every mesh vertex (held ones too: K D K couples two free
    // vertices through a held neighbour). A vertex joins the separator if a neighbour
    // lies across the cut: from the lower side only for one hop, from both for two.
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    for (int v : part) {
      const bool below = V(v, axis) < cut;
      bool across = false;
      if (below || params.separator_hops == 2)
        for (int q = off[v]; q < off[v + 1] && !across; ++q) across = (V(nbr[q], axis) < cut) != below;
      (across ? separator : below ? lower : upper).push_back(v);
    }
    return !lower.empty() && !upper.empty();  // else no cut splits it (a tiny or degenerate part)
  }
};

}  // namespace

NestedDissection nested_dissection(const Mesh& mesh, const std::vector<int>& vertices,
                                   const NestedDissectionParams& params) {
  detail::check_dissection_input(mesh, vertices, params.separator_hops, params.leaf_size, "nested dissection");
  Dissection d{mesh, params, {}, {}};
  // On a 10k drag region the halves on two threads took the ordering from about 1.6
  // to 0.9 ms.
  return detail::dissect_all(d, vertices, params.leaf_size, kParallelHalves);
}

std::vector<int> nested_dissection_order(const Mesh& mesh, const std::vector<int>& vertices,
                                         const NestedDissectionParams& params) {
  return nested_dissection(mesh, vertices, params).order;
}

NestedDissection reuse_ordering(const NestedDissection& previous, const std::vector<int>& vertices, int num_vertices,
                                int* changed) {
  // Per mesh vertex: bit 1 in `vertices`, bit 2 in previous.order.
  std::vector<unsigned char> in(static_cast<std::size_t>(std::max(0, num_vertices)), 0);
  auto mark = [&](const std::vector<int>& list, unsigned char bit, const char* which) {
    for (int v : list) {
      if (v < 0 || v >= num_vertices)
        throw InputError(fmt::format("reuse ordering: vertex {} of the {} does not exist (the mesh has {})", v, which,
                                     num_vertices));
      if (in[static_cast<std::size_t>(v)] & bit)
        throw InputError(fmt::format("reuse ordering: vertex {} is listed twice in the {}", v, which));
      in[static_cast<std::size_t>(v)] |= bit;
    }
  };
  mark(vertices, 1, "new vertex set");
  mark(previous.order, 2, "previous order");
  NestedDissection out;
  out.order.reserve(vertices.size());
  const bool split = previous.parts[0] > 0 && previous.parts[1] > 0;
  std::size_t dropped = 0, kept_in[2] = {0, 0};
  for (std::size_t k = 0; k < previous.order.size(); ++k) {
    const int v = previous.order[k];
    if (!(in[static_cast<std::size_t>(v)] & 1)) {
      ++dropped;
      continue;
    }
    out.order.push_back(v);
    if (split && k < previous.parts[0] + previous.parts[1]) ++kept_in[k < previous.parts[0] ? 0 : 1];
  }
  std::size_t added = 0;
  for (int v : vertices)
    if (!(in[static_cast<std::size_t>(v)] & 2)) {
      out.order.push_back(v);
      ++added;
    }
  if (split && kept_in[0] > 0 && kept_in[1] > 0 && kept_in[0] + kept_in[1] < out.order.size()) {
    out.parts[0] = kept_in[0];
    out.parts[1] = kept_in[1];
  } else {
    out.parts[0] = out.order.size();  // not split (as nested_dissection says it)
  }
  if (changed) *changed = static_cast<int>(added + dropped);
  return out;
}

}  // namespace meshpde
