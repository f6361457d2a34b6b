// Corrections that belong to the surface, not to its triangulation (apps/vessel_correction.h):
// handles at surface points, handles with a size, regions measured on the surface and
// the smooth boundary; checked against the vertex handle they generalize, against
// subdivision, under refinement, and across independent triangulations of one plane.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/surface_point_reading.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

namespace {

// The square [-L, L]^2 (z = 0) as a grid of edge about h, rotated by `angle` and jittered
// by up to 0.2 h: planes of different h, angle and seed are independent triangulations.
Mesh plane_patch(double h, double angle, unsigned seed, double L) {
  const int n = static_cast<int>(std::ceil(2 * L / h));
  GeneratedMesh g = plane_grid(n, n, 2 * L, 2 * L);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.2 * h, 0.2 * h);
  const double c = std::cos(angle), s = std::sin(angle);
  for (Eigen::Index i = 0; i < g.V.rows(); ++i) {
    const bool inside = g.V(i, 0) > 0 && g.V(i, 0) < 2 * L && g.V(i, 1) > 0 && g.V(i, 1) < 2 * L;
    const double x = g.V(i, 0) - L + (inside ? jitter(rng) : 0), y = g.V(i, 1) - L + (inside ? jitter(rng) : 0);
    g.V(i, 0) = c * x - s * y;
    g.V(i, 1) = s * x + c * y;
  }
  return make(g);
}

SurfacePoint point_at(const Mesh& m, const Eigen::Vector3d& x) {
  return closest_surface_points(m, std::span<const Eigen::Vector3d>(&x, 1))[0];
}

// The displacement of `r` (on mesh m) at the surface point nearest x, interpolated.
Eigen::Vector3d displacement_at(const Mesh& m, const CorrectionResult& r, const Eigen::Vector3d& x) {
  const SurfacePoint p = point_at(m, x);
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) d += p.bary[k] * r.displacement.row(m.triangles()(p.face, k)).transpose();
  return d;
}

// A surface point on vertex v: one of its triangles, weight 1 at v.
SurfacePoint on_vertex(const Mesh& m, int v) {
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      if (m.triangles()(f, k) == v) {
        SurfacePoint p{f, Eigen::Vector3d::Zero()};
        p.bary[k] = 1;
        return p;
      }
  return {};
}

// The largest difference between the result on meshes[level] at each of its vertices
// within 1.2 R of x and the result on meshes[level + 1] at the same point (the closest
// point there, its corners interpolated).
double largest_difference(const std::vector<Mesh>& meshes, const std::vector<CorrectionResult>& results, int level,
                          const Eigen::Vector3d& x, double R) {
  const Mesh& coarse = meshes[static_cast<std::size_t>(level)];
  const Mesh& finer = meshes[static_cast<std::size_t>(level) + 1];
  std::vector<int> near;
  std::vector<Eigen::Vector3d> at;
  for (int v = 0; v < coarse.num_vertices(); ++v) {
    const Eigen::Vector3d y = coarse.positions().row(v).transpose();
    if ((y - x).norm() > 1.2 * R) continue;
    near.push_back(v);
    at.push_back(y);
  }
  const std::vector<SurfacePoint> on_finer = closest_surface_points(finer, at);
  const Field& fine = results[static_cast<std::size_t>(level) + 1].displacement;
  double worst = 0;
  for (std::size_t k = 0; k < near.size(); ++k) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int c = 0; c < 3; ++c) d += on_finer[k].bary[c] * fine.row(finer.triangles()(on_finer[k].face, c)).transpose();
    worst =
        std::max(worst, (results[static_cast<std::size_t>(level)].displacement.row(near[k]).transpose() - d).norm());
  }
  return worst;
}

}  // namespace

// A point handle of size 0 at a vertex is the vertex handle: the point constraint's
// reaction is the vertex's, so the bordered system gives the held vertex's answer.
TEST(CorrectionHandles, APointOfSizeZeroOnAVertexIsTheVertexHandle) {
  const Mesh m = make(icosphere(4, 10.0));
  const int v = 17;
  for (const RegionBoundary b : {RegionBoundary::Clamp, RegionBoundary::Smooth}) {
    SCOPED_TRACE(to_string(b));
    CorrectionParams vertex;
    vertex.handles = {{v, Eigen::Vector3d(0.3, -0.2, 1.1)}};
    vertex.radius = 6;
    vertex.boundary = b;
    vertex.handle_radius = 0;
    CorrectionParams point = vertex;
    point.handles = {CorrectionHandle(m, on_vertex(m, v), Eigen::Vector3d(0.3, -0.2, 1.1))};
    const CorrectionResult a = correct_vessel(m, vertex), c = correct_vessel(m, point);
    EXPECT_EQ(a.region.size(), c.region.size());
    EXPECT_LE((a.V - c.V).cwiseAbs().maxCoeff(), 1e-9 * 1.2);
    EXPECT_LE((c.V.row(v) - m.positions().row(v) - Eigen::RowVector3d(0.3, -0.2, 1.1)).norm(), 1e-12);
  }
}

