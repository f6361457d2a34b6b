// Internal: the check that every connected part of a free set touches a held vertex.
//
// Without a g0 (foundation) term, the values on a part of the free set that no held
// vertex touches are undetermined (constants cost no energy there): its system is
// singular, and a factorization or a multigrid would fail with a message that names
// nothing. Both steady solvers run this first and name a vertex of the part instead.
#pragma once

#include <fmt/format.h>

#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/mesh.h"

namespace meshpde::detail {

/// Parts are connected through mesh edges between free vertices. `local_index(v)` is
/// v's index in `free`, or -1 for a held vertex; `anchored(v)` says whether a free
/// vertex holds its part by itself (a positive diagonal term). Cost O(#free).
/// \throw SolverError naming the part's size and one of its vertices.
template <class LocalIndex, class Anchored>
void require_held_parts(const Mesh& mesh, const std::vector<int>& free, LocalIndex&& local_index, Anchored&& anchored) {
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  const int n = static_cast<int>(free.size());
  std::vector<char> seen(static_cast<std::size_t>(n), 0);
  std::vector<int> stack, members;
  for (int s = 0; s < n; ++s) {
    if (seen[static_cast<std::size_t>(s)]) continue;
    stack.assign(1, s);
    members.clear();
    seen[static_cast<std::size_t>(s)] = 1;
    bool held = false;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      const int v = free[static_cast<std::size_t>(k)];
      members.push_back(v);
      if (anchored(v)) held = true;
      for (int t = off[v]; t < off[v + 1]; ++t) {
        const int j = local_index(nbr[t]);
        if (j < 0) {
          held = true;
        } else if (!seen[static_cast<std::size_t>(j)]) {
          seen[static_cast<std::size_t>(j)] = 1;
          stack.push_back(j);
        }
      }
    }
    if (!held)
      throw SolverError(
          fmt::format("a connected part of {} free vertices (vertex {} among them) touches no held "
                      "vertex: its values are undetermined; constrain a vertex there",
                      members.size(), members.front()));
  }
}

}  // namespace meshpde::detail
