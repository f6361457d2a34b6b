// The recursion of both nested dissections (solvers/ordering.h): a part is a leaf, or
// it splits into two halves and the separator between them; the halves are ordered
// first (each the same way), the separator last, and the top level's halves at the
// same time on two threads, each into its own output, so that the order is the same
// as one after the other. Internal to the solver layer.
#pragma once

#include <fmt/format.h>

#include <cstddef>
#include <utility>
#include <vector>

#include "../core/index_map.h"
#include "../core/two_threads.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/solvers/ordering.h"

namespace meshpde::detail {

/// The checks both dissections make of their input, `what` naming the caller in the
/// message. \throw InputError for separator_hops not 1 or 2, leaf_size < 1, a vertex
/// that does not exist or one listed twice.
inline void check_dissection_input(const Mesh& mesh, const std::vector<int>& vertices, int separator_hops,
                                   int leaf_size, const char* what) {
  if (separator_hops != 1 && separator_hops != 2)
    throw InputError(fmt::format("{}: separator_hops is {}; it must be 1 (K) or 2 (K D K)", what, separator_hops));
  if (leaf_size < 1) throw InputError(fmt::format("{}: leaf_size is {}; it must be at least 1", what, leaf_size));
  IndexMap seen(vertices.size());
  for (int v : vertices) {
    if (v < 0 || v >= mesh.num_vertices())
      throw InputError(
          fmt::format("{}: vertex {} does not exist (the mesh has {} vertices)", what, v, mesh.num_vertices()));
    if (!seen.insert(v).second) throw InputError(fmt::format("{}: vertex {} is listed twice", what, v));
  }
}

/// D provides: `std::vector<int> out` (the order so far), `bool split(part, lower,
/// upper, separator)` (false: the part does not split), `void leaf(part)` (appends a
/// part that is not split) and `D sibling()` (an empty dissection with the same
/// input, for the second thread). `sizes`, when given (the top level), gets the two
/// halves' sizes (0, 0 when the part is not split); from `parallel_from` vertices in
/// the two halves they are ordered on two threads.
template <class D>
void dissect(D& d, std::vector<int> part, int leaf_size, std::size_t parallel_from, std::size_t* sizes = nullptr) {
  std::vector<int> lower, upper, separator;
  if (static_cast<int>(part.size()) <= leaf_size || !d.split(part, lower, upper, separator)) {
    d.leaf(part);
    return;
  }
  part = {};  // free it before recursing
  if (sizes) {
    sizes[0] = lower.size();
    sizes[1] = upper.size();
  }
  if (sizes && max_threads() > 1 && lower.size() + upper.size() >= parallel_from) {
    D second = d.sibling();
    run_both([&] { dissect(d, std::move(lower), leaf_size, parallel_from); },
             [&] { dissect(second, std::move(upper), leaf_size, parallel_from); });
    d.out.insert(d.out.end(), second.out.begin(), second.out.end());
  } else {
    dissect(d, std::move(lower), leaf_size, parallel_from);
    dissect(d, std::move(upper), leaf_size, parallel_from);
  }
  d.out.insert(d.out.end(), separator.begin(), separator.end());
}

/// The whole order of `vertices` with its top level (NestedDissection: parts =
/// {#vertices, 0} when the set is not split).
template <class D>
NestedDissection dissect_all(D& d, const std::vector<int>& vertices, int leaf_size, std::size_t parallel_from) {
  d.out.reserve(vertices.size());
  NestedDissection result;
  dissect(d, vertices, leaf_size, parallel_from, result.parts);
  if (result.parts[0] == 0 && result.parts[1] == 0) result.parts[0] = vertices.size();  // not split
  result.order = std::move(d.out);
  return result;
}

}  // namespace meshpde::detail