// The handle point, wherever it is in its triangle, moves by exactly the drag: a point
// (size 0) as the barycentric combination of its corners' displacements, a handle with a
// size as the field's quadratic reading there (mesh/surface_point_reading.h), which the
// corners' interpolation meets to the mesh's own interpolation error. Nothing at or
// beyond the radius (on the surface) moves.
TEST(CorrectionHandles, ThePointMovesByTheDragAndNothingBeyondTheRadiusMoves) {
  const Mesh m = plane_patch(0.5, 0.3, 5, 8);
  const Eigen::Vector3d x(0.137, -0.291, 0), D(0.2, 0.1, 1.0);
  const SurfacePoint sp = point_at(m, x);
  for (const double size : {0.0, 1.0, -1.0}) {
    SCOPED_TRACE(size);
    CorrectionParams p;
    p.handles = {CorrectionHandle(m, sp, D)};
    p.radius = 5;
    p.handle_radius = size;
    const CorrectionResult r = correct_vessel(m, p);
    if (size == 0) {
      EXPECT_LE((displacement_at(m, r, x) - D).norm(), 1e-9);
    } else {
      const auto reading = quadratic_reading(m, sp);
      ASSERT_TRUE(reading);
      Eigen::Vector3d read = Eigen::Vector3d::Zero();
      for (const auto& [v, w] : *reading) read += w * r.displacement.row(v).transpose();
      EXPECT_LE((read - D).norm(), 1e-9);
      EXPECT_LE((displacement_at(m, r, x) - D).norm(), 0.03 * D.norm());
    }
    EXPECT_DOUBLE_EQ(r.handle_radius, size < 0 ? kHandleRadiusFraction * 5 : size);
    const Eigen::VectorXd s = geodesic_distance(m, GeodesicSources{.points = {sp}});
    double near_edge = 0;
    int inner = 0, inner_moved = 0;
    for (int v = 0; v < m.num_vertices(); ++v) {
      const double len = r.displacement.row(v).norm();
      if (s[v] >= 5) {
        EXPECT_EQ(len, 0.0) << "vertex " << v << " at " << s[v];
      }
      if (s[v] >= 0.95 * 5 && s[v] < 5) near_edge = std::max(near_edge, len);
      if (s[v] < 0.3 * 5) {
        ++inner;
        inner_moved += len > 0.2 * D.norm();
      }
    }
    // The displacement has already fallen to almost nothing just inside R.
    EXPECT_LT(near_edge, 2e-3 * D.norm());
    EXPECT_EQ(inner_moved, inner);
  }
}

// A handle with a size makes a bump whose curvature at the handle does not grow as the
// mesh is refined; a point handle's does (its field is r^2 log r, whose Laplacian is
// log r). Curvature of the bump: the discrete Laplacian of the normal displacement at the
// handle vertex, M^-1 K d_z.
TEST(CorrectionHandles, AHandleWithASizeHasBoundedCurvatureUnderRefinement) {
  std::vector<double> sized, point;
  for (const double h : {0.5, 0.25, 0.125}) {
    const Mesh m = plane_patch(h, 0.0, 3, 6);
    const int v = [&] {
      int best = 0;
      m.positions().rowwise().squaredNorm().minCoeff(&best);
      return best;
    }();
    const FemOperators ops = build_cotan_operators(m);
    for (const double size : {1.0, 0.0}) {
      CorrectionParams p;
      p.handles = {{v, Eigen::Vector3d(0, 0, 1)}};
      p.radius = 4;
      p.handle_radius = size;
      const CorrectionResult r = correct_vessel(m, p);
      const Field dz = r.displacement.col(2);
      const Field lap = apply_stiffness(m, ops, dz);
      (size > 0 ? sized : point).push_back(std::abs(lap(v, 0)) / ops.mass[v]);
    }
  }
  RecordProperty("curvature_sized", fmt::format("{:.3g} {:.3g} {:.3g}", sized[0], sized[1], sized[2]));
  RecordProperty("curvature_point", fmt::format("{:.3g} {:.3g} {:.3g}", point[0], point[1], point[2]));
  EXPECT_LT(sized[2], 1.15 * sized[0]);
  EXPECT_GT(point[1], point[0] + 0.1);
  EXPECT_GT(point[2], point[1] + 0.1);
}

