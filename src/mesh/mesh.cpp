#include "meshpde/mesh/mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

void check_finite(const Positions& V) {
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(V(i, c)))
        throw InputError(
            fmt::format("vertex {} has a non-finite coordinate ({}, {}, {})", i, V(i, 0), V(i, 1), V(i, 2)));
}

}  // namespace

Mesh::Mesh(Positions V, Triangles F) : V_(std::move(V)), F_(std::move(F)) {
  check_finite(V_);
  const int nv = num_vertices();
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    for (int c = 0; c < 3; ++c)
      if (F_(f, c) < 0 || F_(f, c) >= nv)
        throw InputError(fmt::format("face {} has vertex index {} outside [0, {})", f, F_(f, c), nv));

  // Count candidate neighbours per vertex (with repeats), fill, then sort and
  // deduplicate each row. This is O(#F log degree) and needs no global sort.
  std::vector<int> count(nv + 1, 0);
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = F_(f, c), b = F_(f, (c + 1) % 3);
      if (a == b) continue;
      ++count[a + 1];
      ++count[b + 1];
    }
  for (int i = 0; i < nv; ++i) count[i + 1] += count[i];
  std::vector<int> raw(count[nv]);
  std::vector<int> fill(count.begin(), count.end() - 1);
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = F_(f, c), b = F_(f, (c + 1) % 3);
      if (a == b) continue;
      raw[fill[a]++] = b;
      raw[fill[b]++] = a;
    }
  adj_offset_.assign(nv + 1, 0);
  adj_vertex_.clear();
  adj_vertex_.reserve(raw.size() / 2 + 1);
  for (int i = 0; i < nv; ++i) {
    auto first = raw.begin() + count[i], last = raw.begin() + count[i + 1];
    std::sort(first, last);
    last = std::unique(first, last);
    adj_vertex_.insert(adj_vertex_.end(), first, last);
    adj_offset_[i + 1] = static_cast<int>(adj_vertex_.size());
  }
  // Edges (i < j) are numbered in row order, so each row's upper part is contiguous.
  adj_edge_.assign(adj_vertex_.size(), -1);
  int ne = 0;
  for (int i = 0; i < nv; ++i)
    for (int s = adj_offset_[i]; s < adj_offset_[i + 1]; ++s)
      if (adj_vertex_[s] > i) adj_edge_[s] = ne++;
  E_.resize(ne, 2);
  for (int i = 0; i < nv; ++i)
    for (int s = adj_offset_[i]; s < adj_offset_[i + 1]; ++s) {
      const int j = adj_vertex_[s];
      if (j > i) {
        E_(adj_edge_[s], 0) = i;
        E_(adj_edge_[s], 1) = j;
      } else {
        adj_edge_[s] = adj_edge_[find_slot(j, i)];
      }
    }
}

void Mesh::set_positions(const Positions& V) {
  if (V.rows() != V_.rows())
    throw InputError(fmt::format("set_positions: expected {} vertices, got {}", V_.rows(), V.rows()));
  check_finite(V);
  V_ = V;
}

int Mesh::find_slot(int i, int j) const {
  const auto first = adj_vertex_.begin() + adj_offset_[i];
  const auto last = adj_vertex_.begin() + adj_offset_[i + 1];
  const auto it = std::lower_bound(first, last, j);
  return (it != last && *it == j) ? static_cast<int>(it - adj_vertex_.begin()) : -1;
}

std::size_t Mesh::connectivity_bytes() const {
  return sizeof(int) *
         (adj_offset_.size() + adj_vertex_.size() + adj_edge_.size() + static_cast<std::size_t>(E_.size()));
}

const VertexFaces& Mesh::vertex_faces() const {
  std::call_once(faces_->once, [&] {
    VertexFaces& out = faces_->lists;
    out.offsets.assign(static_cast<std::size_t>(num_vertices()) + 1, 0);
    for (int f = 0; f < num_faces(); ++f)
      for (int k = 0; k < 3; ++k) ++out.offsets[static_cast<std::size_t>(F_(f, k)) + 1];
    for (std::size_t v = 0; v + 1 < out.offsets.size(); ++v) out.offsets[v + 1] += out.offsets[v];
    out.faces.resize(static_cast<std::size_t>(out.offsets.back()));
    std::vector<int> next(out.offsets.begin(), out.offsets.end() - 1);
    for (int f = 0; f < num_faces(); ++f)
      for (int k = 0; k < 3; ++k) out.faces[static_cast<std::size_t>(next[static_cast<std::size_t>(F_(f, k))]++)] = f;
  });
  return faces_->lists;
}

}  // namespace meshpde
