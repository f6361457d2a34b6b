// image/voxelize.h: which voxel centres lie inside a closed surface, against an
// independent construction (a box's inequalities; a ray-parity count along a random
// direction) on oblique grids, whichever way the triangles face.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "meshpde/core/errors.h"
#include "meshpde/image/voxelize.h"
#include "meshpde/mesh/generators.h"
#include "test_data.h"

namespace meshpde {
namespace {

// An oblique grid: direction turned about (1, 2, 3), anisotropic spacing.
Volume oblique_grid(std::array<int, 3> dims, Eigen::Vector3d spacing, Eigen::Vector3d origin, double angle = 0.4) {
  Volume g;
  g.dims = dims;
  g.spacing = spacing;
  g.origin = origin;
  g.direction = Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  return g;
}

// A box [lo, hi] as 12 outward triangles.
GeneratedMesh box_mesh(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  GeneratedMesh m;
  m.V.resize(8, 3);
  for (int k = 0; k < 8; ++k)
    m.V.row(k) << (k & 1 ? hi.x() : lo.x()), (k & 2 ? hi.y() : lo.y()), (k & 4 ? hi.z() : lo.z());
  m.F.resize(12, 3);
  m.F << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  return m;
}

std::size_t count(const std::vector<std::uint8_t>& m) {
  std::size_t n = 0;
  for (const auto x : m) n += x;
  return n;
}

// Ray parity from p along a fixed direction (Moller-Trumbore): an independent inside test.
bool inside_by_ray(const Positions& V, const Triangles& F, const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = Eigen::Vector3d(0.5773, 0.6123, 0.5402).normalized();
  int hits = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3d e1 = b - a, e2 = c - a, h = d.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-14) continue;
    const Eigen::Vector3d s = p - a;
    const double u = s.dot(h) / det;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (v < 0 || u + v > 1) continue;
    if (e2.dot(q) / det > 0) ++hits;
  }
  return hits % 2 == 1;
}

TEST(Voxelize, ABoxOnAnObliqueGridHoldsExactlyTheCentresInsideIt) {
  const Volume g = oblique_grid({30, 24, 18}, {0.7, 0.9, 1.3}, {-12, -9, -8});
  const Eigen::Vector3d lo(-4.3, -3.1, -2.2), hi(5.2, 4.4, 3.7);
  const GeneratedMesh box = box_mesh(lo, hi);
  const auto mask = voxelize(box.V, box.F, g);
  std::size_t expected = 0;
  std::size_t v = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++v) {
        const Eigen::Vector3d p = g.index_to_lps(Eigen::Vector3d(i, j, k));
        const bool in = (p.array() > lo.array()).all() && (p.array() < hi.array()).all();
        expected += in;
        ASSERT_EQ(mask[v], in) << "voxel " << i << " " << j << " " << k;
      }
  EXPECT_GT(expected, 300u);
  // The same with every triangle reversed (inward-facing surfaces, as vmtk writes them).
  Triangles reversed = box.F;
  reversed.col(1).swap(reversed.col(2));
  EXPECT_EQ(voxelize(box.V, reversed, g), mask);
}

TEST(Voxelize, ASphereAgreesWithRayParityAtEveryVoxel) {
  GeneratedMesh s = icosphere(3, 6.0);
  s.V.rowwise() += Eigen::RowVector3d(0.37, -0.21, 0.13);
  const Volume g = oblique_grid({22, 20, 16}, {0.8, 0.75, 1.0}, {-9, -8.5, -7.5}, 0.9);
  const auto mask = voxelize(s.V, s.F, g);
  std::size_t v = 0, in = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++v) {
        const bool expected = inside_by_ray(s.V, s.F, g.index_to_lps(Eigen::Vector3d(i, j, k)));
        in += expected;
        ASSERT_EQ(mask[v], expected) << "voxel " << i << " " << j << " " << k;
      }
  EXPECT_GT(in, 500u);
}

TEST(Voxelize, VerticesOnTheRowsLeaveNoStreaks) {
  // A box whose corners and edges lie exactly on voxel centres' rows (as a surface
  // extracted from the same grid does): every row still sums to zero, and the voxels
  // inside are those strictly inside the box (the faces pass through centres: a centre
  // on a face may go either way, but never a whole row beyond it).
  Volume g;
  g.dims = {20, 20, 20};
  const GeneratedMesh box = box_mesh(Eigen::Vector3d(3, 4, 5), Eigen::Vector3d(12, 15, 11));
  const auto mask = voxelize(box.V, box.F, g);
  std::size_t v = 0;
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i, ++v) {
        const bool strictly = i > 3 && i < 12 && j > 4 && j < 15 && k > 5 && k < 11;
        const bool outside = i < 3 || i > 12 || j < 4 || j > 15 || k < 5 || k > 11;
        if (strictly) {
          ASSERT_EQ(mask[v], 1) << i << " " << j << " " << k;
        }
        if (outside) {
          ASSERT_EQ(mask[v], 0) << i << " " << j << " " << k;
        }
      }
}