// A point at an edge's midpoint, and the same point as a vertex of the subdivided mesh:
// the two corrections agree at the coarse vertices to the discretization error, which
// falls as the pair is refined.
TEST(CorrectionHandles, AnEdgeMidpointAgreesWithTheVertexOfTheSubdivision) {
  std::vector<double> diff;
  for (const int level : {3, 4}) {
    const GeneratedMesh g = icosphere(level, 10.0);
    const Mesh coarse = make(g), fine = make(subdivide_midpoint(g.V, g.F));
    const int a = coarse.triangles()(0, 0), b = coarse.triangles()(0, 1);
    const Eigen::Vector3d mid = 0.5 * (coarse.positions().row(a) + coarse.positions().row(b)).transpose();
    const Eigen::Vector3d D = 0.8 * mid.normalized();
    CorrectionParams p;
    p.radius = 7;
    p.handles = {CorrectionHandle(coarse, SurfacePoint{0, Eigen::Vector3d(0.5, 0.5, 0)}, D)};
    const CorrectionResult c = correct_vessel(coarse, p);
    int m = 0;  // the subdivision's vertex at the midpoint
    (fine.positions().rowwise() - mid.transpose()).rowwise().squaredNorm().minCoeff(&m);
    ASSERT_LT((fine.positions().row(m).transpose() - mid).norm(), 1e-12);
    p.handles = {CorrectionHandle(fine, on_vertex(fine, m), D)};
    const CorrectionResult f = correct_vessel(fine, p);
    const double d = (f.displacement.topRows(coarse.num_vertices()) - c.displacement).rowwise().norm().maxCoeff();
    diff.push_back(d / D.norm());
  }
  RecordProperty("midpoint_vs_subdivision", fmt::format("{:.4f} {:.4f}", diff[0], diff[1]));
  EXPECT_LT(diff[1], 0.6 * diff[0]);
  EXPECT_LT(diff[1], 0.05);
}

// Independent triangulations of one plane (rotated, jittered grids at h, h/2, h/4), one
// drag at a point: the coarse result at each coarse vertex against the finer result at
// the same point. The smooth boundary with a point handle converges; the clamp with the
// nearest vertex does not (its boundary and handle move with the mesh).
TEST(CorrectionHandles, IndependentTriangulationsAgreeWithTheSmoothBoundary) {
  const Eigen::Vector3d x(0.1234, 0.0567, 0), D(0, 0, 1);
  const double R = 10;  // 10 coarse edges
  for (const bool smooth : {true, false}) {
    std::vector<Mesh> meshes;
    std::vector<CorrectionResult> results;
    for (int level = 0; level < 3; ++level) {
      const Mesh m = plane_patch(1.0 / (1 << level), 0.3 + 0.7 * level, 11 + level, 1.4 * R);
      const SurfacePoint sp = point_at(m, x);
      CorrectionParams p;
      p.radius = R;
      p.prevent_intersections = false;
      if (smooth) {
        p.handles = {CorrectionHandle(m, sp, D)};
      } else {
        int k = 0;
        sp.bary.maxCoeff(&k);
        p.handles = {{m.triangles()(sp.face, k), D}};
        p.boundary = RegionBoundary::Clamp;
      }
      results.push_back(correct_vessel(m, p));
      meshes.push_back(m);
    }
    const std::vector<double> worst = {largest_difference(meshes, results, 0, x, R) / D.norm(),
                                       largest_difference(meshes, results, 1, x, R) / D.norm()};
    RecordProperty(smooth ? "smooth" : "clamp", fmt::format("{:.4f} {:.4f}", worst[0], worst[1]));
    std::printf("%s: largest difference %.3f %% then %.3f %% of the drag\n", smooth ? "smooth" : "clamp",
                100 * worst[0], 100 * worst[1]);
    if (smooth) {
      EXPECT_LT(worst[1], 0.8 * worst[0]);
      EXPECT_LT(worst[1], 0.01);
    } else {
      EXPECT_GT(worst[1], 0.05);  // the old rule does not converge: the reason for the new one
    }
  }
}

