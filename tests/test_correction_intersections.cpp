// Corrections that would make the wall intersect itself: the guard's steps, a drag at
// the carina.
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

// The guard's continuation applies at least what limiting the one-shot field applies
// (max_substeps = 1: no smaller step may be taken), and both leave no new pair.
TEST(Vessel, TheGuardsStepsApplyAtLeastTheLimitedOneShotField) {
  const Mesh m = make(y_bifurcation(BifurcationParams{}));
  const int v = carina(m);
  ASSERT_GE(v, 0);
  CorrectionParams p;
  p.handles = {{v, Eigen::Vector3d(8, 0, 0)}};
  p.radius = 10;
  const CorrectionResult steps = correct_vessel(m, p);
  p.max_substeps = 1;
  const CorrectionResult one = correct_vessel(m, p);
  EXPECT_NE(one.intersection_action.find("limited"), std::string::npos) << one.intersection_action;
  EXPECT_EQ(one.substeps, 1);
  EXPECT_GT(one.applied_fraction, 0.5);
  EXPECT_GE(steps.applied_fraction, one.applied_fraction - 1e-12);
  for (const CorrectionResult* r : {&steps, &one}) {
    EXPECT_EQ(r->new_self_intersections, 0);
    Mesh after = m;
    after.set_positions(r->V);
    EXPECT_TRUE(SelfIntersectionChecker(after).all_pairs().empty());
    // The handle moved by the fraction applied.
    EXPECT_NEAR((r->V.row(v) - m.positions().row(v)).norm(), r->applied_fraction * 8.0, 1e-9 * 8.0);
  }
  std::printf("guard: steps applied %.3f (%s), one-shot limited %.3f\n", steps.applied_fraction,
              steps.intersection_action.c_str(), one.applied_fraction);
}

TEST(Vessel, CarinaDragFarCreatesNoIntersections) {
  BifurcationParams bp;
  const Mesh m = make(y_bifurcation(bp));
  const int v = carina(m);
  ASSERT_GE(v, 0);
  for (const Eigen::Vector3d& d : {Eigen::Vector3d(8, 0, 0), Eigen::Vector3d(0, 0, -9), Eigen::Vector3d(0, 8, 0)}) {
    SCOPED_TRACE(d.transpose());
    for (const RegionBoundary boundary : {RegionBoundary::Clamp, RegionBoundary::Smooth}) {
      SCOPED_TRACE(to_string(boundary));
      CorrectionParams p;
      p.handles = {{v, d}};
      p.radius = 10;
      p.boundary = boundary;
      const CorrectionResult r = correct_vessel(m, p);
      EXPECT_EQ(r.new_self_intersections, 0);
      // Whatever was done is reported, and what was applied is real.
      EXPECT_NEAR((r.V.row(v) - m.positions().row(v)).norm(), r.applied_fraction * d.norm(), 1e-9 * d.norm());
      if (r.applied_fraction < 1) {
        EXPECT_NE(r.intersection_action.find("limited"), std::string::npos);
      }
      // The smooth boundary's foundation keeps the drag within about 0.75 R, so a drag this
      // far bends the wall more steeply there and less of it fits.
      EXPECT_GT(r.applied_fraction, boundary == RegionBoundary::Clamp ? 0.8 : 0.75);
      // An independent whole-mesh check of the result agrees.
      Mesh after = m;
      after.set_positions(r.V);
      EXPECT_TRUE(SelfIntersectionChecker(after).all_pairs().empty());
      // The thesis method on the same drag folds the wall through itself.
      CorrectionParams s = p;
      s.method = CorrectionMethod::Springs;
      s.radius = 0;
      s.rings = 10;
      EXPECT_GT(correct_vessel(m, s).new_self_intersections, 0);
    }
  }
}
