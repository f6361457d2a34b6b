// apps/local_drag.h: DragSession (drag_vertex: test_local_drag.cpp).
#include <gtest/gtest.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <chrono>
#include <limits>
#include <map>
#include <numbers>
#include <queue>
#include <random>
#include <thread>
#include <unordered_set>

#include "../src/core/index_map.h"
#include "meshpde/apps/fairing.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/handle_load.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/refinement.h"
#include "meshpde/solvers/surface_multigrid.h"
#include "solver_problems.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using namespace meshpde::test;

namespace {

// Held values of the session's handles and the region solved from scratch by a fresh
// factorization: the reference for every DragSession figure.
Field fresh_solve(const Mesh& mesh, const FemOperators& ops, const std::vector<int>& handles,
                  const Eigen::MatrixXd& moves, const std::vector<int>& region_with_handles) {
  std::vector<int> free;
  for (int v : region_with_handles)
    if (std::find(handles.begin(), handles.end(), v) == handles.end()) free.push_back(v);
  const SteadyDirectSolver s(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  Field held = Field::Zero(mesh.num_vertices(), 3);
  for (std::size_t k = 0; k < handles.size(); ++k) held.row(handles[k]) = moves.row(static_cast<Eigen::Index>(k));
  return s.solve(held);
}

Field session_field(const Mesh& mesh, const DragSession& s, const Eigen::MatrixXd& moves) {
  return s.positions(moves) - mesh.positions();
}

// The smooth boundary's foundation as pde/region_boundary.h documents it (plate only),
// built here from the distances: kappa(s) M_i at the free vertices.
Eigen::VectorXd documented_foundation(const FemOperators& ops, const Eigen::VectorXd& dist,
                                      const std::vector<int>& free, double R) {
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(dist.size());
  for (const int v : free) {
    const double x = std::clamp((dist[v] / R - 0.5) / 0.5, 0.0, 0.98);
    extra[v] = 1e3 / std::pow(R, 4) * x * x / std::pow(1 - x, 4) * ops.mass[v];
  }
  return extra;
}

}  // namespace

TEST(DragSession, UpdatesAreTheDirectSolveAndLinearInTheHandle) {
  const GeneratedMesh g = icosphere(4);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  int handle = 0;
  mesh.positions().col(2).maxCoeff(&handle);
  DragSession s(mesh, ops, {handle}, DragSessionParams{.radius = 0.6, .boundary = RegionBoundary::Clamp});
  EXPECT_EQ(s.factorizations(), 1);
  EXPECT_GT(s.region().size(), 150u);
  // The region: the vertices within the radius on the surface (the handle held), the
  // correction's rule, not the smaller edge-path ball.
  std::vector<int> surface;
  for (const auto& [v, dist] : geodesic_distances_from(mesh, GeodesicSources{.vertices = {handle}}, 0.6))
    if (v != handle) surface.push_back(v);
  std::vector<int> region = s.region();
  std::sort(region.begin(), region.end());
  std::sort(surface.begin(), surface.end());
  EXPECT_EQ(region, surface);
  EXPECT_GT(region.size() + 1, geodesic_ball(mesh, handle, 0.6).size());
  for (const Eigen::RowVector3d& move : {Eigen::RowVector3d(0, 0, 0.1), Eigen::RowVector3d(0.05, -0.02, 0.3)}) {
    const Eigen::MatrixXd d = move;
    const DragResult r = drag_vertex(
        mesh, ops,
        DragParams{
            .vertex = handle, .displacement = move.transpose(), .radius = 0.6, .boundary = RegionBoundary::Clamp});
    EXPECT_LE((session_field(mesh, s, d) - r.displacement).cwiseAbs().maxCoeff(), 1e-12 + 1e-10 * move.norm());
  }
  // Still one factorization: updates are products with the basis.
  EXPECT_EQ(s.factorizations(), 1);
  EXPECT_EQ(s.solves(), 1);
}

TEST(DragSession, AddedHandlesAndGrownRegionsMatchFreshFactorizations) {
  const GeneratedMesh g = icosphere(4);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  int h0 = 0;
  mesh.positions().col(2).maxCoeff(&h0);
  DragSession s(mesh, ops, {h0}, DragSessionParams{.radius = 0.7, .boundary = RegionBoundary::Clamp, .margin = true});
  // Two more handles inside the region, far enough from each other and the first.
  const std::vector<int> region0 = s.region();
  std::vector<int> extra;
  for (int v : region0) {
    const Eigen::RowVector3d p = mesh.positions().row(v);
    bool far = (p - mesh.positions().row(h0)).norm() > 0.25;
    for (int e : extra) far = far && (p - mesh.positions().row(e)).norm() > 0.25;
    if (far && (p - mesh.positions().row(h0)).norm() < 0.4) extra.push_back(v);
    if (extra.size() == 2) break;
  }
  ASSERT_EQ(extra.size(), 2u);
  s.add_handle(extra[0]);
  s.add_handle(extra[1]);
  EXPECT_EQ(s.factorizations(), 1);  // handles added with the same factor
  Eigen::MatrixXd moves(3, 3);
  moves << 0, 0, 0.2, 0.05, 0, -0.1, 0, 0.08, 0.02;
  std::vector<int> with_handles = region0;
  with_handles.push_back(h0);
  const Field ref = fresh_solve(mesh, ops, s.handles(), moves, with_handles);
  const double tol = 1e-9 * moves.norm();
  EXPECT_LE((session_field(mesh, s, moves) - ref).cwiseAbs().maxCoeff(), tol);
  // Each handle lands exactly where it was moved; the basis is 1 at its own handle.
  const Positions P = s.positions(moves);
  for (int k = 0; k < 3; ++k)
    EXPECT_LE((P.row(s.handles()[k]) - mesh.positions().row(s.handles()[k]) - moves.row(k)).norm(), 1e-12);
  // Grown by a ring: the larger region's answer, handles kept. The first ring was
  // factored at set-up as a margin (ordered last), so it needs no new factor.
  std::vector<int> previous = region0;
  Field previous_ref = ref;
  for (int grown_by : {1, 1, 2}) {
    SCOPED_TRACE(grown_by);
    s.grow(grown_by);
    EXPECT_GT(s.region().size(), previous.size());
    std::vector<int> grown = s.region();
    grown.push_back(h0);
    const Field ref2 = fresh_solve(mesh, ops, s.handles(), moves, grown);
    EXPECT_LE((session_field(mesh, s, moves) - ref2).cwiseAbs().maxCoeff(), tol);
    EXPECT_LE(s.last_relative_residual(), 1e-10);
    EXPECT_GT((ref2 - previous_ref).cwiseAbs().maxCoeff(), 1e-6);  // the rings did change the answer
    previous = s.region();
    previous_ref = ref2;
  }
  // One factor for the set-up and the first ring; the second and third growths refactor.
  EXPECT_EQ(s.factorizations(), 3);
  // Without a margin the first growth refactors too.
  DragSession plain(mesh, ops, {h0}, DragSessionParams{.radius = 0.7, .boundary = RegionBoundary::Clamp});
  plain.grow(1);
  EXPECT_EQ(plain.factorizations(), 2);
}

TEST(DragSession, LargeRegionsFactoredOnTwoThreadsMatchFreshFactorizations) {
  // A region of about 3k vertices without margins: the split factor (both halves of
  // the nested dissection at once) for the set-up, an added handle and a growth.
  const GeneratedMesh g = icosphere(6);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  int h0 = 0;
  mesh.positions().col(2).maxCoeff(&h0);
  DragSession s(mesh, ops, {h0}, DragSessionParams{.radius = 0.6, .boundary = RegionBoundary::Clamp});
  ASSERT_GT(s.region().size(), 2500u);
  EXPECT_EQ(s.split_factor(), SplitCholesky::available());
  int second = s.region()[0];
  for (int v : s.region())  // a free vertex about 0.3 from the first handle
    if (std::abs((mesh.positions().row(v) - mesh.positions().row(h0)).norm() - 0.3) <
        std::abs((mesh.positions().row(second) - mesh.positions().row(h0)).norm() - 0.3))
      second = v;
  s.add_handle(second);
  Eigen::MatrixXd moves(2, 3);
  moves << 0.01, 0.02, 0.1, -0.03, 0, 0.05;
  const double tol = 1e-9 * moves.norm();
  std::vector<int> with_handles = s.region();
  with_handles.push_back(h0);
  EXPECT_LE(
      (session_field(mesh, s, moves) - fresh_solve(mesh, ops, s.handles(), moves, with_handles)).cwiseAbs().maxCoeff(),
      tol);
  s.grow(1);
  EXPECT_EQ(s.factorizations(), 2);
  EXPECT_EQ(s.split_factor(), SplitCholesky::available());
  with_handles = s.region();
  with_handles.push_back(h0);
  EXPECT_LE(
      (session_field(mesh, s, moves) - fresh_solve(mesh, ops, s.handles(), moves, with_handles)).cwiseAbs().maxCoeff(),
      tol);
  EXPECT_LE(s.last_relative_residual(), 1e-10);
  // With a margin the factor keeps its leading-block form (the ring ordered last).
  EXPECT_FALSE(
      DragSession(mesh, ops, {h0}, DragSessionParams{.radius = 0.6, .boundary = RegionBoundary::Clamp, .margin = true})
          .split_factor());
}

TEST(DragSession, ShrunkRegionsReuseTheFactorAndMatchFreshFactorizations) {
  const GeneratedMesh g = icosphere(4);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  int h0 = 0;
  mesh.positions().col(2).maxCoeff(&h0);
  DragSession s(
      mesh, ops, {h0},
      DragSessionParams{.radius = 0.7, .boundary = RegionBoundary::Clamp, .margin = true, .inner_margin = true});
  const std::vector<int> region0 = s.region();
  // A second handle on the region's outermost ring: shrinking holds it, as a handle.
  const std::unordered_set<int> inside(region0.begin(), region0.end());
  int edge = -1;
  for (int v : region0)
    for (int w : mesh.neighbors(v))
      if (edge < 0 && w != h0 && !inside.count(w)) edge = v;
  ASSERT_GE(edge, 0);
  s.add_handle(edge);
  Eigen::MatrixXd moves(2, 3);
  moves << 0, 0, 0.2, 0.03, -0.02, 0.05;
  const double tol = 1e-9 * moves.norm();
  auto matches_fresh = [&] {
    const Field ref = fresh_solve(mesh, ops, s.handles(), moves, s.region());
    EXPECT_LE((session_field(mesh, s, moves) - ref).cwiseAbs().maxCoeff(), tol);
    const Positions P = s.positions(moves);
    EXPECT_LE((P.row(edge) - mesh.positions().row(edge) - moves.row(1)).norm(), 1e-12);
  };
  s.shrink(1);  // the inner margin: a leading block of the same factor
  const std::size_t shrunk = s.region().size();
  EXPECT_LT(shrunk, region0.size());
  EXPECT_EQ(s.region_index(edge), -1);
  EXPECT_EQ(s.factorizations(), 1);
  matches_fresh();
  s.grow(1);  // the ring given up comes back, the handle inside it again
  EXPECT_EQ(s.region().size(), region0.size());
  EXPECT_GE(s.region_index(edge), 0);
  matches_fresh();
  s.grow(1);  // the outer margin
  EXPECT_GT(s.region().size(), region0.size());
  matches_fresh();
  s.shrink(1);
  EXPECT_EQ(s.region().size(), region0.size());
  EXPECT_EQ(s.factorizations(), 1);
  matches_fresh();
  s.shrink(2);  // beyond the factored rings: a new factor
  EXPECT_EQ(s.factorizations(), 2);
  EXPECT_LT(s.region().size(), shrunk);
  matches_fresh();
  // Without margins the same shrink refactors and peels the same ring.
  DragSession plain(mesh, ops, {h0}, DragSessionParams{.radius = 0.7, .boundary = RegionBoundary::Clamp});
  plain.shrink(1);
  EXPECT_EQ(plain.factorizations(), 2);
  EXPECT_EQ(plain.region().size(), shrunk);
  EXPECT_THROW(plain.shrink(0), InputError);
  EXPECT_THROW(plain.shrink(1000), InputError);
}

TEST(DragSession, BadRequestsAreRefused) {
  const GeneratedMesh g = icosphere(3);
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  EXPECT_THROW(DragSession(mesh, ops, {}, DragSessionParams{.rings = 3}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {0, 0}, DragSessionParams{.rings = 3}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {mesh.num_vertices()}, DragSessionParams{.rings = 3}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {0}, DragSessionParams{}), InputError);
  EXPECT_NE(test::error_of([&] {
              DragSession(mesh, ops, {0}, DragSessionParams{.radius = std::nan("")});
            }).find("not a number"),
            std::string::npos);
  EXPECT_NE(test::error_of([&] {
              drag_vertex(mesh, ops, DragParams{.vertex = 0, .displacement = {0, 0, 1}, .radius = std::nan("")});
            }).find("not a number"),
            std::string::npos);
  DragSession s(mesh, ops, {0}, DragSessionParams{.rings = 3});
  int outside = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (s.region_index(v) < 0 && v != 0) outside = v;
  EXPECT_THROW(s.add_handle(outside), InputError);
  EXPECT_THROW(s.add_handle(0), InputError);
  EXPECT_THROW((void)s.displacements(Eigen::MatrixXd::Zero(2, 3)), InputError);
}

// The smooth boundary (the default): the region within R of the handles on the surface,
// the foundation of pde/region_boundary.h on the diagonal. Checked against the
// foundation built here from its documented formula and factored by Eigen, against
// correct_vessel with the same vertex handles of size 0 (the corrections' rule), and
// drag_vertex; nothing at R or beyond moves and little beyond 0.95 R.
TEST(DragSession, TheSmoothBoundaryIsTheCorrectionsRuleWithVertexHandlesOfSizeZero) {
  const GeneratedMesh g = tube(5.0, 40.0, 60, 48);  // mm, about 0.65 mm edges
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  auto nearest = [&](const Eigen::RowVector3d& x) {
    int best = 0;
    (mesh.positions().rowwise() - x).rowwise().squaredNorm().minCoeff(&best);
    return best;
  };
  const int h0 = nearest(Eigen::RowVector3d(5, 0, 20)), h1 = nearest(Eigen::RowVector3d(0, 5, 23));
  const double R = 6.0;
  Eigen::MatrixXd moves(2, 3);
  moves << -0.8, 0.1, 0.2, 0.05, -0.6, 0;
  const DragSession s(mesh, ops, {h0, h1}, DragSessionParams{.radius = R, .handle_radius = 0});
  EXPECT_EQ(s.boundary(), RegionBoundary::Smooth);
  EXPECT_EQ(s.handle_radius(), 0.0);
  const Field d = session_field(mesh, s, moves);

  // The reference: K D K plus kappa(s) M_i on the free rows, factored by Eigen.
  const Eigen::VectorXd dist = geodesic_distance(mesh, GeodesicSources{.vertices = {h0, h1}});
  std::vector<int> free;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (dist[v] < R && v != h0 && v != h1) free.push_back(v);
  std::vector<int> sorted_region = s.region();
  std::sort(sorted_region.begin(), sorted_region.end());
  EXPECT_EQ(sorted_region, free);
  const Eigen::VectorXd extra = documented_foundation(ops, dist, free, R);
  const PdeCoefficients plate{.g0 = 0, .g1 = 0, .g2 = 1};
  const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, plate, free, extra);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(free.size()), 3);
  const std::vector<int> handles{h0, h1};
  for (std::size_t k = 0; k < handles.size(); ++k) {
    const auto coupling = steady_coupling(mesh, ops, plate, handles[k]);
    for (std::size_t i = 0; i < free.size(); ++i)
      for (const auto& [w, value] : coupling)
        if (w == free[i]) b.row(static_cast<Eigen::Index>(i)) += value * moves.row(static_cast<Eigen::Index>(k));
  }
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::MatrixXd x = ldlt.solve(b);
  double diff = 0;
  for (std::size_t i = 0; i < free.size(); ++i)
    diff = std::max(diff, (d.row(free[i]) - x.row(static_cast<Eigen::Index>(i))).cwiseAbs().maxCoeff());
  EXPECT_LE(diff, 1e-9 * moves.norm());
  // Nothing at R or beyond moves; beyond 0.95 R below 0.2 % of the drag.
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (dist[v] >= R) {
      ASSERT_EQ(d.row(v).norm(), 0.0) << v;
    }
    if (dist[v] > 0.95 * R) {
      EXPECT_LE(d.row(v).norm(), 2e-3 * 0.8) << v;
    }
  }

  // The correction's smooth rule with the same handles as vertices of size 0.
  CorrectionParams cp;
  cp.handles = {CorrectionHandle(h0, moves.row(0).transpose()), CorrectionHandle(h1, moves.row(1).transpose())};
  cp.radius = R;
  cp.handle_radius = 0;
  cp.laplacian = LaplacianKind::Cotan;
  cp.prevent_intersections = false;
  const CorrectionResult c = correct_vessel(mesh, cp);
  EXPECT_LE((c.displacement - d).cwiseAbs().maxCoeff(), 1e-9 * moves.norm());
  // The clamp differs (no foundation): the smooth rule is not the clamp under another name.
  const DragSession clamp(mesh, ops, {h0, h1}, DragSessionParams{.radius = R, .boundary = RegionBoundary::Clamp});
  EXPECT_GT((session_field(mesh, clamp, moves) - d).cwiseAbs().maxCoeff(), 0.05 * moves.norm());

  // drag_vertex takes the same rule by default.
  const DragResult one =
      drag_vertex(mesh, ops, DragParams{.vertex = h0, .displacement = moves.row(0).transpose(), .radius = R});
  const DragSession single(mesh, ops, {h0}, DragSessionParams{.radius = R});
  EXPECT_LE((one.displacement - session_field(mesh, single, moves.topRows(1))).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(one.solver, SteadySolver::Direct);
  // A held handle's force is the plate's row at it applied to the whole field (computed
  // here on drag_vertex's whole-mesh displacement; the session reads only its region).
  const DragResult held = drag_vertex(
      mesh, ops, DragParams{.vertex = h0, .displacement = moves.row(0).transpose(), .radius = R, .handle_radius = 0});
  Eigen::Vector3d row;
  for (int axis = 0; axis < 3; ++axis)
    row[axis] = bilaplacian_row(mesh, ops, h0, [&](int j) { return held.displacement(j, axis); });
  EXPECT_GT(row.norm(), 0);
  EXPECT_LE((held.reaction - row).norm(), 1e-12 * row.norm());
  // The same for both held handles of the two-handle session, on its own field.
  const Eigen::MatrixXd forces = s.forces(moves);
  for (std::size_t k = 0; k < handles.size(); ++k)
    for (int axis = 0; axis < 3; ++axis) {
      const double expected = bilaplacian_row(mesh, ops, handles[k], [&](int j) { return d(j, axis); });
      EXPECT_NEAR(forces(static_cast<Eigen::Index>(k), axis), expected, 1e-12 * forces.norm()) << k << " " << axis;
    }
  EXPECT_THROW(
      drag_vertex(mesh, ops,
                  DragParams{.vertex = h0, .displacement = {0, 0, 1}, .radius = R, .solver = SteadySolver::Global}),
      InputError);

  // The smooth region is fixed by its radius: margins, grow and shrink ask for the clamp;
  // the fade is a correction's only.
  DragSession grown(mesh, ops, {h0}, DragSessionParams{.radius = R});
  EXPECT_THROW(grown.grow(1), InputError);
  EXPECT_THROW(grown.shrink(1), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {h0}, DragSessionParams{.radius = R, .margin = true}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {h0}, DragSessionParams{.radius = R, .boundary = RegionBoundary::Fade}),
               InputError);
  // A region given by rings ends by the clamp whatever the boundary asked.
  EXPECT_EQ(DragSession(mesh, ops, {h0}, DragSessionParams{.rings = 3}).boundary(), RegionBoundary::Clamp);
}