TEST(CorrectionHandles, PointHandlesFromTextAndBadOnesAreRefused) {
  const Mesh m = make(icosphere(3, 10.0));
  const std::vector<Eigen::Vector3d> at{Eigen::Vector3d(0, 0, 12), Eigen::Vector3d(12, 0, 0)};
  const auto hs = parse_point_handles(m, at, {"normal:2", "0,0,1"});
  ASSERT_EQ(hs.size(), 2u);
  ASSERT_TRUE(hs[0].point.has_value());
  // normal:2 at the top of a sphere is 2 along +z (the outward normal there).
  EXPECT_LT((hs[0].displacement - Eigen::Vector3d(0, 0, 2)).norm(), 0.05);
  EXPECT_LT((position(m, *hs[0].point) - Eigen::Vector3d(0, 0, 10)).norm(), 0.3);
  EXPECT_NE(error_of([&] { parse_point_handles(m, at, {"normal:2"}); }).find("2 handles but 1 moves"),
            std::string::npos);
  CorrectionParams p;
  p.radius = 5;
  p.handles = {CorrectionHandle(m, SurfacePoint{0, Eigen::Vector3d(0.7, 0.7, -0.4)}, Eigen::Vector3d(0, 0, 1))};
  EXPECT_NE(error_of([&] { correct_vessel(m, p); }).find("barycentric"), std::string::npos);
  EXPECT_NE(error_of([&] {
              CorrectionHandle(m, SurfacePoint{m.num_faces()}, Eigen::Vector3d::Zero());
            }).find("does not exist"),
            std::string::npos);
  // The global solver takes the clamp with vertex handles of size 0 only.
  CorrectionParams g;
  g.radius = 5;
  g.handles = {{0, Eigen::Vector3d(0, 0, 1)}};
  g.solver = SteadySolver::Global;
  EXPECT_NE(error_of([&] { correct_vessel(m, g); }).find("clamp boundary"), std::string::npos);
  g.boundary = RegionBoundary::Clamp;
  EXPECT_EQ(error_of([&] { correct_vessel(m, g); }), "(no error)");
  // A radius far below the edges: only the handle's triangle moves, the point exactly;
  // an absurdly small one is refused, never a NaN.
  CorrectionParams tiny;
  tiny.radius = 1e-3;
  tiny.handles = {CorrectionHandle(m, SurfacePoint{5, Eigen::Vector3d(0.2, 0.3, 0.5)}, Eigen::Vector3d(0, 0, 1))};
  const CorrectionResult t = correct_vessel(m, tiny);
  EXPECT_TRUE(t.V.allFinite());
  EXPECT_LE(t.region.size(), 3u);
  Eigen::Vector3d moved = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k)
    moved += tiny.handles[0].point->bary[k] * t.displacement.row(m.triangles()(5, k)).transpose();
  EXPECT_LE((moved - Eigen::Vector3d(0, 0, 1)).norm(), 1e-9);
  EXPECT_NE(t.region_warning.find("only the handles move"), std::string::npos) << t.region_warning;
  // A handle far smaller than the edges is the point load (and no overflow on the way).
  CorrectionParams small = tiny;
  small.radius = 5;
  small.handle_radius = 1e-300;
  CorrectionParams point = small;
  point.handle_radius = 0;
  EXPECT_LE((correct_vessel(m, small).V - correct_vessel(m, point).V).cwiseAbs().maxCoeff(), 1e-12);
  tiny.radius = 1e-90;
  EXPECT_NE(error_of([&] { correct_vessel(m, tiny); }).find("too small"), std::string::npos);
  EXPECT_EQ(parse_region_boundary("smooth"), RegionBoundary::Smooth);
  EXPECT_EQ(std::string(to_string(CorrectionParams{}.boundary)), "smooth");
}

