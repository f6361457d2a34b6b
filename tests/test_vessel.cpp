// Vessel correction on generated vessels: resolution independence (and the thesis
// method failing it), no self-intersections at a carina, several handles, tissue
// stiffness, dynamics settling to the static answer, undo and redo.
#include <fmt/format.h>
#include <gtest/gtest.h>

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
using test::make;

namespace {

// The vertex nearest p.
int nearest_vertex(const Mesh& m, const Eigen::Vector3d& p) {
  int best = 0;
  (m.positions().rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&best);
  return best;
}

// Moves the wall point at `at` to `at + d`: the handle is the nearest vertex, and
// its displacement lands it exactly on the target, whatever the resolution.
CorrectionParams drag_to(const Mesh& m, const Eigen::Vector3d& at, const Eigen::Vector3d& d, double radius) {
  CorrectionParams p;
  const int v = nearest_vertex(m, at);
  p.handles = {{v, at + d - m.positions().row(v).transpose()}};
  p.radius = radius;
  return p;
}

// A tube of radius 5 mm and length 60 mm whose edges are about h long.
Mesh tube_at(int segments) {
  const double h = 2 * M_PI * 5 / segments;
  const int half = static_cast<int>(std::round(30 / h));
  return make(tube(5.0, 60.0, 2 * half + 1, segments));
}

// The vertices within `radius` of `centre`, and how much the displacement's length
// varies over them (a patch that bends less has a smaller spread).
std::vector<int> patch_near(const Mesh& m, const Eigen::Vector3d& centre, double radius) {
  std::vector<int> patch;
  for (int i = 0; i < m.num_vertices(); ++i)
    if ((m.positions().row(i).transpose() - centre).norm() < radius) patch.push_back(i);
  return patch;
}
double spread(const CorrectionResult& r, const std::vector<int>& patch) {
  double lo = 1e300, hi = -1e300;
  for (int i : patch) {
    lo = std::min(lo, r.displacement.row(i).norm());
    hi = std::max(hi, r.displacement.row(i).norm());
  }
  return hi - lo;
}

// The carina of the generated bifurcation: the lowest wall vertex between the branches.
int carina(const Mesh& m) {
  int best = -1;
  for (int i = 0; i < m.num_vertices(); ++i) {
    const auto p = m.positions().row(i);
    if (std::abs(p.x()) < 0.6 && std::abs(p.y()) < 0.6 && p.z() > 0 && (best < 0 || p.z() < m.positions()(best, 2)))
      best = i;
  }
  return best;
}

}  // namespace

TEST(Vessel, SameDragAtThreeResolutionsGivesTheSameSurface) {
  const Eigen::Vector3d at(5, 0, 30), d(-4, 0, 1);  // 4.1 mm inwards and along
  std::vector<Mesh> tubes = {tube_at(32), tube_at(64), tube_at(128)};
  std::vector<CorrectionResult> fem, thesis;
  for (const Mesh& m : tubes) {
    fem.push_back(correct_vessel(m, drag_to(m, at, d, 15.0)));
    CorrectionParams sp = drag_to(m, at, d, 0);
    sp.method = CorrectionMethod::Springs;
    sp.rings = 12;  // the thesis counts its level of influence in rings
    thesis.push_back(correct_vessel(m, sp));
  }
  const double limit = 0.02 * d.norm();
  for (std::size_t k = 1; k < tubes.size(); ++k) {
    const double h_fem = hausdorff_distance(fem[0].V, tubes[0].triangles(), fem[k].V, tubes[k].triangles());
    const double h_thesis = hausdorff_distance(thesis[0].V, tubes[0].triangles(), thesis[k].V, tubes[k].triangles());
    RecordProperty("hausdorff_fem_" + std::to_string(k), std::to_string(h_fem));
    std::printf("tube 32 vs %d segments: Hausdorff fem %.4f mm, thesis springs %.4f mm (limit %.4f)\n", 32 << k, h_fem,
                h_thesis, limit);
    EXPECT_LE(h_fem, limit);
    EXPECT_GT(h_thesis, limit);  // the thesis's open problem, reproduced
  }
}

