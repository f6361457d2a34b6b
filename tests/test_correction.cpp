// The correction on generated vessels: handles land exactly and the outside stays, a
// region below one edge, bad requests, meshes in other units.
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

TEST(Vessel, SeveralHandlesLandExactlyAndTheOutsideStays) {
  const Mesh m = tube_at(48);
  CorrectionParams p;
  const int a = nearest_vertex(m, {5, 0, 20}), b = nearest_vertex(m, {-5, 0, 40});
  p.handles = {{a, {-1, 0, 0}}, {b, {1.5, 0, 0.5}}};
  p.radius = 8;
  const CorrectionResult r = correct_vessel(m, p);
  EXPECT_LT((r.displacement.row(a) - Eigen::RowVector3d(-1, 0, 0)).norm(), 1e-12);
  EXPECT_LT((r.displacement.row(b) - Eigen::RowVector3d(1.5, 0, 0.5)).norm(), 1e-12);
  std::vector<char> in(static_cast<std::size_t>(m.num_vertices()), 0);
  for (int v : r.region) in[static_cast<std::size_t>(v)] = 1;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (!in[static_cast<std::size_t>(v)]) {
      ASSERT_EQ(r.displacement.row(v).norm(), 0.0);
    }
  EXPECT_LE(r.relative_residual, 1e-10);
}

TEST(Vessel, ARadiusBelowOneEdgeMovesOnlyTheHandleWithEverySolver) {
  // Found by fuzzing the editor's requests: a region holding no free vertex gave the
  // direct solve an empty system, whose error measure read past it (a segfault).
  const Mesh m = make(icosphere(2, 10.0));
  for (const SteadySolver solver : {SteadySolver::Direct, SteadySolver::Global, SteadySolver::Iterative})
    for (const bool dynamic : {false, true}) {
      if (dynamic && solver != SteadySolver::Direct) continue;
      CorrectionParams p;
      p.handles = {{6, Eigen::Vector3d(0, 0, 2)}};
      p.radius = 1.0;  // the edges are about 4.4 long
      p.solver = solver;
      // The clamp for every solver; the smooth boundary (direct only) too.
      p.boundary = solver == SteadySolver::Direct && !dynamic ? RegionBoundary::Smooth : RegionBoundary::Clamp;
      p.dynamic = dynamic;
      const CorrectionResult r = correct_vessel(m, p);
      EXPECT_EQ(r.moved_vertices, 1);
      EXPECT_EQ(r.V.row(6), m.positions().row(6) + Eigen::RowVector3d(0, 0, 2));
      EXPECT_EQ((r.V - m.positions()).rowwise().norm().maxCoeff(), 2.0);
      EXPECT_TRUE(r.V.allFinite());
      // And it says so, naming the radius against the edges.
      EXPECT_NE(r.region_warning.find("only the handles move"), std::string::npos) << r.region_warning;
      EXPECT_NE(r.region_warning.find("radius of 1 mm"), std::string::npos) << r.region_warning;
    }
  CorrectionParams wide;
  wide.handles = {{6, Eigen::Vector3d(0, 0, 2)}};
  wide.radius = 12;
  EXPECT_EQ(correct_vessel(m, wide).region_warning, "");
}

TEST(Vessel, BadRequestsAreRefusedClearly) {
  const Mesh m = tube_at(24);
  CorrectionParams p;
  EXPECT_THROW(correct_vessel(m, p), InputError);  // no handle
  p.handles = {{m.num_vertices(), {0, 0, 1}}};
  p.radius = 5;
  EXPECT_THROW(correct_vessel(m, p), InputError);
  p.handles = {{0, {0, 0, 1}}};
  p.radius = 0;
  EXPECT_THROW(correct_vessel(m, p), InputError);  // no region
  p.radius = 5;
  p.tissue.viscosity = 2;
  EXPECT_THROW(correct_vessel(m, p), InputError);
  EXPECT_THROW(parse_correction_method("magic"), InputError);
}