// A handle point typed far from the wall (another frame or unit) still takes the
// nearest surface point, but the result says how far it was and, when the point with x
// and y negated lies on the wall, that RAS and LPS were most likely mixed up; the
// report gives each point as given and its distance in mm, whatever the mesh's unit.
TEST(CorrectionHandles, APointGivenFarFromTheSurfaceIsWarnedAboutAndAFrameMixUpNamed) {
  GeneratedMesh g = icosphere(3, 10.0);
  g.V.rowwise() += Eigen::RowVector3d(30, 20, 0);  // off the origin: negating x and y moves it away
  const Mesh m = make(g);
  auto correct_at = [&](const Mesh& mesh, const Eigen::Vector3d& x, LengthUnit units) {
    CorrectionParams p;
    p.radius = 5;
    p.units = units;
    p.handles = parse_point_handles(mesh, {x}, {"normal:1"});
    const CorrectionResult r = correct_vessel(mesh, p);
    EXPECT_GT(r.moved_vertices, 3) << "the handle is the nearest surface point all the same";
    return std::pair{r, nlohmann::json::parse(correction_report_json(mesh.positions(), mesh.triangles(), p, r))};
  };
  {  // on the wall: no warning, distance about 0
    const auto [r, j] = correct_at(m, Eigen::Vector3d(30, 20, 10), LengthUnit::Millimetre);
    EXPECT_TRUE(r.handle_warning.empty()) << r.handle_warning;
    EXPECT_TRUE(j["handle_warning"].is_null());
    EXPECT_LT(j["handle_points"][0]["distance_to_surface"].get<double>(), 0.2);
    EXPECT_EQ(j["handle_points"][0]["given"][2].get<double>(), 10.0);
  }
  {  // 90 mm above the top, a frame that does not explain it
    const auto [r, j] = correct_at(m, Eigen::Vector3d(30, 20, 100), LengthUnit::Millimetre);
    EXPECT_NE(r.handle_warning.find("lies 90 mm from the surface, farther than the region's 5 mm"), std::string::npos)
        << r.handle_warning;
    EXPECT_NE(r.handle_warning.find("mesh's coordinates, frame and unit"), std::string::npos) << r.handle_warning;
    EXPECT_EQ(r.handle_warning.find("RAS"), std::string::npos);
    EXPECT_NEAR(j["handle_points"][0]["distance_to_surface"].get<double>(), 90.0, 0.2);
    EXPECT_EQ(j["handle_warning"].get<std::string>(), r.handle_warning);
  }
  {  // a vertex spelled @X,Y,Z far off (the nearest vertex): the same warning
    CorrectionParams p;
    p.radius = 5;
    p.handles = parse_handles(m, {0}, {"normal:1"});
    p.handles[0].given = m.positions().row(0).transpose() + Eigen::Vector3d(0, 0, 0.5);
    EXPECT_TRUE(correct_vessel(m, p).handle_warning.empty()) << "half a mm from its vertex";
    const Eigen::Vector3d centre(30, 20, 0);  // 50 mm straight out from vertex 0: still its nearest vertex
    p.handles[0].given = centre + 6 * (m.positions().row(0).transpose() - centre);
    const std::string w = correct_vessel(m, p).handle_warning;
    EXPECT_NE(w.find("lies 50 mm from the nearest vertex"), std::string::npos) << w;
    EXPECT_NE(w.find("its handle is the nearest vertex, 0,"), std::string::npos) << w;
  }
  {  // the top of the wall with x and y negated (RAS given for an LPS mesh)
    const auto [r, j] = correct_at(m, Eigen::Vector3d(-30, -20, 10), LengthUnit::Millimetre);
    EXPECT_NE(r.handle_warning.find("(30, 20, 10), lies"), std::string::npos) << r.handle_warning;
    EXPECT_NE(r.handle_warning.find("RAS"), std::string::npos) << r.handle_warning;
  }
  {  // a mesh in cm: distances and the region in mm
    GeneratedMesh gc = g;
    gc.V /= 10;
    const Mesh cm = make(gc);
    const auto [r, j] = correct_at(cm, Eigen::Vector3d(3, 2, 10), LengthUnit::Centimetre);
    EXPECT_NE(r.handle_warning.find("the handle point (3, 2, 10) lies 90 mm from the surface, farther than the "
                                    "region's 5 mm"),
              std::string::npos)
        << "the point as given, in cm; distances in mm: " << r.handle_warning;
    EXPECT_NEAR(j["handle_points"][0]["distance_to_surface"].get<double>(), 90.0, 0.2);
    EXPECT_EQ(j["handle_points"][0]["given"][2].get<double>(), 10.0) << "as given, in the mesh's unit";
    const CorrectionResult mirrored = correct_at(cm, Eigen::Vector3d(-3, -2, 1), LengthUnit::Centimetre).first;
    EXPECT_NE(mirrored.handle_warning.find("(3, 2, 1), lies"), std::string::npos) << mirrored.handle_warning;
    const CorrectionResult near = correct_at(cm, Eigen::Vector3d(3, 2, 1.02), LengthUnit::Centimetre).first;
    EXPECT_TRUE(near.handle_warning.empty()) << "0.2 mm off is within the 5 mm region: " << near.handle_warning;
  }
}

