#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <string>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using test::make;

TEST(Mesh, CsrAdjacencyIsSortedSymmetricAndIndexesEdges) {
  const Mesh m = make(icosphere(2));
  EXPECT_EQ(m.num_edges(), 3 * m.num_vertices() - 6);  // closed genus-0 triangle mesh
  for (int i = 0; i < m.num_vertices(); ++i) {
    const auto n = m.neighbors(i);
    EXPECT_TRUE(std::is_sorted(n.begin(), n.end()));
    for (int s = m.offsets()[i]; s < m.offsets()[i + 1]; ++s) {
      const int j = m.neighbors()[s], e = m.edge_ids()[s];
      EXPECT_GE(m.find_slot(j, i), 0);
      EXPECT_EQ(std::min(i, j), m.edges()(e, 0));
      EXPECT_EQ(std::max(i, j), m.edges()(e, 1));
    }
  }
  EXPECT_EQ(m.find_slot(0, 0), -1);
}

TEST(Mesh, RejectsOutOfRangeIndexAndNonFiniteCoordinates) {
  Positions V(3, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  Triangles F(1, 3);
  F << 0, 1, 3;
  EXPECT_THROW(Mesh(V, F), InputError);
  F << 0, 1, 2;
  V(1, 2) = std::nan("");
  try {
    Mesh bad(V, F);
    FAIL() << "NaN accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 1"), std::string::npos) << e.what();
  }
}

TEST(Generators, LatLongSphereCountsOfTable1) {
  const int n[] = {2, 3, 4, 5, 15}, expected[] = {6, 14, 26, 42, 422};
  for (int k = 0; k < 5; ++k) {
    const Mesh m = make(latlong_sphere(n[k], 100));
    EXPECT_EQ(m.num_vertices(), expected[k]);
    const MeshReport r = analyze(m);
    EXPECT_EQ(r.boundary_loops, 0);
    EXPECT_TRUE(r.orientation_consistent);
    EXPECT_GT(r.signed_volume, 0);
    EXPECT_EQ(r.euler_characteristic, 2);
  }
}

TEST(Generators, GeodesicSpheresAreClosedOutwardAndOfTheRightSize) {
  const int tet_f[] = {1, 2, 4, 10, 20}, tet_v[] = {4, 10, 34, 202, 802};
  for (int k = 0; k < 5; ++k) {
    const Mesh m = make(geodesic_sphere(BaseSolid::Tetrahedron, tet_f[k], 5));
    EXPECT_EQ(m.num_vertices(), tet_v[k]);
    const MeshReport r = analyze(m);
    EXPECT_EQ(r.euler_characteristic, 2);
    EXPECT_TRUE(r.orientation_consistent);
    EXPECT_GT(r.signed_volume, 0);
  }
  const int ico_f[] = {1, 3, 5}, ico_v[] = {12, 92, 252};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(make(geodesic_sphere(BaseSolid::Icosahedron, ico_f[k], 5)).num_vertices(), ico_v[k]);
  }
  const Mesh ico5 = make(icosphere(5));
  EXPECT_EQ(ico5.num_vertices(), 10242);
  const MeshReport r = analyze(ico5);
  EXPECT_TRUE(r.orientation_consistent);
  EXPECT_GT(r.signed_volume, 0);
  EXPECT_NEAR(r.area, 4 * M_PI, 0.01 * 4 * M_PI);
}

