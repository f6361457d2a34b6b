// The active domain of a localized solve (Kim and Rossignac 2004 section 4.2).
//
// Every vertex is Free (in A, solved), Constrained (prescribed value) or Frozen
// (held at its current value). The domain keeps the free list A and the ring
// A+1 \ A (non-free vertices adjacent to A) incrementally: adding or removing a
// vertex costs O(its degree), never O(#V). Per-vertex bookkeeping arrays are
// allocated once, when the domain is created.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

enum class VertexState : std::uint8_t { Frozen = 0, Free = 1, Constrained = 2 };

class ActiveDomain {
 public:
  explicit ActiveDomain(const Mesh& mesh);

  VertexState state(int v) const { return static_cast<VertexState>(state_[v]); }
  /// A: the free vertices, in an order that changes as vertices come and go.
  std::span<const int> free_vertices() const { return free_; }
  /// A+1 \ A: frozen or constrained vertices with at least one free neighbour.
  std::span<const int> ring() const { return ring_; }
  /// Position of v in free_vertices(), or -1.
  int free_index(int v) const { return free_pos_[v]; }
  /// True for a free vertex with at least one frozen neighbour.
  bool on_border(int v) const;

  /// Frozen or constrained -> free. Returns false if v was already free.
  bool make_free(int v);
  /// Free or constrained -> frozen. Returns false if v was already frozen.
  bool make_frozen(int v);
  /// Any -> constrained. Returns false if v was already constrained.
  bool make_constrained(int v);

  int num_free() const { return static_cast<int>(free_.size()); }

 private:
  void leave_free(int v);
  void ring_insert(int v);
  void ring_erase(int v);

  const Mesh* mesh_;
  std::vector<std::uint8_t> state_;
  std::vector<int> free_, free_pos_;
  std::vector<int> ring_, ring_pos_;
  std::vector<int> free_neighbors_;  ///< count of free neighbours per vertex
};

}  // namespace meshpde
