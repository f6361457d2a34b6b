// Triangle mesh: positions, triangles and the derived connectivity that every
// operator reads.
//
// Plain data in and out: V is #V x 3 doubles (row-major, so a vertex's x, y, z are
// contiguous, as in numpy's default layout), F is #F x 3 zero-based vertex indices.
// Units are whatever the caller's coordinates are in (millimetres for medical data).
//
// Connectivity is stored in compressed-row (CSR) form and kept for the lifetime of
// the mesh. Nothing is rejected for being non-manifold: an edge may have any number
// of incident triangles, a vertex any number of fans, and boundaries are fine.
// Triangles with a repeated index contribute no edge between the repeated corners.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross(): declared by Core, defined here; needed by every geometry user
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

namespace meshpde {

using Positions = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Triangles = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Edges = Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// The triangles around each vertex, in compressed rows: those of vertex v are
/// faces[offsets[v] .. offsets[v + 1]), in increasing index.
struct VertexFaces {
  std::vector<int> offsets;  ///< #V + 1
  std::vector<int> faces;
};

class Mesh {
 public:
  Mesh() = default;

  /// Builds connectivity for (V, F).
  /// \throw InputError if an index is out of [0, #V) or a coordinate is not finite;
  ///        the message names the face or vertex.
  Mesh(Positions V, Triangles F);

  const Positions& positions() const { return V_; }
  const Triangles& triangles() const { return F_; }
  int num_vertices() const { return static_cast<int>(V_.rows()); }
  int num_faces() const { return static_cast<int>(F_.rows()); }
  int num_edges() const { return static_cast<int>(E_.rows()); }

  /// Moves the vertices; connectivity is unchanged. Operators that depend on the
  /// geometry must be rebuilt by the caller (see operators/fem_operators.h).
  /// \throw InputError on a size mismatch or a non-finite coordinate.
  void set_positions(const Positions& V);

  /// Unique undirected edges, E(e, 0) < E(e, 1), sorted lexicographically.
  const Edges& edges() const { return E_; }

  /// Vertex-to-vertex adjacency in CSR form: the neighbours of vertex i are
  /// neighbors()[offsets()[i] .. offsets()[i+1]), sorted ascending, and
  /// edge_ids() gives, for the same slot, the id of the edge (i, j).
  std::span<const int> offsets() const { return adj_offset_; }
  std::span<const int> neighbors() const { return adj_vertex_; }
  std::span<const int> edge_ids() const { return adj_edge_; }
  std::span<const int> neighbors(int i) const {
    return {adj_vertex_.data() + adj_offset_[i], adj_vertex_.data() + adj_offset_[i + 1]};
  }
  int degree(int i) const { return adj_offset_[i + 1] - adj_offset_[i]; }

  /// CSR slot of neighbour j in row i, or -1 if (i, j) is not an edge. O(log degree).
  int find_slot(int i, int j) const;

  /// Bytes held by the adjacency arrays (offsets, neighbours, edge ids) and edges.
  std::size_t connectivity_bytes() const;

  /// The triangles around each vertex: built by the first call (one pass over the
  /// triangles; thread-safe) and kept, shared by copies of this mesh.
  const VertexFaces& vertex_faces() const;

 private:
  struct LazyFaces {
    std::once_flag once;
    VertexFaces lists;
  };
  Positions V_;
  Triangles F_;
  Edges E_;
  std::vector<int> adj_offset_;
  std::vector<int> adj_vertex_;
  std::vector<int> adj_edge_;
  std::shared_ptr<LazyFaces> faces_ = std::make_shared<LazyFaces>();
};

}  // namespace meshpde