TEST(Vessel, AMeshInCentimetresOrMetresGivesTheMillimetreCorrection) {
  // The same tube in mm, cm and m, the same request in mm (a 1 mm push, 8 mm region):
  // the displacement comes back in the mesh's unit and equals the mm one scaled, the
  // dynamic mode and the springs included; read as mm, the cm tube's 8 mm region
  // would hold ten times more of the tube.
  const Mesh mm = tube_at(48);
  const int a = nearest_vertex(mm, {5, 0, 30});
  for (const CorrectionMethod method : {CorrectionMethod::Fem, CorrectionMethod::Springs})
    for (const bool dynamic : {false, true}) {
      if (method == CorrectionMethod::Springs && dynamic) continue;
      CorrectionParams p;
      p.handles = {{a, {-1, 0, 0.5}}};
      p.method = method;
      p.dynamic = dynamic;
      if (method == CorrectionMethod::Springs)
        p.rings = 4;
      else
        p.radius = 8;
      const CorrectionResult ref = correct_vessel(mm, p);
      for (const LengthUnit u : {LengthUnit::Centimetre, LengthUnit::Metre}) {
        SCOPED_TRACE(fmt::format("{} dynamic {} {}", method == CorrectionMethod::Fem ? "fem" : "springs", dynamic,
                                 to_string(u)));
        const double s = millimetres_per(u);
        const Mesh scaled(mm.positions() / s, mm.triangles());
        CorrectionParams q = p;
        q.units = u;
        const CorrectionResult r = correct_vessel(scaled, q);
        // The same vertices (their order may differ where two distances tie to rounding).
        auto sorted = [](std::vector<int> v) {
          std::sort(v.begin(), v.end());
          return v;
        };
        EXPECT_EQ(sorted(r.region), sorted(ref.region));
        EXPECT_LT((r.displacement * s - ref.displacement).cwiseAbs().maxCoeff(), 1e-9);
        EXPECT_EQ(r.V, scaled.positions() + r.displacement);
        EXPECT_NEAR(r.max_displacement, ref.max_displacement, 1e-9);  // reported in mm
        EXPECT_EQ(r.moved_vertices, ref.moved_vertices);
      }
    }
  // Taken for mm, the cm tube (0.5 mm radius) is all inside an 8 mm region.
  CorrectionParams wrong;
  wrong.handles = {{a, {-0.1, 0, 0}}};
  wrong.radius = 8;
  const Mesh cm(mm.positions() / 10, mm.triangles());
  EXPECT_GT(correct_vessel(cm, wrong).region.size(), 3 * correct_vessel(mm, wrong).region.size());
}

TEST(Vessel, UnitsThatMakeAnImplausibleVesselAreNamed) {
  const Mesh mm = tube_at(48);  // 5 mm radius, 60 mm long: plausible in mm
  EXPECT_FALSE(check_units(mm, LengthUnit::Millimetre).implausible);
  EXPECT_EQ(units_warning(mm, LengthUnit::Millimetre, "tube.vtp"), "");
  // Read in metres it is 60 m long: mm is suggested.
  const UnitsCheck as_m = check_units(mm, LengthUnit::Metre);
  EXPECT_TRUE(as_m.implausible);
  ASSERT_TRUE(as_m.suggested.has_value());
  EXPECT_EQ(*as_m.suggested, LengthUnit::Millimetre);
  // The same tube written in cm (6 units long), read as mm: cm is suggested.
  const Mesh cm(mm.positions() / 10, mm.triangles());
  const UnitsCheck c = check_units(cm, LengthUnit::Millimetre);
  EXPECT_TRUE(c.implausible);
  EXPECT_NEAR(c.diagonal_mm, check_units(mm, LengthUnit::Millimetre).diagonal_mm / 10, 1e-9);
  ASSERT_TRUE(c.suggested.has_value());
  EXPECT_EQ(*c.suggested, LengthUnit::Centimetre);
  const std::string w = units_warning(cm, LengthUnit::Millimetre, "tube.vtp", "--units ");
  EXPECT_NE(w.find("tube.vtp"), std::string::npos) << w;
  EXPECT_NE(w.find("--units cm"), std::string::npos) << w;
  // The library names no front end's option unless given one.
  const std::string plain = units_warning(cm, LengthUnit::Millimetre, "tube.vtp");
  EXPECT_EQ(plain.find("--"), std::string::npos) << plain;
  EXPECT_NE(plain.find("may be in cm"), std::string::npos) << plain;
  EXPECT_FALSE(check_units(cm, LengthUnit::Centimetre).implausible);
  EXPECT_EQ(parse_length_unit("CM"), LengthUnit::Centimetre);
  EXPECT_THROW(parse_length_unit("inch"), InputError);
}
