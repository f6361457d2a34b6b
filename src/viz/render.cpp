#include "meshpde/viz/render.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "font5x7.h"
#include "meshpde/core/errors.h"

namespace meshpde {

Colormap parse_colormap(const std::string& name) {
  if (name == "viridis") return Colormap::Viridis;
  if (name == "coolwarm") return Colormap::Coolwarm;
  throw InputError(fmt::format("unknown colormap '{}' (expected viridis or coolwarm)", name));
}

int parse_up_axis(const std::string& name) {
  if (name == "x") return 0;
  if (name == "y") return 1;
  if (name == "z") return 2;
  throw InputError(fmt::format("unknown up axis '{}' (expected x, y or z)", name));
}

Eigen::Vector3d colormap(Colormap map, double t) {
  // Anchor colours sampled from the published colormaps, linearly interpolated.
  static const double viridis[11][3] = {{0.267, 0.005, 0.329}, {0.283, 0.141, 0.458}, {0.254, 0.265, 0.530},
                                        {0.207, 0.372, 0.553}, {0.164, 0.471, 0.558}, {0.128, 0.567, 0.551},
                                        {0.135, 0.659, 0.518}, {0.267, 0.749, 0.441}, {0.478, 0.821, 0.318},
                                        {0.741, 0.873, 0.150}, {0.993, 0.906, 0.144}};
  static const double coolwarm[5][3] = {{0.230, 0.299, 0.754},
                                        {0.552, 0.690, 0.996},
                                        {0.865, 0.865, 0.865},
                                        {0.958, 0.603, 0.482},
                                        {0.706, 0.016, 0.150}};
  if (!std::isfinite(t)) return {0.5, 0.5, 0.5};
  t = std::clamp(t, 0.0, 1.0);
  const auto* table = map == Colormap::Viridis ? viridis : coolwarm;
  const int n = map == Colormap::Viridis ? 11 : 5;
  const double x = t * (n - 1);
  const int k = std::min(static_cast<int>(x), n - 2);
  const double f = x - k;
  return {table[k][0] * (1 - f) + table[k + 1][0] * f, table[k][1] * (1 - f) + table[k + 1][1] * f,
          table[k][2] * (1 - f) + table[k + 1][2] * f};
}

namespace {

struct Canvas {
  int w, h;
  std::vector<float> rgb;    // linear 0..1
  std::vector<float> depth;  // larger is closer
  Canvas(int width, int height)
      : w(width),
        h(height),
        rgb(3 * std::size_t(width) * height, 1.0f),
        depth(std::size_t(width) * height, -std::numeric_limits<float>::infinity()) {}
  void put(int x, int y, float z, const Eigen::Vector3d& c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    const std::size_t k = std::size_t(y) * w + x;
    if (z < depth[k]) return;
    depth[k] = z;
    for (int i = 0; i < 3; ++i) rgb[3 * k + i] = static_cast<float>(c[i]);
  }
};

void draw_line(Canvas& cv, Eigen::Vector3d a, Eigen::Vector3d b, const Eigen::Vector3d& color, int thickness) {
  const double len = std::max(std::abs(b.x() - a.x()), std::abs(b.y() - a.y()));
  const int n = std::max(1, static_cast<int>(std::ceil(len)));
  const int r = thickness / 2;
  for (int s = 0; s <= n; ++s) {
    const Eigen::Vector3d p = a + (b - a) * (double(s) / n);
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx)
        cv.put(static_cast<int>(std::lround(p.x())) + dx, static_cast<int>(std::lround(p.y())) + dy,
               static_cast<float>(p.z()), color);
  }
}

void draw_text(Image& img, int x, int y, const std::string& text, int scale, const Eigen::Vector3d& color) {
  const auto& font = detail::font5x7();
  int cx = x;
  for (char ch : text) {
    const char up = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    const auto it = font.find(up);
    if (it != font.end())
      for (int row = 0; row < 7; ++row)
        for (int col = 0; col < 5; ++col)
          if (it->second[row] & (1 << (4 - col)))
            for (int sy = 0; sy < scale; ++sy)
              for (int sx = 0; sx < scale; ++sx) {
                const int px = cx + col * scale + sx, py = y + row * scale + sy;
                if (px < 0 || py < 0 || px >= img.width || py >= img.height) continue;
                for (int c = 0; c < 3; ++c)
                  img.rgb[3 * (std::size_t(py) * img.width + px) + c] = static_cast<std::uint8_t>(255 * color[c]);
              }
    cx += 6 * scale;
  }
}

std::string label(double v) {
  return fmt::format("{:.4g}", v);
}

}  // namespace

