// CorrectionSession: undo, redo, the intersection count, a restored history.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "correction_support.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;
using namespace meshpde::test;

TEST(Vessel, SessionUndoRedoAndIntersectionCount) {
  const Mesh m = tube_at(32);
  CorrectionSession s(m);
  EXPECT_FALSE(s.can_undo());
  EXPECT_THROW(s.undo(), InputError);
  const CorrectionResult r1 = s.apply(drag_to(m, {5, 0, 30}, {-1, 0, 0}, 8.0));
  const CorrectionResult r2 = s.apply(drag_to(s.mesh(), {0, 5, 20}, {0, -1, 0}, 8.0));
  EXPECT_EQ(s.mesh().positions(), r2.V);
  s.undo();
  EXPECT_EQ(s.mesh().positions(), r1.V);
  s.undo();
  EXPECT_EQ(s.mesh().positions(), m.positions());
  EXPECT_FALSE(s.can_undo());
  s.redo();
  EXPECT_EQ(s.mesh().positions(), r1.V);
  // A new correction after an undo drops the redo history.
  s.apply(drag_to(s.mesh(), {-5, 0, 40}, {1, 0, 0}, 8.0));
  EXPECT_FALSE(s.can_redo());
  EXPECT_EQ(s.new_self_intersections(), 0);
}

// A saved history put back (the editor's session files): the same positions, undo and
// redo, and self-intersection count; a history that does not belong to the mesh is
// refused and leaves the session as it was.
TEST(Vessel, ARestoredHistoryUndoesAndRedoesAsTheOriginal) {
  const Mesh m = tube_at(32);
  CorrectionSession s(m);
  const CorrectionResult r1 = s.apply(drag_to(m, {5, 0, 30}, {-1, 0, 0}, 8.0));
  s.apply(drag_to(s.mesh(), {0, 5, 20}, {0, -1, 0}, 8.0));
  s.apply(drag_to(s.mesh(), {-5, 0, 40}, {1, 0, 0}, 8.0));
  s.undo();
  s.undo();
  ASSERT_EQ(s.current(), 1u);
  CorrectionSession back(m);
  back.restore(s.history(), s.current());
  EXPECT_EQ(back.mesh().positions(), r1.V);
  EXPECT_TRUE(back.can_undo());
  EXPECT_TRUE(back.can_redo());
  EXPECT_EQ(back.new_self_intersections(), s.new_self_intersections());
  back.redo();
  back.redo();
  EXPECT_EQ(back.mesh().positions(), s.history().back());
  EXPECT_FALSE(back.can_redo());
  // Corrections go on from the restored state as from the original.
  back.undo();
  s.redo();
  EXPECT_EQ(back.apply(drag_to(back.mesh(), {0, -5, 25}, {0, 1, 0}, 8.0)).V,
            s.apply(drag_to(s.mesh(), {0, -5, 25}, {0, 1, 0}, 8.0)).V);
  // Refused: another mesh's original, a step out of range, a short step, a NaN.
  CorrectionSession fresh(m);
  std::vector<Positions> h = s.history();
  EXPECT_THROW(fresh.restore(h, h.size()), InputError);
  h[0](3, 1) += 1e-9;
  EXPECT_THROW(fresh.restore(h, 1), InputError);
  h = s.history();
  h[1] = Positions(h[1].topRows(10));  // (a copy: the block reads the matrix being resized)
  EXPECT_THROW(fresh.restore(h, 1), InputError);
  h = s.history();
  h[1](0, 0) = NAN;
  EXPECT_THROW(fresh.restore(h, 1), InputError);
  EXPECT_EQ(fresh.mesh().positions(), m.positions());
  EXPECT_FALSE(fresh.can_undo());
}