TEST(Generators, TubePlaneFinsAndBifurcation) {
  const MeshReport tube_r = analyze(make(tube(1, 5, 10, 12)));
  EXPECT_EQ(tube_r.boundary_loops, 2);
  EXPECT_EQ(tube_r.nonmanifold_edges, 0);
  EXPECT_TRUE(tube_r.orientation_consistent);

  const MeshReport plane_r = analyze(make(plane_grid(4, 3)));
  EXPECT_EQ(plane_r.vertices, 20);
  EXPECT_EQ(plane_r.boundary_loops, 1);
  EXPECT_NEAR(plane_r.area, 1.0, 1e-12);

  const Mesh f = make(fins(3, 4));
  const MeshReport fr = analyze(f);
  EXPECT_EQ(fr.nonmanifold_edges, 4);  // the shared axis has 4 edges, each with 3 triangles
  EXPECT_EQ(fr.components, 1);

  const Mesh y = make(y_bifurcation(BifurcationParams{.cell = 1.0, .dent = true}));
  const MeshReport yr = analyze(y);
  EXPECT_EQ(yr.boundary_loops, 0);
  EXPECT_EQ(yr.nonmanifold_edges, 0);
  EXPECT_EQ(yr.nonmanifold_vertices, 0);
  EXPECT_EQ(yr.components, 1);
  EXPECT_EQ(yr.euler_characteristic, 2);
  EXPECT_TRUE(yr.orientation_consistent);
  EXPECT_GT(yr.signed_volume, 0);
  EXPECT_GT(yr.min_angle_deg, 5.0);  // relaxed onto the surface: no slivers
}

// The demo's handle: a vertex at the bottom of the dent, moved radially back onto the
// trunk's cylinder; on the undented mesh the same rule finds a wall vertex that needs
// almost no move (the wall is already there, up to the relaxation's O(h^2)).
TEST(Generators, DentHandleMovesTheDentsBottomBackOntoTheTrunk) {
  for (const double cell : {1.0, 0.6}) {
    const BifurcationParams bp{.cell = cell, .dent = true};
    const GeneratedMesh dented = y_bifurcation(bp);
    const DentHandle h = dent_handle(dented.V, bp);
    const Eigen::Vector3d p = dented.V.row(h.vertex).transpose();
    EXPECT_LT(std::hypot(p.x(), p.y()), bp.trunk_radius - 0.5 * bp.dent_depth) << "cell " << cell;
    EXPECT_NEAR(p.z(), -0.5 * bp.trunk_length, cell) << "cell " << cell;
    const Eigen::Vector3d q = p + h.move;
    EXPECT_NEAR(std::hypot(q.x(), q.y()), bp.trunk_radius, 1e-12) << "cell " << cell;
    EXPECT_EQ(h.move.z(), 0.0);
    EXPECT_GT(h.move.dot(Eigen::Vector3d(p.x(), p.y(), 0)), 0.0) << "outward";
    EXPECT_NEAR(h.move.norm(), bp.dent_depth, 0.6 * cell) << "cell " << cell;
  }
}

TEST(Generators, MidpointSubdivisionQuadruplesFaces) {
  const GeneratedMesh g = icosphere(1);
  const GeneratedMesh s = subdivide_midpoint(g.V, g.F);
  EXPECT_EQ(s.F.rows(), 4 * g.F.rows());
  const Mesh a(g.V, g.F), b(s.V, s.F);
  EXPECT_EQ(b.num_vertices(), a.num_vertices() + a.num_edges());
  EXPECT_NEAR(analyze(b).area, analyze(a).area, 1e-12);
}

