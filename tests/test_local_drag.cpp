// apps/local_drag.h: drag_vertex, the one-off drag (DragSession: test_drag_session.cpp).
#include <gtest/gtest.h>

#include <vector>

#include "meshpde/apps/local_drag.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;
using test::make;

TEST(LocalDrag, MovesTheHandleAndStaysInsideTheRegion) {
  const Mesh m = make(y_bifurcation(BifurcationParams{.cell = 1.0, .dent = true}));
  const FemOperators ops = build_cotan_operators(m);
  const DragResult r = drag_vertex(m, ops, DragParams{.vertex = 5, .displacement = {0.5, 0, 0}, .radius = 5.0});
  ASSERT_TRUE(r.cg.converged()) << r.cg.message;
  EXPECT_NEAR((r.V.row(5) - m.positions().row(5)).norm(), 0.5, 1e-12);
  std::vector<char> in(m.num_vertices(), 0);
  for (int v : r.region) in[v] = 1;
  in[5] = 1;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (!in[v]) {
      ASSERT_EQ(r.displacement.row(v).norm(), 0.0);
    }
  EXPECT_GT(r.moved_vertices, 20);
  // Smooth decay: displacement is largest at the handle.
  EXPECT_LE(r.displacement.rowwise().norm().maxCoeff(), 0.5 * (1 + 1e-9) + 0.05);
}