TEST(Voxelize, OverlapsAndNonManifoldSurfacesCountByWinding) {
  // Two overlapping spheres in one mesh: the overlap has winding 2 and is inside.
  GeneratedMesh a = icosphere(2, 4.0), b = icosphere(2, 4.0);
  b.V.rowwise() += Eigen::RowVector3d(3, 0, 0);
  Positions V(a.V.rows() + b.V.rows(), 3);
  V << a.V, b.V;
  Triangles F(a.F.rows() + b.F.rows(), 3);
  F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  Volume g;
  g.dims = {30, 20, 20};
  g.spacing = Eigen::Vector3d::Constant(0.5);
  g.origin = Eigen::Vector3d(-5, -5, -5);
  const auto both = voxelize(V, F, g);
  const auto only_a = voxelize(a.V, a.F, g);
  const auto only_b = voxelize(b.V, b.F, g);
  for (std::size_t v = 0; v < both.size(); ++v) ASSERT_EQ(both[v], only_a[v] || only_b[v]) << v;
  // The real hourglass (two icospheres sharing a vertex) is closed and voxelizes.
  if (!test::have_data("nonmanifold-vertex-hourglass.obj")) return;
  const MeshData h = read_mesh(test::data_dir() / "nonmanifold-vertex-hourglass.obj");
  Volume hg;
  hg.dims = {40, 40, 40};
  const Eigen::Vector3d lo = h.V.colwise().minCoeff(), hi = h.V.colwise().maxCoeff();
  hg.spacing = Eigen::Vector3d::Constant((hi - lo).maxCoeff() / 36);
  hg.origin = lo - 2 * hg.spacing;
  EXPECT_GT(count(voxelize(h.V, h.F, hg)), 100u);
}

TEST(Voxelize, OversamplingApproachesTheVolume) {
  GeneratedMesh s = icosphere(4, 5.0);
  Volume g;
  g.dims = {14, 14, 14};
  g.spacing = Eigen::Vector3d::Constant(1.0);
  g.origin = Eigen::Vector3d::Constant(-6.3);
  double volume = 0;
  for (Eigen::Index f = 0; f < s.F.rows(); ++f)
    volume += Eigen::Vector3d(s.V.row(s.F(f, 0)))
                  .dot(Eigen::Vector3d(s.V.row(s.F(f, 1))).cross(Eigen::Vector3d(s.V.row(s.F(f, 2))))) /
              6;
  const double e1 = std::abs(count(voxelize(s.V, s.F, g, 1)) - volume) / volume;
  // With K = 4 each voxel is 64 samples; the majority of them decides it.
  std::vector<std::uint8_t> fine = voxelize(s.V, s.F, g, 4);
  EXPECT_LT(std::abs(count(fine) - volume) / volume, 0.05);
  EXPECT_LT(e1, 0.1);
  EXPECT_THROW(voxelize(s.V, s.F, g, 0), InputError);
  EXPECT_THROW(voxelize(s.V, s.F, g, 9), InputError);
}

TEST(Voxelize, ABoxOfVoxelsDecidesOnlyThoseAndAgreesWithTheWholeGrid) {
  GeneratedMesh s = icosphere(3, 6.0);
  const Volume g = oblique_grid({20, 20, 20}, {0.8, 0.8, 0.8}, {-8, -8, -8});
  const auto all = voxelize(s.V, s.F, g);
  const VoxelBox box{{3, 5, 7}, {15, 12, 16}};
  const auto part = voxelize(s.V, s.F, g, 1, &box);
  std::size_t v = 0;
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i, ++v) {
        const bool in_box = i >= 3 && i < 15 && j >= 5 && j < 12 && k >= 7 && k < 16;
        ASSERT_EQ(part[v], in_box ? all[v] : 0) << i << " " << j << " " << k;
      }
  // The box around points: the voxels within the margin of them, clipped to the grid.
  const VoxelBox around = voxel_box_around(g, {g.index_to_lps(Eigen::Vector3d(2.2, 3.7, 19.6))}, 1.0);
  EXPECT_EQ(around.lo, (std::array<int, 3>{2, 3, 19}));
  EXPECT_EQ(around.hi, (std::array<int, 3>{4, 5, 20}));
  EXPECT_TRUE(voxel_box_around(g, {Eigen::Vector3d(1e3, 0, 0)}, 1.0).empty());
}

TEST(Voxelize, AnOpenSurfaceIsRefusedInWords) {
  GeneratedMesh s = icosphere(2, 5.0);
  Triangles open = s.F.topRows(s.F.rows() - 1);
  Volume g;
  g.dims = {8, 8, 8};
  try {
    voxelize(s.V, open, g);
    FAIL() << "an open surface was voxelized";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not closed (3 boundary edges)"), std::string::npos) << e.what();
  }
  Positions bad = s.V;
  bad(0, 0) = std::nan("");
  EXPECT_THROW(voxelize(bad, s.F, g), InputError);
}

}  // namespace
}  // namespace meshpde