// A session applies point handles on top of each other, with undo.
TEST(CorrectionHandles, ASessionTakesPointHandles) {
  const Mesh m = make(icosphere(3, 10.0));
  CorrectionSession s(m);
  CorrectionParams p;
  p.radius = 6;
  p.handles = parse_point_handles(m, {Eigen::Vector3d(3, 2, 11)}, {"normal:1"});
  const CorrectionResult r = s.apply(p);
  EXPECT_GT(r.moved_vertices, 3);
  EXPECT_LE((s.mesh().positions() - r.V).cwiseAbs().maxCoeff(), 0.0);
  s.undo();
  EXPECT_LE((s.mesh().positions() - m.positions()).cwiseAbs().maxCoeff(), 0.0);
}

// Independent triangulations of a curved wall: icospheres of radius 10 at three levels,
// each turned by its own rotation (so no vertex or edge is shared), one drag at a point
// that is no vertex of any, R = 5 coarse edges. The handle's bump is read to second order
// (a linear reading scaled the whole field by where the point fell in its triangle), so
// the coarse result at each coarse vertex meets the finer result at the same point to
// under 1 % of the drag on the finer pair, converging at better than order 1.5.
TEST(CorrectionHandles, IndependentTriangulationsOfASphereAgreeAtFiveEdges) {
  const Eigen::Vector3d x = 10 * Eigen::Vector3d(0.3, 0.5, 0.8).normalized();
  const Eigen::Vector3d D = -1.5 * x.normalized();
  std::vector<Mesh> meshes;
  std::vector<CorrectionResult> results;
  double R = 0;
  for (const int level : {3, 4, 5}) {
    GeneratedMesh g = icosphere(level, 10.0);
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(0.4 + 0.9 * level, Eigen::Vector3d(1, -2, 0.5 * level).normalized()).toRotationMatrix();
    g.V = (g.V * turn.transpose()).eval();
    const Mesh m = make(g);
    if (level == 3) R = 5 * mean_edge_length(m);
    CorrectionParams p;
    p.radius = R;
    p.prevent_intersections = false;
    p.handles = {CorrectionHandle(m, point_at(m, x), D)};
    results.push_back(correct_vessel(m, p));
    meshes.push_back(m);
  }
  const std::vector<double> worst = {largest_difference(meshes, results, 0, x, R) / D.norm(),
                                     largest_difference(meshes, results, 1, x, R) / D.norm()};
  RecordProperty("sphere", fmt::format("{:.4f} {:.4f}", worst[0], worst[1]));
  std::printf("sphere, R = 5 coarse edges: largest difference %.3f %% then %.3f %% of the drag\n", 100 * worst[0],
              100 * worst[1]);
  EXPECT_LT(worst[1], 0.01);
  EXPECT_GT(std::log2(worst[0] / worst[1]), 1.5);
}

// A vessel only a few edges round (a coarse coronary: 4 mm across, 1.5 mm edges) turns
// too much around the handle for a quadratic over its triangle's plane: the handle is
// read at its corners, which move by exactly the drag, and nothing moves much farther
// than the drag (a bad fit scaled such a field by up to 3 times the drag).
TEST(CorrectionHandles, AVesselAFewEdgesRoundIsReadAtTheCorners) {
  const Mesh m = make(tube(2.0, 40.0, 26, 8));
  const Eigen::Vector3d x(1.9, 0.3, 20.2), D(-0.8, 0, 0);
  const SurfacePoint sp = point_at(m, x);
  CorrectionParams p;
  p.handles = {CorrectionHandle(m, sp, D)};
  p.radius = 10;
  p.prevent_intersections = false;
  const CorrectionResult r = correct_vessel(m, p);
  ASSERT_EQ(r.handle_reading.size(), 1u);
  EXPECT_EQ(r.handle_reading[0].size(), 3u);
  EXPECT_LE((displacement_at(m, r, x) - D).norm(), 1e-9);
  EXPECT_LE(r.max_displacement, 1.5 * D.norm());
}