// The fade boundary (RegionBoundary::Fade) on a tube and its 1-to-4 subdivision (the
// coarse vertices kept, in place): the displacement at the coarse vertices changes
// much less from one resolution to the other than with the clamp; the handle lands
// where it is sent; nothing beyond twice the radius moves, and little beyond 1.2 R.
TEST(Vessel, FadeBoundaryAgreesAcrossResolutionsBetterThanTheClamp) {
  const GeneratedMesh g = tube(5.0, 100.0, 88, 32);
  const GeneratedMesh g1 = subdivide_midpoint(g.V, g.F);
  const Mesh coarse = make(g), fine = make(g1);
  const int v = nearest_vertex(coarse, Eigen::Vector3d(5, 0, 50));
  const Eigen::Vector3d normal =
      coarse.positions().row(v).transpose().cwiseProduct(Eigen::Vector3d(1, 1, 0)).normalized();
  const Eigen::Vector3d drag = -3.0 * normal;  // 3 mm inwards
  const double h = mean_edge_length(coarse);
  const int n0 = coarse.num_vertices();
  for (const double R : {5.0, 10.0}) {
    SCOPED_TRACE(fmt::format("R = {} h", R));
    double change[2] = {0, 0};
    for (const RegionBoundary b : {RegionBoundary::Clamp, RegionBoundary::Fade}) {
      CorrectionParams p;
      p.handles = {{v, drag}};
      p.radius = R * h;
      p.boundary = b;
      p.prevent_intersections = false;
      const CorrectionResult c = correct_vessel(coarse, p), f = correct_vessel(fine, p);
      const double diff = (f.displacement.topRows(n0) - c.displacement).rowwise().norm().maxCoeff() / drag.norm();
      change[static_cast<int>(b)] = diff;
      std::printf("R = %g h, %s: largest change at the coarse vertices %.2f %% of the drag\n", R, to_string(b),
                  100 * diff);
      for (const CorrectionResult* r : {&c, &f}) {
        const Mesh& m = r == &c ? coarse : fine;
        EXPECT_NEAR((r->displacement.row(v).transpose() - drag).norm(), 0.0, 1e-9);
        double beyond_2r = 0, beyond_12r = 0;
        for (int i = 0; i < m.num_vertices(); ++i) {
          const double rho = (m.positions().row(i) - coarse.positions().row(v)).norm();  // below the path distance
          if (rho > 2.0 * p.radius) beyond_2r = std::max(beyond_2r, r->displacement.row(i).norm());
          if (rho > 1.2 * p.radius) beyond_12r = std::max(beyond_12r, r->displacement.row(i).norm());
        }
        EXPECT_EQ(beyond_2r, 0.0);
        if (b == RegionBoundary::Clamp) {
          EXPECT_EQ(beyond_12r, 0.0);
        } else {
          EXPECT_LT(beyond_12r, 0.1 * drag.norm());
        }
      }
    }
    // Measured: 5.1 % against 2.1 % at 5 h, 2.5 % against 0.86 % at 10 h.
    EXPECT_LT(change[1], 0.5 * change[0]);
  }
}

TEST(Vessel, FadeBoundaryNeedsARadiusAndTheDirectSolver) {
  const Mesh m = tube_at(32);
  CorrectionParams p;
  p.handles = {{0, Eigen::Vector3d(0.1, 0, 0)}};
  p.rings = 4;
  p.boundary = RegionBoundary::Fade;
  EXPECT_THROW(correct_vessel(m, p), InputError);
  p.rings = 0;
  p.radius = 5;
  p.solver = SteadySolver::Global;
  EXPECT_THROW(correct_vessel(m, p), InputError);
  EXPECT_THROW(parse_region_boundary("soft"), InputError);
  EXPECT_EQ(parse_region_boundary("fade"), RegionBoundary::Fade);
}

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

TEST(Vessel, StifferTissueDeformsLess) {
  // A stiff patch between the handle and the border bends less: the displacement
  // varies less across it than with uniform tissue.
  const Mesh m = tube_at(64);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 0}, 12.0);
  const std::vector<int> patch = patch_near(m, {5, 0, 36}, 2.5);
  const double uniform = spread(correct_vessel(m, p), patch);
  p.stiffness = Eigen::VectorXd::Ones(m.num_vertices());
  for (int i : patch) p.stiffness[i] = 20;
  const double stiff = spread(correct_vessel(m, p), patch);
  EXPECT_LT(stiff, 0.5 * uniform);
  p.stiffness[0] = -1;
  EXPECT_THROW(correct_vessel(m, p), InputError);
}