Image render(const Positions& V, const Triangles& F, const RenderOptions& o) {
  if (o.width < 16 || o.height < 16 || o.width > 16384 || o.height > 16384)
    throw InputError(fmt::format("image size {} x {} is outside 16..16384", o.width, o.height));
  const Eigen::Index nv = V.rows();
  if (o.field.size() != 0 && o.field.size() != nv)
    throw InputError(fmt::format("field has {} values for {} vertices", o.field.size(), nv));
  if (o.vectors.rows() != 0 && o.vectors.rows() != nv)
    throw InputError(fmt::format("vector field has {} rows for {} vertices", o.vectors.rows(), nv));
  if (o.up_axis < 0 || o.up_axis > 2) throw InputError("up axis must be 0, 1 or 2");
  const int ss = std::clamp(o.supersample, 1, 4);
  const bool legend = o.field.size() > 0;
  const int W = o.width * ss, H = o.height * ss;
  Canvas cv(W, H);

  // Camera: orthographic, looking at the bounding-box centre along -eye.
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  up[o.up_axis] = 1;
  const Eigen::Vector3d w0 = o.up_axis == 1   ? Eigen::Vector3d(0, 0, 1)
                             : o.up_axis == 2 ? Eigen::Vector3d(0, -1, 0)
                                              : Eigen::Vector3d(0, 1, 0);
  const double az = o.azimuth_deg * M_PI / 180, el = o.elevation_deg * M_PI / 180;
  const Eigen::Vector3d eye =
      (std::cos(el) * (std::cos(az) * w0 + std::sin(az) * up.cross(w0)) + std::sin(el) * up).normalized();
  const Eigen::Vector3d xs = up.cross(eye).normalized(), ys = eye.cross(xs);
  const Eigen::Vector3d lo = V.colwise().minCoeff().transpose(), hi = V.colwise().maxCoeff().transpose();
  const Eigen::Vector3d box_centre = 0.5 * (lo + hi);
  const Eigen::Vector3d centre = o.center ? *o.center : box_centre;
  double extent_x = 1e-30, extent_y = 1e-30;
  for (Eigen::Index i = 0; i < nv; ++i) {
    const Eigen::Vector3d d = V.row(i).transpose() - box_centre;
    extent_x = std::max(extent_x, std::abs(d.dot(xs)));
    extent_y = std::max(extent_y, std::abs(d.dot(ys)));
  }
  const double draw_w = W * (legend ? 0.72 : 0.94), draw_h = H * (o.title.empty() ? 0.92 : 0.84);
  const double scale = o.zoom * std::min(draw_w / (2 * extent_x), draw_h / (2 * extent_y));
  const double cx = W * (legend ? 0.39 : 0.5), cy = H * (o.title.empty() ? 0.5 : 0.54);
  auto project = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = p - centre;
    return Eigen::Vector3d(cx + scale * d.dot(xs), cy - scale * d.dot(ys), d.dot(eye));
  };

  // Vertex normals (area-weighted) for smooth two-sided shading.
  Eigen::MatrixX3d N = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) N.row(F(f, k)) += n.transpose();
  }
  double fmin = 0, fmax = 1;
  if (legend) {
    if (o.range) {
      fmin = o.range->first;
      fmax = o.range->second;
    } else {
      fmin = o.field.minCoeff();
      fmax = o.field.maxCoeff();
    }
    if (!(fmax > fmin)) fmax = fmin + 1;
  }
  // The legend's layout (output pixels): a bar at 80 % of the width with its labels to
  // the right, smaller or with the bar moved left where they would run off the image.
  const int ts = std::max(1, o.height / 360);
  const std::string labels[3] = {label(fmax), label(0.5 * (fmin + fmax)), label(fmin)};
  std::size_t label_chars = 0;
  for (const std::string& s : labels) label_chars = std::max(label_chars, s.size());
  const int bar_w = std::max(2, static_cast<int>(o.width * 0.035)), gap = std::max(2, o.width / 100);
  const auto labels_w = [&](int k) { return static_cast<int>(label_chars) * 6 * k; };
  int label_scale = ts + 1, bar_x = static_cast<int>(o.width * 0.80);
  if (bar_x + bar_w + gap + labels_w(label_scale) > o.width - 2) label_scale = ts;
  bar_x = std::max(0, std::min(bar_x, o.width - 2 - labels_w(label_scale) - gap - bar_w));
  const Eigen::Vector3d light = (eye + 0.35 * ys - 0.25 * xs).normalized();
  std::vector<Eigen::Vector3d> P(nv);
  for (Eigen::Index i = 0; i < nv; ++i) P[i] = project(V.row(i).transpose());

  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int i0 = F(f, 0), i1 = F(f, 1), i2 = F(f, 2);
    const Eigen::Vector3d &a = P[i0], &b = P[i1], &c = P[i2];
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(W - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(H - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        double l0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) / area;
        double l1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) / area;
        double l2 = 1 - l0 - l1;
        if (l0 < 0 || l1 < 0 || l2 < 0) continue;
        const double z = l0 * a.z() + l1 * b.z() + l2 * c.z();
        Eigen::Vector3d n = l0 * N.row(i0) + l1 * N.row(i1) + l2 * N.row(i2);
        const double nn = n.norm();
        const double lambert = nn > 0 ? std::abs(n.dot(light)) / nn : 1.0;
        const double shade = 0.3 + 0.7 * lambert;
        Eigen::Vector3d base(0.72, 0.76, 0.86);
        if (legend) {
          const double v = l0 * o.field[i0] + l1 * o.field[i1] + l2 * o.field[i2];
          base = colormap(o.colormap, (v - fmin) / (fmax - fmin));
        }
        cv.put(x, y, static_cast<float>(z), base * shade);
      }
  }
  const double bias = 1e-3 * (hi - lo).norm();
  if (o.wireframe) {
    const Mesh mesh(V, F);
    for (int e = 0; e < mesh.num_edges(); ++e) {
      Eigen::Vector3d a = P[mesh.edges()(e, 0)], b = P[mesh.edges()(e, 1)];
      a.z() += bias;
      b.z() += bias;
      draw_line(cv, a, b, Eigen::Vector3d(0.15, 0.15, 0.2), 1);
    }
  }
  // Arrows, depth-tested against the surface so the hidden side stays hidden.
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> arrows = o.extra_arrows;
  if (o.vectors.rows() > 0) {
    std::vector<int> which = o.arrow_vertices;
    if (which.empty()) {
      for (Eigen::Index i = 0; i < nv; ++i)
        if (o.vectors.row(i).norm() > 0) which.push_back(static_cast<int>(i));
      if (o.max_arrows > 0 && static_cast<int>(which.size()) > o.max_arrows) {
        std::vector<int> kept;
        const double stride = double(which.size()) / o.max_arrows;
        for (int k = 0; k < o.max_arrows; ++k) kept.push_back(which[static_cast<std::size_t>(k * stride)]);
        which.swap(kept);
      }
    }
    double longest = 0;
    for (int i : which) longest = std::max(longest, o.vectors.row(i).norm());
    const double s = o.arrow_scale > 0 ? o.arrow_scale : (longest > 0 ? 0.1 * (hi - lo).norm() / longest : 0);
    for (int i : which) arrows.emplace_back(V.row(i).transpose(), s * o.vectors.row(i).transpose());
  }
  const int thick = std::max(1, ss);
  for (const auto& [start, vec] : arrows) {
    if (!(vec.norm() > 0)) continue;
    Eigen::Vector3d a = project(start), b = project(start + vec);
    a.z() += 4 * bias;
    b.z() += 4 * bias;
    draw_line(cv, a, b, o.arrow_color, thick);
    const Eigen::Vector2d d = (b.head<2>() - a.head<2>());
    const double len = d.norm();
    if (len < 2) continue;
    const Eigen::Vector2d u = d / len;
    const double head = std::min(0.35 * len, 6.0 * ss);
    for (const double sgn : {-1.0, 1.0}) {
      const double ang = sgn * 0.45;
      const Eigen::Vector2d r(std::cos(ang) * -u.x() - std::sin(ang) * -u.y(),
                              std::sin(ang) * -u.x() + std::cos(ang) * -u.y());
      draw_line(cv, b, Eigen::Vector3d(b.x() + head * r.x(), b.y() + head * r.y(), b.z()), o.arrow_color, thick);
    }
  }
  // Legend colour bar, drawn at full resolution.
  if (legend) {
    const int bx0 = bar_x * ss, bx1 = (bar_x + bar_w) * ss;
    const int by0 = static_cast<int>(H * 0.2), by1 = static_cast<int>(H * 0.8);
    for (int y = by0; y <= by1; ++y) {
      const Eigen::Vector3d c = colormap(o.colormap, double(by1 - y) / (by1 - by0));
      for (int x = bx0; x <= bx1; ++x) cv.put(x, y, std::numeric_limits<float>::max(), c);
    }
    for (int x = bx0 - ss; x <= bx1 + ss; ++x)
      for (int t = 0; t < ss; ++t) {
        cv.put(x, by0 - ss + t, std::numeric_limits<float>::max(), Eigen::Vector3d::Zero());
        cv.put(x, by1 + t + 1, std::numeric_limits<float>::max(), Eigen::Vector3d::Zero());
      }
  }
  // Box-filter down to the output size.
  Image img;
  img.width = o.width;
  img.height = o.height;
  img.rgb.resize(3 * std::size_t(o.width) * o.height);
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x)
      for (int c = 0; c < 3; ++c) {
        double acc = 0;
        for (int sy = 0; sy < ss; ++sy)
          for (int sx = 0; sx < ss; ++sx) acc += cv.rgb[3 * (std::size_t(y * ss + sy) * W + (x * ss + sx)) + c];
        img.rgb[3 * (std::size_t(y) * o.width + x) + c] =
            static_cast<std::uint8_t>(std::lround(255 * std::clamp(acc / (ss * ss), 0.0, 1.0)));
      }
  if (!o.title.empty()) draw_text(img, 12 * ts, 10 * ts, o.title, 2 * ts, Eigen::Vector3d(0.1, 0.1, 0.1));
  if (legend) {
    const int ly0 = static_cast<int>(o.height * 0.2), ly1 = static_cast<int>(o.height * 0.8);
    const Eigen::Vector3d ink(0.1, 0.1, 0.1);
    // Keep the legend title inside the image: right-align it when it is long.
    const int title_w = static_cast<int>(o.field_name.size()) * 6 * (ts + 1);
    const int lx = std::min(bar_x, o.width - title_w - 8);
    draw_text(img, std::max(0, lx), ly0 - 22 * ts, o.field_name, ts + 1, ink);
    const int tx = bar_x + bar_w + gap;
    draw_text(img, tx, ly0 - 3 * ts, labels[0], label_scale, ink);
    draw_text(img, tx, (ly0 + ly1) / 2 - 3 * ts, labels[1], label_scale, ink);
    draw_text(img, tx, ly1 - 3 * ts, labels[2], label_scale, ink);
  }
  return img;
}

Image side_by_side(const std::vector<Image>& images) {
  Image out;
  for (const auto& im : images) {
    out.width += im.width;
    out.height = std::max(out.height, im.height);
  }
  out.rgb.assign(3 * std::size_t(out.width) * out.height, 255);
  int x0 = 0;
  for (const auto& im : images) {
    for (int y = 0; y < im.height; ++y)
      std::copy_n(im.rgb.begin() + 3 * std::size_t(y) * im.width, 3 * im.width,
                  out.rgb.begin() + 3 * (std::size_t(y) * out.width + x0));
    x0 += im.width;
  }
  return out;
}

}  // namespace meshpde
