// editor/editor_session.h (meshpde::editor): one page's session: the drag preview and
// its release, the shared operator bundles, poke, paint and the rim under the cursor.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>
#include <vector>

#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/editor/editor_session.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/surface_point_reading.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/steady_direct.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using namespace meshpde::test;

namespace {
// A generated mesh as the data an EditorSession opens.
MeshData as_mesh_data(const GeneratedMesh& g) {
  MeshData data;
  data.V = g.V;
  data.F = g.F;
  return data;
}
}  // namespace

TEST(EditorSession, EditorPreviewFollowsTheHandleAndCorrectReplacesIt) {
  EditorSession s(as_mesh_data(icosphere(4)));
  const Mesh& mesh = s.mesh();
  int handle = 0;
  mesh.positions().col(2).maxCoeff(&handle);
  const Positions rest = mesh.positions();
  const double setup_ms = s.drag_begin(handle, 0.6);
  EXPECT_GE(setup_ms, 0.0);
  EXPECT_TRUE(s.dragging());
  EXPECT_GT(s.drag_region_vertices(), 100);
  const Eigen::Vector3d offset(0.02, 0, 0.15);
  s.drag_move(offset);
  const Positions P = s.display_positions();
  // The handle is where it was dragged, and the preview when the mouse stops is the
  // correction that releasing applies (same region rule, copy and operators), to
  // 1e-9 of the drag.
  EXPECT_LE((P.row(handle) - rest.row(handle) - offset.transpose()).norm(), 1e-12);
  CorrectionParams release;
  release.handles = {{handle, offset}};
  release.radius = 0.6;
  const CorrectionResult expected = correct_vessel(mesh, release);
  EXPECT_LE((P - expected.V).cwiseAbs().maxCoeff(), 1e-9 * offset.norm());
  // The vertices the drag can move (the page redraws only these and their neighbours):
  // every vertex that moved is one, and they are a part of the sphere, not all of it.
  {
    std::vector<char> can_move(static_cast<std::size_t>(mesh.num_vertices()), 0);
    for (int v : s.drag_moving_vertices()) can_move.at(static_cast<std::size_t>(v)) = 1;
    int moved = 0, outside = 0;
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if ((P.row(v) - rest.row(v)).norm() > 0) {
        ++moved;
        if (!can_move[static_cast<std::size_t>(v)]) ++outside;
      }
    EXPECT_GE(moved, s.drag_region_vertices() / 2);
    EXPECT_EQ(outside, 0);
    EXPECT_GE(static_cast<int>(s.drag_moving_vertices().size()), s.drag_region_vertices());
    EXPECT_LT(static_cast<int>(s.drag_moving_vertices().size()), mesh.num_vertices() / 2);
  }
  EXPECT_THROW(s.drag_move(Eigen::Vector3d(NAN, 0, 0)), InputError);
  EXPECT_THROW(s.drag_begin(handle, -1), InputError);
  EXPECT_TRUE(s.dragging());  // a refused request leaves the drag as it was
  // Releasing with a correction: the corrected surface replaces the preview.
  CorrectionParams p;
  p.handles = {{handle, offset}};
  p.radius = 0.6;
  const CorrectionResult r = s.correct(p);
  EXPECT_FALSE(s.dragging());
  EXPECT_LE((s.display_positions() - r.V).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LE((r.V - P).cwiseAbs().maxCoeff(), 1e-9 * offset.norm());
  // The wall shows how far each vertex moved until the next action; a save leaves it out.
  EXPECT_EQ(s.field_name(), "moved (mm)");
  ASSERT_EQ(s.field().size(), mesh.num_vertices());
  EXPECT_NEAR(s.field()[handle], offset.norm(), 1e-12);
  EXPECT_NEAR(s.field().maxCoeff(), r.max_displacement, 1e-12);
  EXPECT_FALSE(s.snapshot().vertex_scalars.count("moved (mm)"));
  // A drag let go without moving leaves the surface as it was.
  s.drag_begin(handle, 0.6);
  EXPECT_EQ(s.field_name(), "");  // the next action ends the colouring
  s.drag_end();
  EXPECT_TRUE(s.drag_moving_vertices().empty());
  EXPECT_LE((s.display_positions() - r.V).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_THROW(s.drag_move(offset), InputError);
  // A region too large to factor while the user waits is refused in words.
  const GeneratedMesh big = icosphere(6);  // 40,962 vertices
  MeshData big_data;
  big_data.V = big.V;
  big_data.F = big.F;
  EditorSession b(big_data);
  try {
    b.drag_begin(0, 10.0);
    ADD_FAILURE() << "a whole-mesh preview region was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("too large for a live preview"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(b.dragging());
}

TEST(EditorSession, EditorSessionsShareOneOperatorBundlePerStateOfTheSurface) {
  EditorSession s(as_mesh_data(icosphere(3)));
  EXPECT_EQ(s.operator_builds(), 0);
  s.paint(0, 1.0, 0, 1);
  s.paint(10, -1.0, 0, 1);
  s.add_source(5);
  s.play("heat");
  s.advance(5);
  const double warmed = s.snapshot().vertex_scalars.at("heat").sum();
  s.poke_begin(20, 0);
  s.poke_end();
  EXPECT_EQ(s.operator_builds(), 1);  // one bundle served painting, heat and the probe
  CorrectionParams p;
  p.handles = {{0, Eigen::Vector3d(0, 0, 0.1)}};
  p.rings = 2;
  s.correct(p);
  // The surface changed: heat starts again on the new operators (before, it went on
  // from its old state on the old surface's operators).
  s.play("heat");
  s.advance(1);
  EXPECT_EQ(s.operator_builds(), 2);
  EXPECT_LT(s.snapshot().vertex_scalars.at("heat").sum(), warmed);
  s.paint(3, 0.5, 0, 1);
  EXPECT_EQ(s.operator_builds(), 2);
}

// A new tool ends the previous tool's work at once: a paint, a correction or a drag
// right after a poke's release shows the surface at rest, without waiting for the
// probe's relaxation (which runs on its own thread and takes a second or more).
TEST(EditorSession, ANewToolEndsThePokeAtOnce) {
  EditorSession s(as_mesh_data(icosphere(4)));
  const Positions rest = s.mesh().positions();
  auto poke = [&] {
    s.poke_begin(10, 0);
    for (int k = 1; k <= 10; ++k) {
      s.poke_move(Eigen::Vector3d(0, 0, -0.03 * k));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    // The servo moves the surface: wait until it shows, then let go.
    for (int k = 0; k < 200 && (s.display_positions() - rest).cwiseAbs().maxCoeff() < 0.05; ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_GT((s.display_positions() - rest).cwiseAbs().maxCoeff(), 0.05);
    s.poke_end();
  };
  poke();
  s.paint(100, 3.0, 0, 1);
  EXPECT_EQ((s.display_positions() - rest).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(s.poke_active_vertices(), 0);
  EXPECT_EQ(s.field_name(), "paint");
  poke();
  s.drag_begin(200, 0.5);
  EXPECT_EQ((s.display_positions() - rest).cwiseAbs().maxCoeff(), 0.0);
  s.drag_end();
  poke();
  s.add_source(300);  // a heat or wave source
  EXPECT_EQ((s.display_positions() - rest).cwiseAbs().maxCoeff(), 0.0);
  poke();
  s.end_poke();  // the page's tissue brush
  EXPECT_EQ((s.display_positions() - rest).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(s.poke_active_vertices(), 0);
}

TEST(EditorSession, EditorPaintKeepsOneFactorAndEqualsAFreshInterpolation) {
  EditorSession s(as_mesh_data(icosphere(3)));
  std::map<int, double> painted;
  auto click = [&](int v, double x, double g1, double g2) {
    s.paint(v, x, g1, g2);
    painted[v] = x;
    std::vector<InterpolationConstraint> c;
    for (const auto& [w, y] : painted) c.push_back({w, Eigen::VectorXd::Constant(1, y)});
    const InterpolationResult fresh = interpolate(
        s.mesh(), FieldKind::Scalar, c, InterpolationParams{.g1 = g1, .g2 = g2, .solver = SteadySolver::Direct});
    const Eigen::VectorXd u = s.snapshot().vertex_scalars.at("paint");
    EXPECT_LT((u - fresh.values.col(0)).cwiseAbs().maxCoeff(), 1e-10 * fresh.values.cwiseAbs().maxCoeff());
  };
  click(0, 1.0, 0, 1);
  click(10, -1.0, 0, 1);
  click(200, 0.5, 0, 1);
  click(10, 2.0, 0, 1);  // a new value where one was painted
  EXPECT_NE(s.last_solve_info().find("1 factorization"), std::string::npos) << s.last_solve_info();
  click(300, 0.25, 1, 1);  // other weights: a new factor
  EXPECT_NE(s.last_solve_info().find("1 factorization"), std::string::npos) << s.last_solve_info();
  s.clear_paint();
  painted.clear();
  click(5, 1.0, 0, 1);
}

TEST(EditorSession, EditorPreviewEqualsTheReleasedCorrectionWithStiffnessOnADentedVessel) {
  // A generated vessel with a dent, a stiffer band painted on it, a drag over a region
  // much smaller than the mesh (so both solve on the region's copy): the preview at the
  // last mouse position equals the correction applied on release.
  const MeshData data = as_mesh_data(y_bifurcation(BifurcationParams{.cell = 0.7, .dent = true}));
  EditorSession s(data);
  const Mesh& mesh = s.mesh();
  const Eigen::Vector3d target(2.5, 0, -10);
  int handle = 0;
  (mesh.positions().rowwise() - target.transpose()).rowwise().squaredNorm().minCoeff(&handle);
  Eigen::VectorXd stiffness;
  apply_brush(mesh, stiffness, Brush{.vertex = handle, .radius = 2.0, .value = 4.0});
  const double radius = 6.0;
  s.drag_begin(handle, radius, stiffness);
  ASSERT_LT(s.drag_region_vertices(), mesh.num_vertices() / 3);
  const Eigen::Vector3d offset(1.2, 0.1, -0.3);
  for (double t : {0.25, 0.5, 1.0}) s.drag_move(t * offset);  // the mouse moves, then stops
  const Positions preview = s.display_positions();
  CorrectionParams p;
  p.handles = {{handle, offset}};
  p.radius = radius;
  p.stiffness = stiffness;
  const CorrectionResult r = s.correct(p);
  EXPECT_EQ(r.new_self_intersections, 0);
  EXPECT_EQ(r.intersection_action, "none");
  EXPECT_LE((preview - r.V).cwiseAbs().maxCoeff(), 1e-9 * offset.norm());
  // and the stiffness mattered: without it the release differs
  CorrectionParams soft = p;
  soft.stiffness.resize(0);
  EXPECT_GT((correct_vessel(Mesh(data.V, data.F), soft).V - r.V).cwiseAbs().maxCoeff(), 1e-3 * offset.norm());
}

TEST(EditorSession, TheEditorsLaplacianChoiceReachesEveryTool) {
  // serve --laplacian: the session's operators (paint, heat, probe) and its corrections
  // and previews use the kind chosen, not Auto's pick. An icosphere is well shaped, so
  // Auto would take the cotangent operator everywhere.
  const MeshData data = as_mesh_data(icosphere(3));
  for (const LaplacianKind kind : {LaplacianKind::Auto, LaplacianKind::IntrinsicDelaunay}) {
    EditorSession s(data, nullptr, Space::LPS, kind);
    EXPECT_EQ(s.laplacian(), kind);
    CorrectionParams p;
    p.handles = {{0, Eigen::Vector3d(0, 0, 0.1)}};
    p.radius = 0.5;
    const CorrectionResult r = s.correct(p);
    EXPECT_EQ(r.laplacian, kind == LaplacianKind::Auto ? LaplacianKind::Cotan : LaplacianKind::IntrinsicDelaunay);
    // The preview solves with the same operator as the release: they agree.
    s.undo();
    s.drag_begin(0, 0.5);
    s.drag_move(Eigen::Vector3d(0, 0, 0.1));
    EXPECT_LE((s.display_positions() - r.V).cwiseAbs().maxCoeff(), 1e-9);
    s.drag_end();
  }
}

// A drag at a surface point (what the page sends): the preview uses the correction's
// default rule (the point moves, the region on the surface, the smooth boundary, a
// handle of a quarter of the radius) and equals the release with that point handle to
// 1e-9 of the drag; with a stiffness field and a labelled cap held too.
TEST(EditorSession, APointDragPreviewEqualsTheReleasedPointCorrection) {
  const GeneratedMesh g = tube(5.0, 60.0, 50, 32, true);
  MeshData data = as_mesh_data(g);
  data.cell_arrays["CellEntityIds"] = DataArray{g.face_labels.cast<double>(), "Int32"};
  EditorSession s(data);
  ASSERT_FALSE(s.held_vertices().empty());
  const Mesh mesh = s.mesh();
  const Eigen::Vector3d x(5.0, 0.3, 7.5);  // near the cap at z = 0: the held rim is inside the region
  const SurfacePoint sp = closest_surface_points(mesh, std::span<const Eigen::Vector3d>(&x, 1))[0];
  Eigen::VectorXd stiffness = Eigen::VectorXd::Ones(mesh.num_vertices());
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.positions()(v, 1) > 2) stiffness[v] = 4;
  s.drag_begin(sp, 9.0, stiffness);
  EXPECT_TRUE(s.dragging());
  EXPECT_GT(s.drag_region_vertices(), 50);
  const Eigen::Vector3d offset(-1.2, 0.2, 0.4);
  for (double t : {0.3, 1.0}) s.drag_move(t * offset);
  const Positions preview = s.display_positions();
  // The picked point itself follows the drag exactly, as the handle reads it (the
  // quadratic reading of a handle with a size), and its triangle's corners to the mesh's
  // interpolation error.
  const auto reading = quadratic_reading(mesh, sp);
  ASSERT_TRUE(reading);
  Eigen::Vector3d moved = Eigen::Vector3d::Zero(), corners = Eigen::Vector3d::Zero();
  for (const auto& [v, w] : *reading) moved += w * (preview.row(v) - mesh.positions().row(v)).transpose();
  for (int k = 0; k < 3; ++k)
    corners +=
        sp.bary[k] *
        (preview.row(mesh.triangles()(sp.face, k)) - mesh.positions().row(mesh.triangles()(sp.face, k))).transpose();
  EXPECT_LE((moved - offset).norm(), 1e-9);
  EXPECT_LE((corners - offset).norm(), 0.04 * offset.norm());
  CorrectionParams p;
  p.handles = {CorrectionHandle(mesh, sp, offset)};
  p.radius = 9.0;
  p.stiffness = stiffness;
  const CorrectionResult r = s.correct(p);
  EXPECT_EQ(r.intersection_action, "none");
  EXPECT_LE((preview - r.V).cwiseAbs().maxCoeff(), 1e-9 * offset.norm());
  for (const int v : s.held_vertices()) EXPECT_EQ(r.displacement.row(v).norm(), 0.0);
  EXPECT_FALSE(s.dragging());
  // A point outside the mesh's triangles is refused in words.
  EXPECT_THROW(s.drag_begin(SurfacePoint{mesh.num_faces()}, 9.0), InputError);
}

// What the editor draws under the cursor before a press: on a sphere of radius 10, the
// rim at a radius of 8 mm is the small circle at great-circle distance 8 from the point
// (within 1 % of the radius, along all of it), a closed curve as long as that circle,
// and the handle's rim the one at a quarter of it; the count of vertices inside is the
// region that a drag from that point then moves.
TEST(EditorSession, TheRimUnderTheCursorIsTheCircleTheDragWillMove) {
  GeneratedMesh g = icosphere(4);
  const double rho = 10, R = 8;
  g.V *= rho;
  EditorSession s(as_mesh_data(g));
  const Mesh& mesh = s.mesh();
  const Eigen::Vector3d x = Eigen::Vector3d(3, 4, 9).normalized() * rho;
  const SurfacePoint sp = closest_surface_points(mesh, std::span<const Eigen::Vector3d>(&x, 1))[0];
  const Eigen::Vector3d c = position(mesh, sp).normalized();
  const RegionRim rim = s.region_rim(sp, R);
  EXPECT_DOUBLE_EQ(rim.handle_radius, kHandleRadiusFraction * R);
  const auto check = [&](const std::vector<LevelSetSegment>& segments, double radius, const char* what) {
    ASSERT_GT(segments.size(), 8u) << what;
    double worst = 0, length = 0;
    for (const LevelSetSegment& seg : segments) {
      for (const Eigen::Vector3d* y : {&seg.a, &seg.b})
        worst = std::max(worst, std::abs(rho * std::acos(std::clamp(y->normalized().dot(c), -1.0, 1.0)) - radius));
      length += (seg.b - seg.a).norm();
    }
    EXPECT_LT(worst, 0.01 * R) << what;
    EXPECT_NEAR(length, 2 * std::numbers::pi * rho * std::sin(radius / rho), 0.01 * length) << what;
    // Closed: every end is the end of exactly two segments.
    std::map<std::pair<long, long>, int> ends;
    for (const LevelSetSegment& seg : segments)
      for (const Eigen::Vector3d* y : {&seg.a, &seg.b}) ++ends[{std::lround(y->x() * 1e6), std::lround(y->y() * 1e6)}];
    for (const auto& [key, count] : ends) EXPECT_EQ(count, 2) << what;
  };
  check(rim.rim, R, "region");
  check(rim.handle, rim.handle_radius, "handle");
  s.drag_begin(sp, R);
  EXPECT_EQ(rim.region_vertices, s.drag_region_vertices());
  EXPECT_THROW(s.region_rim(sp, 0), InputError);
  EXPECT_THROW(s.region_rim(SurfacePoint{mesh.num_faces()}, R), InputError);
}