TEST(Vessel, DynamicCorrectionSettlesToTheStaticOne) {
  const Mesh m = tube_at(48);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 1}, 10.0);
  const CorrectionResult still = correct_vessel(m, p);
  p.dynamic = true;
  p.steps = 300;
  const CorrectionResult settled = correct_vessel(m, p);
  const double scale = still.displacement.norm();
  EXPECT_LT((settled.displacement - still.displacement).norm(), 1e-3 * scale);
  p.steps = 1;  // a moment after the drag: the tissue has not caught up
  EXPECT_GT((correct_vessel(m, p).displacement - still.displacement).norm(), 0.2 * scale);
  // After 40 steps (10 / omega) critically damped tissue has settled; barely damped
  // tissue is still ringing.
  p.steps = 40;
  p.tissue.viscosity = 1.0;
  const double critical = (correct_vessel(m, p).displacement - still.displacement).norm();
  p.tissue.viscosity = 0.05;
  const double ringing = (correct_vessel(m, p).displacement - still.displacement).norm();
  EXPECT_LT(critical, 1e-2 * scale);
  EXPECT_GT(ringing, 10 * critical);
}

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
  const std::string w = units_warning(cm, LengthUnit::Millimetre, "tube.vtp");
  EXPECT_NE(w.find("tube.vtp"), std::string::npos) << w;
  EXPECT_NE(w.find("--units cm"), std::string::npos) << w;
  EXPECT_FALSE(check_units(cm, LengthUnit::Centimetre).implausible);
  EXPECT_EQ(parse_length_unit("CM"), LengthUnit::Centimetre);
  EXPECT_THROW(parse_length_unit("inch"), InputError);
}

namespace {

// Bands of other tissue across the tube near z = 30: heavier above, softer at the
// handle's height, more viscous below; the thesis's defaults elsewhere.
TissueParams banded_tissue(const Mesh& m) {
  const int nv = m.num_vertices();
  TissueParams t;
  t.mass_field = Eigen::VectorXd::Constant(nv, 0.1);
  t.elasticity_field = Eigen::VectorXd::Constant(nv, 0.9);
  t.viscosity_field = Eigen::VectorXd::Constant(nv, 0.6);
  for (int i = 0; i < nv; ++i) {
    const double z = m.positions()(i, 2);
    if (z > 31 && z < 34) t.mass_field[i] = 0.8;
    if (z > 29 && z < 31.5) t.elasticity_field[i] = 0.3;
    if (z > 25 && z < 29) t.viscosity_field[i] = 1.0;
  }
  return t;
}

}  // namespace

TEST(Vessel, ConstantTissueFieldsGiveExactlyTheScalarsResult) {
  const Mesh m = tube_at(48);
  const int a = nearest_vertex(m, {5, 0, 30}), nv = m.num_vertices();
  for (const CorrectionMethod method : {CorrectionMethod::Fem, CorrectionMethod::Springs})
    for (const bool dynamic : {false, true}) {
      if (method == CorrectionMethod::Springs && dynamic) continue;
      CorrectionParams p;
      p.handles = {{a, {-1, 0, 0.5}}};
      p.method = method;
      p.dynamic = dynamic;
      p.steps = 12;
      p.g1 = 0.2;
      if (method == CorrectionMethod::Springs)
        p.rings = 4;
      else
        p.radius = 8;
      p.tissue.mass = 0.3;
      p.tissue.elasticity = 0.5;
      p.tissue.viscosity = 0.8;
      CorrectionParams q = p;
      q.tissue.mass_field = Eigen::VectorXd::Constant(nv, 0.3);
      q.tissue.elasticity_field = Eigen::VectorXd::Constant(nv, 0.5);
      q.tissue.viscosity_field = Eigen::VectorXd::Constant(nv, 0.8);
      q.tissue.mass = q.tissue.elasticity = q.tissue.viscosity = 0;  // unused once the fields are given
      SCOPED_TRACE(fmt::format("method {} dynamic {}", static_cast<int>(method), dynamic));
      const CorrectionResult r = correct_vessel(m, p), s = correct_vessel(m, q);
      EXPECT_EQ(r.displacement, s.displacement);
      EXPECT_GT(r.max_displacement, 0);
    }
}

TEST(Vessel, AnElasticityFieldWeighsTheStaticSolveAsTheStiffnessFieldDoes) {
  // The model: elasticity e_i relative to its largest value multiplies the stiffness,
  // static or dynamic. So a patch twenty times more elastic than the tissue around it
  // bends less (as in StifferTissueDeformsLess): the displacement varies less across it.
  const Mesh m = tube_at(64);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 0}, 12.0);
  p.g1 = 0.2;
  const TissueParams t = banded_tissue(m);
  CorrectionParams banded = p, weighted = p;
  banded.tissue.elasticity_field = t.elasticity_field;
  weighted.stiffness = t.elasticity_field / t.elasticity_field.maxCoeff();
  EXPECT_LT((correct_vessel(m, banded).displacement - correct_vessel(m, weighted).displacement).cwiseAbs().maxCoeff(),
            1e-12);

  const std::vector<int> patch = patch_near(m, {5, 0, 36}, 2.5);
  CorrectionParams elastic = p;
  elastic.tissue.elasticity_field = Eigen::VectorXd::Constant(m.num_vertices(), 0.045);
  for (int i : patch) elastic.tissue.elasticity_field[i] = 0.9;
  EXPECT_LT(spread(correct_vessel(m, elastic), patch), 0.5 * spread(correct_vessel(m, p), patch));
}

