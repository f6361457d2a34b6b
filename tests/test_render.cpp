#include <gtest/gtest.h>

#include <filesystem>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/viz/render.h"
#include "test_support.h"

using namespace meshpde;

namespace {

int count(const Image& img, auto pred) {
  int n = 0;
  for (std::size_t k = 0; k < img.rgb.size(); k += 3) n += pred(img.rgb[k], img.rgb[k + 1], img.rgb[k + 2]);
  return n;
}

}  // namespace

TEST(Render, ShadesTheSurfaceAndRoundTripsThroughPng) {
  const GeneratedMesh g = icosphere(3);
  const Image img = render(g.V, g.F, RenderOptions{.width = 200, .height = 150});
  ASSERT_EQ(img.rgb.size(), 200u * 150u * 3u);
  const int surface = count(img, [](int r, int gg, int b) { return !(r == 255 && gg == 255 && b == 255); });
  // An orthographic sphere filling the height covers about pi/4 of a 150 x 150 square.
  EXPECT_GT(surface, 0.6 * 150 * 150 * M_PI / 4);
  EXPECT_LT(surface, 1.4 * 150 * 150 * M_PI / 4);
  const auto path = test::scratch_path("render-test.png");
  write_png(path, img);
  const Image back = read_png(path);
  EXPECT_EQ(back.width, 200);
  EXPECT_EQ(back.rgb, img.rgb);
}

TEST(Render, FieldColoursArrowsAndLegend) {
  const GeneratedMesh g = icosphere(3);
  RenderOptions o{.width = 320, .height = 240, .elevation_deg = 0};
  o.field = g.V.col(1);  // y: low at the bottom, high at the top
  o.field_name = "height";
  const Image img = render(g.V, g.F, o);
  // Viridis ends: dark purple (low) and yellow (high) both appear.
  EXPECT_GT(count(img, [](int r, int gg, int b) { return r > 200 && gg > 180 && b < 90; }), 50);
  EXPECT_GT(count(img, [](int r, int gg, int b) { return r < 90 && gg < 40 && b > 60; }), 50);
  const auto red = [](int r, int gg, int b) { return r > 180 && gg < 60 && b < 60; };
  EXPECT_EQ(count(img, red), 0);
  // One outward arrow at the vertex facing the camera (azimuth 0, elevation 0, y up:
  // the camera looks from +z).
  int front = 0;
  g.V.col(2).maxCoeff(&front);
  o.vectors = Eigen::MatrixX3d::Zero(g.V.rows(), 3);
  o.vectors.row(front) = g.V.row(front) + Eigen::RowVector3d(0.5, 0, 0);
  o.arrow_vertices = {front};
  o.field.resize(0);
  o.azimuth_deg = 0;
  EXPECT_GT(count(render(g.V, g.F, o), red), 20);
  EXPECT_THROW(render(g.V, g.F, RenderOptions{.width = 4, .height = 4}), InputError);
  RenderOptions bad;
  bad.field = Eigen::VectorXd::Zero(3);
  EXPECT_THROW(render(g.V, g.F, bad), InputError);
}

// The legend's labels stay inside the image at any size: long ones ("-0.9608") in a
// small image once ran off its right edge.
TEST(Render, LegendLabelsFitInsideSmallImages) {
  const GeneratedMesh g = icosphere(2);
  const int sizes[3][2] = {{320, 240}, {200, 150}, {960, 720}};
  for (const auto& size : sizes) {
    const int w = size[0], h = size[1];
    RenderOptions o{.width = w, .height = h};
    o.field = g.V.col(1);
    o.field_name = "curvature";
    o.range = std::pair{-0.9608, 1.51};
    const Image img = render(g.V, g.F, o);
    // Text is drawn in dark ink (0.1): none in the last two columns, and some in the
    // right third (the labels are drawn).
    int edge = 0, right = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 2 * w / 3; x < w; ++x) {
        const std::uint8_t* p = &img.rgb[3 * (static_cast<std::size_t>(y) * w + x)];
        const bool ink = p[0] < 40 && p[1] < 40 && p[2] < 40;
        right += ink;
        edge += ink && x >= w - 2;
      }
    EXPECT_EQ(edge, 0) << w << "x" << h;
    EXPECT_GT(right, 40) << w << "x" << h;
  }
}

TEST(Render, ColormapEndpoints) {
  EXPECT_NEAR(colormap(Colormap::Viridis, 0)[0], 0.267, 1e-9);
  EXPECT_NEAR(colormap(Colormap::Viridis, 1)[1], 0.906, 1e-9);
  EXPECT_NEAR(colormap(Colormap::Coolwarm, 0.5)[0], 0.865, 1e-9);
  EXPECT_EQ(colormap(Colormap::Viridis, -3), colormap(Colormap::Viridis, 0));
}