TEST(Topology, DegenerateDuplicateUnreferencedAndNonManifoldVertex) {
  // Two triangles sharing only vertex 0 (a bow-tie), a degenerate repeated-index
  // face, a zero-area collinear face, a vertex duplicating another's position, and
  // an unreferenced vertex.
  Positions V(9, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0, 2, 0, 0, 3, 0, 0, 1, 0, 0, 5, 5, 5;
  Triangles F(4, 3);
  F << 0, 1, 2, 0, 3, 4, 1, 1, 2, 1, 5, 6;
  const MeshReport r = analyze(Mesh(V, F));
  EXPECT_EQ(r.nonmanifold_vertices, 2);  // vertex 0 (bow-tie) and vertex 1 (face 1 5 6 touches it alone)
  EXPECT_EQ(r.degenerate_faces, 2);
  EXPECT_EQ(r.duplicate_vertices, 1);     // vertex 7 sits on vertex 1
  EXPECT_EQ(r.unreferenced_vertices, 2);  // 7 and 8
  EXPECT_NEAR(r.area, 1.0, 1e-15);
}

constexpr int kNotStated = -1000;

struct RealMeshExpectation {
  const char* file;
  int vertices, boundary_loops, nonmanifold_edges, duplicate_vertices, unreferenced;
  int euler;       // kNotStated where the manifest does not give it
  int consistent;  // 1, 0 or kNotStated
};

class RealMeshInfo : public ::testing::TestWithParam<RealMeshExpectation> {};

TEST_P(RealMeshInfo, MatchesManifest) {
  const auto& e = GetParam();
  Mesh m;
  if (!test::load_data(e.file, m)) return;
  const MeshReport r = analyze(m);
  EXPECT_EQ(r.vertices, e.vertices);
  EXPECT_EQ(r.boundary_loops, e.boundary_loops);
  EXPECT_EQ(r.nonmanifold_edges, e.nonmanifold_edges);
  EXPECT_EQ(r.duplicate_vertices, e.duplicate_vertices);
  EXPECT_EQ(r.unreferenced_vertices, e.unreferenced);
  if (e.euler != kNotStated) {
    EXPECT_EQ(r.euler_characteristic, e.euler);
  }
  if (e.consistent != kNotStated) {
    EXPECT_EQ(r.orientation_consistent, e.consistent == 1);
  }
  EXPECT_EQ(r.degenerate_faces, 0);
}

// Figures from ../shared/data/MANIFEST.md.
// What gtest prints for a case (ctest -N, failures): its file.
void PrintTo(const RealMeshExpectation& e, std::ostream* os) {
  *os << e.file;
}

INSTANTIATE_TEST_SUITE_P(Manifest, RealMeshInfo,
                         ::testing::Values(RealMeshExpectation{"bunny-3k.off", 3485, 0, 0, 0, 0, 2, 1},
                                           RealMeshExpectation{"bunny-36k.obj", 35947, 5, 0, 0, 1113, -3, 1},
                                           RealMeshExpectation{"fertility-4k.off", 4494, 0, 0, 0, 0, -6, 1},
                                           RealMeshExpectation{"camelhead-11k.off", 11381, 1, 0, 0, 0, 1, 1},
                                           RealMeshExpectation{"cow-3k.off", 2762, 0, 0, 1, 0, 2, 1},
                                           RealMeshExpectation{"igea-134k.ply", 134345, 0, 0, 0, 0, 2, 1},
                                           RealMeshExpectation{"aorta-open-6k.stl", 6068, 3, 0, 0, 0, -1, 1},
                                           RealMeshExpectation{"coronary-phantom-7k.stl", 6531, 7, 0, 0, 0, -5, 1},
                                           RealMeshExpectation{"nonmanifold-vierbein.obj", 75, 1, 20, 0, 0, kNotStated,
                                                               kNotStated}),
                         // ctest lists each case by its file: Manifest/RealMeshInfo.MatchesManifest/bunny_3k_off
                         [](const ::testing::TestParamInfo<RealMeshExpectation>& param_info) {
                           std::string name = param_info.param.file;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(Topology, NonManifoldRealMeshes) {
  Mesh m;
  if (!test::load_data("nonmanifold-vertex-hourglass.obj", m)) return;
  const MeshReport r = analyze(m);
  EXPECT_EQ(r.nonmanifold_vertices, 1);
  EXPECT_EQ(r.nonmanifold_edges, 0);
  EXPECT_EQ(r.euler_characteristic, 3);
  EXPECT_EQ(r.boundary_loops, 0);
}

TEST(Topology, InwardAortaHasNegativeVolume) {
  Mesh m;
  if (!test::load_data("aorta-open-6k.stl", m)) return;
  // Open ends: the signed volume is not a true volume, but the inward orientation
  // of the vmtk meshes still shows as a negative sign of the closed-mesh formula on
  // the (nearly closed) surface.
  const MeshReport r = analyze(m);
  EXPECT_LT(r.signed_volume, 0);
  EXPECT_LT(r.min_angle_deg, 1.0);  // marching-cubes slivers
  bool warned = false;
  for (const auto& w : r.warnings) warned |= w.find("badly shaped") != std::string::npos;
  EXPECT_TRUE(warned);
}