TEST(Vessel, PerVertexTissueEntersTheDynamicsAsTheModelSays) {
  // Three successive states d_{N-2}, d_{N-1}, d_N of a dynamic correction through the
  // bands (runs of N-2, N-1 and N steps) satisfy, at every free vertex i, the model's
  // backward-Euler step, built here from the weighted stiffness of the whole tube:
  //   alpha_i M_i (d_N - 2 d_{N-1} + d_{N-2}) / dt^2 + b_i M_i (d_N - d_{N-1}) / dt
  //     + e_max (g2 K_w D K_w + g1 K_w) d_N = 0,
  // alpha_i = mass_i, k_i = e_i s, b_i = 2 viscosity_i sqrt(alpha_i k_i), w_i = e_i / e_max,
  // s = g2 (pi/L)^4 + g1 (pi/L)^2 (L the radius), dt = 1 / (4 sqrt(e_max s / min alpha)).
  const Mesh m = tube_at(48);
  const int a = nearest_vertex(m, {5, 0, 30}), nv = m.num_vertices();
  CorrectionParams p;
  p.handles = {{a, {-1, 0, 0.5}}};
  p.radius = 8;
  p.boundary = RegionBoundary::Clamp;  // the held handle and free set the construction below repeats
  p.g1 = 0.2;
  p.dynamic = true;
  p.tissue = banded_tissue(m);
  const int N = 9;
  std::vector<CorrectionResult> r;
  for (int steps : {N - 2, N - 1, N}) {
    p.steps = steps;
    r.push_back(correct_vessel(m, p));
  }
  const TissueParams& t = p.tissue;
  const double e_max = t.elasticity_field.maxCoeff();
  OperatorOptions o;
  o.face_weights = vertex_to_face_average(m, t.elasticity_field / e_max);
  const FemOperators ops = build_operators(m, o);
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
  const Eigen::VectorXd D = ops.mass.cwiseInverse();
  const double s = p.g2 * std::pow(M_PI / p.radius, 4) + p.g1 * std::pow(M_PI / p.radius, 2);
  std::vector<int> free;
  for (int v : r[2].region)
    if (v != a) free.push_back(v);
  double alpha_min = 1;
  for (int v : free) alpha_min = std::min(alpha_min, t.mass_field[v]);
  const double dt = 0.25 / std::sqrt(e_max * s / alpha_min);
  const Field& d0 = r[0].displacement;
  const Field& d1 = r[1].displacement;
  const Field& d2 = r[2].displacement;
  const Field elastic = e_max * (p.g2 * (K * (D.asDiagonal() * (K * d2))) + p.g1 * (K * d2));
  double worst = 0, scale = 0;
  for (int i : free) {
    const double alpha = t.mass_field[i];
    const double b = 2 * t.viscosity_field[i] * std::sqrt(alpha * t.elasticity_field[i] * s);
    const Eigen::RowVector3d inertia = alpha * ops.mass[i] * (d2.row(i) - 2 * d1.row(i) + d0.row(i)) / (dt * dt);
    const Eigen::RowVector3d damping = b * ops.mass[i] * (d2.row(i) - d1.row(i)) / dt;
    worst = std::max(worst, (inertia + damping + elastic.row(i)).norm());
    scale = std::max({scale, inertia.norm(), damping.norm(), elastic.row(i).norm()});
  }
  EXPECT_GT(scale, 0);
  EXPECT_LT(worst, 1e-8 * scale) << "worst residual " << worst << " of terms up to " << scale;
  // And the heavier band has not caught up yet: it lags the light tissue's run.
  CorrectionParams light = p;
  light.tissue.mass_field = Eigen::VectorXd::Constant(nv, 0.1);
  const CorrectionResult lr = correct_vessel(m, light);
  const CorrectionParams settled = [&] {
    CorrectionParams q = p;
    q.dynamic = false;
    return q;
  }();
  const Field target = correct_vessel(m, settled).displacement;
  double lag = 0, lag_light = 0;
  for (int i = 0; i < nv; ++i) {
    const double z = m.positions()(i, 2);
    if (!(z > 31 && z < 34)) continue;
    lag += (d2.row(i) - target.row(i)).norm();
    lag_light += (lr.displacement.row(i) - target.row(i)).norm();
  }
  EXPECT_GT(lag, lag_light);
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
