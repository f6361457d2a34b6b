// pde/active_domain.h: the free set, its ring and border kept incrementally, against a
// recount from the states after every change.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <vector>

#include "meshpde/mesh/generators.h"
#include "meshpde/pde/active_domain.h"
#include "test_support.h"

using namespace meshpde;

TEST(ActiveDomain, ThousandRandomChangesKeepTheFreeSetRingAndBorderExact) {
  const Mesh mesh = test::make(icosphere(2));
  const int n = mesh.num_vertices();
  ActiveDomain d(mesh);
  std::vector<VertexState> want(static_cast<std::size_t>(n), VertexState::Frozen);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> vertex(0, n - 1), op(0, 2);
  for (int step = 0; step < 1000; ++step) {
    const int v = vertex(rng);
    const VertexState before = want[static_cast<std::size_t>(v)];
    bool changed = false;
    switch (op(rng)) {
      case 0:
        changed = d.make_free(v);
        want[static_cast<std::size_t>(v)] = VertexState::Free;
        break;
      case 1:
        changed = d.make_frozen(v);
        want[static_cast<std::size_t>(v)] = VertexState::Frozen;
        break;
      default:
        changed = d.make_constrained(v);
        want[static_cast<std::size_t>(v)] = VertexState::Constrained;
    }
    ASSERT_EQ(changed, before != want[static_cast<std::size_t>(v)]) << "step " << step;
    // Recount everything from the states.
    std::set<int> free, ring;
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(d.state(i), want[static_cast<std::size_t>(i)]) << "step " << step << ", vertex " << i;
      const bool is_free = want[static_cast<std::size_t>(i)] == VertexState::Free;
      bool free_neighbour = false, frozen_neighbour = false;
      for (int j : mesh.neighbors(i)) {
        free_neighbour |= want[static_cast<std::size_t>(j)] == VertexState::Free;
        frozen_neighbour |= want[static_cast<std::size_t>(j)] == VertexState::Frozen;
      }
      if (is_free) free.insert(i);
      if (!is_free && free_neighbour) ring.insert(i);
      ASSERT_EQ(d.on_border(i), is_free && frozen_neighbour) << "step " << step << ", vertex " << i;
    }
    const auto A = d.free_vertices();
    ASSERT_EQ(std::set<int>(A.begin(), A.end()), free) << "step " << step;
    ASSERT_EQ(static_cast<std::size_t>(d.num_free()), free.size());
    for (std::size_t k = 0; k < A.size(); ++k) ASSERT_EQ(d.free_index(A[k]), static_cast<int>(k));
    const auto R = d.ring();
    ASSERT_EQ(std::set<int>(R.begin(), R.end()), ring) << "step " << step;
    ASSERT_EQ(R.size(), ring.size()) << "a ring vertex listed twice at step " << step;
  }
}