// Handles with a size and at surface points: the session equals correct_vessel with the
// same handles and the default size (a quarter of R), each handle's point lands on its
// displacement, forces() is the load's total (the residual of an independently assembled
// system), and a handle added later equals an independent bordered solve.
TEST(DragSession, SizedAndPointHandlesAreTheCorrectionsHandles) {
  const GeneratedMesh g = tube(5.0, 40.0, 60, 48);  // mm, about 0.65 mm edges
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  const double R = 6.0;
  auto nearest = [&](const Eigen::RowVector3d& x) {
    int best = 0;
    (mesh.positions().rowwise() - x).rowwise().squaredNorm().minCoeff(&best);
    return best;
  };
  const int h0 = nearest(Eigen::RowVector3d(5, 0, 20));
  // A point inside a triangle near (0, 5, 23): no vertex of the mesh.
  const SurfacePoint p1 = closest_surface_points(mesh, std::vector<Eigen::Vector3d>{{0.3, 5.2, 23.1}})[0];
  ASSERT_GT(p1.bary.minCoeff(), 0.05);
  Eigen::MatrixXd moves(2, 3);
  moves << -0.8, 0.1, 0.2, 0.05, -0.6, 0;
  const DragSession s(mesh, ops, {h0}, {p1}, DragSessionParams{.radius = R});
  EXPECT_DOUBLE_EQ(s.handle_radius(), kHandleRadiusFraction * R);
  ASSERT_EQ(s.handles().size(), 2u);
  const Field d = session_field(mesh, s, moves);

  CorrectionParams cp;
  cp.handles = {CorrectionHandle(h0, moves.row(0).transpose()), CorrectionHandle(mesh, p1, moves.row(1).transpose())};
  cp.radius = R;
  cp.laplacian = LaplacianKind::Cotan;
  cp.prevent_intersections = false;
  const CorrectionResult c = correct_vessel(mesh, cp);
  EXPECT_DOUBLE_EQ(c.handle_radius, s.handle_radius());
  EXPECT_LE((c.displacement - d).cwiseAbs().maxCoeff(), 1e-9 * moves.norm());
  // A size is not a no-op: the held vertices of size 0 give another field.
  const DragSession point_loads(mesh, ops, {h0}, {p1}, DragSessionParams{.radius = R, .handle_radius = 0});
  EXPECT_GT((session_field(mesh, point_loads, moves) - d).cwiseAbs().maxCoeff(), 0.02 * moves.norm());

  // Each handle's point lands on its displacement; the vertex handle moves by exactly its own.
  const auto readings = s.readings();
  for (std::size_t k = 0; k < 2; ++k) {
    Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
    for (const auto& [v, w] : readings[k]) at += w * d.row(v);
    EXPECT_LE((at - moves.row(static_cast<Eigen::Index>(k))).norm(), 1e-9 * moves.norm()) << k;
  }
  EXPECT_LE((d.row(h0) - moves.row(0)).norm(), 1e-12);  // positions() sets it: rest + move, less rest
  const Eigen::MatrixXd rows = s.displacements(moves);
  EXPECT_LE((rows.row(s.region_index(h0)) - moves.row(0)).norm(), 1e-9 * moves.norm());

  // forces(): A d on the free rows (assembled here: K D K plus the foundation) is each
  // handle's load times its multiplier, and the multipliers are the loads' totals.
  const Eigen::VectorXd dist = geodesic_distance(mesh, GeodesicSources{.vertices = {h0}, .points = {p1}});
  std::vector<int> free = s.region();
  std::sort(free.begin(), free.end());
  const Eigen::VectorXd extra = documented_foundation(ops, dist, free, R);
  const PdeCoefficients plate{.g0 = 0, .g1 = 0, .g2 = 1};
  const Eigen::SparseMatrix<double> A = assemble_steady_matrix(mesh, ops, plate, free, extra);
  Eigen::MatrixXd dF(static_cast<Eigen::Index>(free.size()), 3);
  for (std::size_t i = 0; i < free.size(); ++i) dF.row(static_cast<Eigen::Index>(i)) = d.row(free[i]);
  const Eigen::MatrixXd y = A * dF;
  const Eigen::MatrixXd forces = s.forces(moves);
  EXPECT_LE((y.colwise().sum() - forces.colwise().sum()).norm(), 1e-7 * forces.norm());
  const HandleLoad l0 = handle_load(mesh, h0, std::nullopt, s.handle_radius());
  const HandleLoad l1 = handle_load(mesh, h0, p1, s.handle_radius());
  Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(mesh.num_vertices(), 3);
  for (const auto& [v, w] : l0.load) expected.row(v) += w * forces.row(0);
  for (const auto& [v, w] : l1.load) expected.row(v) += w * forces.row(1);
  for (std::size_t i = 0; i < free.size(); ++i)
    EXPECT_LE((y.row(static_cast<Eigen::Index>(i)) - expected.row(free[i])).norm(), 1e-7 * forces.norm()) << free[i];
  // drag_vertex's reaction is the session's force.
  const DragResult one =
      drag_vertex(mesh, ops, DragParams{.vertex = h0, .displacement = moves.row(0).transpose(), .radius = R});
  const DragSession single(mesh, ops, {h0}, DragSessionParams{.radius = R});
  EXPECT_LE((one.displacement - session_field(mesh, single, moves.topRows(1))).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LE((one.reaction.transpose() - single.forces(moves.topRows(1))).norm(), 1e-12 * one.reaction.norm());

  // A vertex added later (held at its displacement): the bordered system
  // [A -W; C^T 0] [d; lambda] = [0; D] solved here by a sparse LU.
  DragSession added(mesh, ops, {h0}, {p1}, DragSessionParams{.radius = R});
  const int h2 = nearest(Eigen::RowVector3d(3.5, 3.5, 21.5));
  added.add_handle(h2);
  Eigen::MatrixXd moves3(3, 3);
  moves3 << moves, 0.2, 0.3, -0.4;
  const Field d3 = session_field(mesh, added, moves3);
  const auto n = static_cast<Eigen::Index>(free.size());
  std::map<int, Eigen::Index> row;
  for (Eigen::Index i = 0; i < n; ++i) row[free[static_cast<std::size_t>(i)]] = i;
  std::vector<Eigen::Triplet<double>> t;
  for (int j = 0; j < A.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) t.emplace_back(it.row(), it.col(), it.value());
  const std::vector<std::vector<std::pair<int, double>>> loads{l0.load, l1.load, {{h2, 1.0}}};
  const auto reads = added.readings();
  for (Eigen::Index k = 0; k < 3; ++k) {
    for (const auto& [v, w] : loads[static_cast<std::size_t>(k)]) t.emplace_back(row.at(v), n + k, -w);
    for (const auto& [v, w] : reads[static_cast<std::size_t>(k)]) t.emplace_back(n + k, row.at(v), w);
  }
  Eigen::SparseMatrix<double> K(n + 3, n + 3);
  K.setFromTriplets(t.begin(), t.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(K);
  ASSERT_EQ(lu.info(), Eigen::Success);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n + 3, 3);
  rhs.bottomRows(3) = moves3;
  const Eigen::MatrixXd ref = lu.solve(rhs);
  double diff = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    diff = std::max(diff, (d3.row(free[static_cast<std::size_t>(i)]) - ref.row(i)).cwiseAbs().maxCoeff());
  EXPECT_LE(diff, 1e-8 * moves3.norm());
  EXPECT_LE((added.forces(moves3) - ref.bottomRows(3)).norm(), 1e-6 * ref.bottomRows(3).norm());
  EXPECT_EQ(added.factorizations(), 1);

  // Refused: points or sizes without the smooth boundary, a size that is not a number, a bad point.
  EXPECT_THROW(DragSession(mesh, ops, {h0}, {p1}, DragSessionParams{.radius = R, .boundary = RegionBoundary::Clamp}),
               InputError);
  EXPECT_THROW(DragSession(mesh, ops, {h0}, DragSessionParams{.handle_radius = 1, .rings = 3}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {h0}, DragSessionParams{.radius = R, .handle_radius = std::nan("")}), InputError);
  EXPECT_THROW(DragSession(mesh, ops, {}, {SurfacePoint{.face = -1}}, DragSessionParams{.radius = R}), InputError);
  EXPECT_THROW(drag_vertex(mesh, ops,
                           DragParams{.vertex = h0,
                                      .displacement = {0, 0, 1},
                                      .radius = R,
                                      .boundary = RegionBoundary::Clamp,
                                      .handle_radius = 1}),
               InputError);
}
