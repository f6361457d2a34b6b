// Slices through volumes (image/volume_slice.h): placement in the patient frame,
// trilinear sampling (exact on a linear field, whatever the volume's direction),
// window/level, extent and the default window's quantiles.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/image/volume_slice.h"

using namespace meshpde;

namespace {

// A volume whose value is a linear function of the LPS position: trilinear sampling
// reproduces it exactly, so every pixel has a known value.
Volume linear_volume(const Eigen::Matrix3d& direction, const Eigen::Vector3d& gradient, double offset,
                     const Eigen::Vector3d& spacing = Eigen::Vector3d(0.8, 1.1, 1.7)) {
  Volume v;
  v.dims = {23, 17, 11};
  v.spacing = spacing;
  v.origin = Eigen::Vector3d(-9.5, 4.0, -30.0);
  v.direction = direction;
  v.values.resize(v.num_voxels());
  for (int k = 0; k < v.dims[2]; ++k)
    for (int j = 0; j < v.dims[1]; ++j)
      for (int i = 0; i < v.dims[0]; ++i)
        v.values[static_cast<std::size_t>(i + v.dims[0] * (j + v.dims[1] * k))] =
            static_cast<float>(gradient.dot(v.index_to_lps(Eigen::Vector3d(i, j, k))) + offset);
  return v;
}

}  // namespace

TEST(VolumeSlice, PixelsAreTheWindowedValueAtTheirPointInEitherFrame) {
  const Eigen::Matrix3d oblique = (Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix() *
                                  Eigen::Vector3d(-1, -1, 1).asDiagonal();
  const Eigen::Vector3d g(0.7, -0.3, 0.45);
  const Volume vol = linear_volume(oblique, g, 5.0);
  for (const Space space : {Space::LPS, Space::RAS})
    for (const SliceAxis axis : {SliceAxis::Axial, SliceAxis::Coronal, SliceAxis::Sagittal}) {
      const auto [lo, hi] = volume_bounds(vol, space);
      const int n = axis == SliceAxis::Axial ? 2 : axis == SliceAxis::Coronal ? 1 : 0;
      SliceParams p;
      p.axis = axis;
      p.position = 0.4 * lo[n] + 0.6 * hi[n];
      p.level = 5.0;
      p.window = 30.0;
      const Slice s = slice_volume(vol, space, p);
      ASSERT_GT(s.width, 1);
      ASSERT_GT(s.height, 1);
      EXPECT_NEAR(s.origin[n], p.position, 1e-12);
      EXPECT_EQ(s.u[n], 0.0);
      EXPECT_EQ(s.v[n], 0.0);
      int inside = 0, outside = 0, exact = 0;
      for (int b = 0; b < s.height; ++b)
        for (int a = 0; a < s.width; ++a) {
          const Eigen::Vector3d x = s.origin + a * s.u + b * s.v;
          const std::uint8_t got = s.pixels[static_cast<std::size_t>(b * s.width + a)];
          if (!vol.sample(x, space)) {
            ++outside;
            EXPECT_EQ(got, 0) << "outside the volume at " << x.transpose();
            continue;
          }
          ++inside;
          const double value = g.dot(to_lps(x, space)) + 5.0;
          const double want = std::clamp(255.0 * (value - (p.level - p.window / 2)) / p.window, 0.0, 255.0);
          EXPECT_LE(std::abs(got - want), 0.5 + 1e-6) << to_string(axis) << " pixel " << a << "," << b;
          exact += std::abs(got - want) <= 0.5 + 1e-6;
        }
      // An oblique volume fills only part of its bounding box's plane.
      EXPECT_GT(inside, 20) << to_string(axis);
      EXPECT_GT(outside, 0) << to_string(axis);
      EXPECT_EQ(exact, inside);
    }
}

TEST(VolumeSlice, AnAxisAlignedSliceCoversTheVolumeOnItsVoxelGrid) {
  const Volume v = linear_volume(Eigen::Vector3d(-1, -1, 1).asDiagonal(), Eigen::Vector3d(0, 0, 1), 0,
                                 Eigen::Vector3d(0.5, 0.5, 2.0));
  const auto [lo, hi] = volume_bounds(v, Space::RAS);
  // RAS of an LPS grid whose i and j axes point to -L and -P: +x and +y in RAS.
  EXPECT_NEAR(lo.x(), -v.origin.x(), 1e-12);
  EXPECT_NEAR(hi.x(), -v.origin.x() + 0.5 * (v.dims[0] - 1), 1e-12);
  SliceParams p;
  p.position = v.origin.z() + 2.0 * 3;  // through voxel layer k = 3
  p.window = 100;
  p.level = 0;
  const Slice s = slice_volume(v, Space::RAS, p);
  EXPECT_EQ(s.width, v.dims[0]);
  EXPECT_EQ(s.height, v.dims[1]);
  EXPECT_NEAR(s.u.norm(), 0.5, 1e-12);
  // Every pixel lies inside and has the layer's value (z), windowed.
  const double want = 255.0 * (p.position - (-50.0)) / 100.0;
  for (std::uint8_t x : s.pixels) EXPECT_NEAR(x, want, 0.5 + 1e-9);
  // A plane beyond the volume: the same extent, every pixel 0.
  p.position = hi.z() + 1;
  const Slice beyond = slice_volume(v, Space::RAS, p);
  EXPECT_EQ(beyond.width, s.width);
  EXPECT_TRUE(std::all_of(beyond.pixels.begin(), beyond.pixels.end(), [](std::uint8_t x) { return x == 0; }));
}

TEST(VolumeSlice, LargeSlicesAreCappedAndBadParametersRefused) {
  const Volume v = linear_volume(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1, 0, 0), 0);
  SliceParams p;
  p.axis = SliceAxis::Coronal;
  p.position = v.origin.y() + 3;
  p.window = 10;
  p.pixel_mm = 0.01;
  p.max_side = 64;
  const Slice s = slice_volume(v, Space::LPS, p);
  EXPECT_LE(s.width, 64);
  EXPECT_LE(s.height, 64);
  EXPECT_GE(s.width, 60);  // the longer side uses the cap
  p.position = NAN;
  EXPECT_THROW(slice_volume(v, Space::LPS, p), InputError);
  EXPECT_THROW(parse_slice_axis("transverse"), InputError);
  EXPECT_EQ(parse_slice_axis("sagittal"), SliceAxis::Sagittal);
}

TEST(VolumeSlice, QuantilesOfTheVoxelValues) {
  Volume v;
  v.dims = {101, 1, 1};
  for (int i = 0; i <= 100; ++i) v.values.push_back(static_cast<float>(100 - i));
  v.values[50] = NAN;  // ignored
  const auto q = volume_quantiles(v, {0.0, 0.5, 1.0});
  EXPECT_EQ(q[0], 0.0);
  EXPECT_EQ(q[2], 100.0);
  EXPECT_NEAR(q[1], 50.0, 1.0);
}
