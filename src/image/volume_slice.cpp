#include "meshpde/image/volume_slice.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "meshpde/core/errors.h"

namespace meshpde {

SliceAxis parse_slice_axis(std::string_view text) {
  if (text == "axial") return SliceAxis::Axial;
  if (text == "coronal") return SliceAxis::Coronal;
  if (text == "sagittal") return SliceAxis::Sagittal;
  throw InputError(fmt::format("slice axis '{}': expected axial, coronal or sagittal", text));
}

const char* to_string(SliceAxis axis) {
  switch (axis) {
    case SliceAxis::Axial:
      return "axial";
    case SliceAxis::Coronal:
      return "coronal";
    case SliceAxis::Sagittal:
      return "sagittal";
  }
  return "?";
}

namespace {

// RAS <-> LPS is its own inverse: negate x and y.
Eigen::Vector3d flip(const Eigen::Vector3d& p, Space space) {
  return to_lps(p, space);
}

}  // namespace

std::pair<Eigen::Vector3d, Eigen::Vector3d> volume_bounds(const Volume& volume, Space space) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? volume.dims[0] - 1 : 0, (c & 2) ? volume.dims[1] - 1 : 0,
                              (c & 4) ? volume.dims[2] - 1 : 0);
    const Eigen::Vector3d p = flip(volume.index_to_lps(ijk), space);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

Slice slice_volume(const Volume& volume, Space space, const SliceParams& p) {
  if (!std::isfinite(p.position) || !std::isfinite(p.window) || !std::isfinite(p.level) || !std::isfinite(p.pixel_mm))
    throw InputError("slice: position, window, level and pixel size must be finite");
  const int normal = p.axis == SliceAxis::Axial ? 2 : p.axis == SliceAxis::Coronal ? 1 : 0;
  const int ua = normal == 0 ? 1 : 0, va = normal == 2 ? 1 : 2;  // in-plane axes, in order
  const auto [lo, hi] = volume_bounds(volume, space);
  double pixel = p.pixel_mm > 0 ? p.pixel_mm : volume.spacing.minCoeff();
  const int max_side = std::max(1, p.max_side);
  const double extent_u = hi[ua] - lo[ua], extent_v = hi[va] - lo[va];
  pixel = std::max({pixel, extent_u / max_side, extent_v / max_side});
  Slice s;
  s.axis = p.axis;
  s.position = p.position;
  s.width = std::min(max_side, static_cast<int>(std::floor(extent_u / pixel)) + 1);
  s.height = std::min(max_side, static_cast<int>(std::floor(extent_v / pixel)) + 1);
  s.origin = lo;
  s.origin[normal] = p.position;
  s.u = Eigen::Vector3d::Unit(ua) * pixel;
  s.v = Eigen::Vector3d::Unit(va) * pixel;
  s.pixels.assign(static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height), 0);
  // The window: level +- window / 2, or the volume's whole range.
  double wlo = p.level - p.window / 2, whi = p.level + p.window / 2;
  if (!(p.window > 0)) {
    const auto q = volume_quantiles(volume, {0.0, 1.0});
    wlo = q[0];
    whi = q[1] > q[0] ? q[1] : q[0] + 1;
  }
  const double scale = 255.0 / (whi - wlo);
  // Continuous voxel index is affine in the pixel: ijk = i0 + a di + b dj, so each
  // sample costs one trilinear lookup and no matrix product.
  const auto index_of = [&](const Eigen::Vector3d& x) { return volume.lps_to_index(flip(x, space)); };
  const Eigen::Vector3d i0 = index_of(s.origin), di = index_of(s.origin + s.u) - i0, dj = index_of(s.origin + s.v) - i0;
  const int nx = volume.dims[0], ny = volume.dims[1], nz = volume.dims[2];
  const std::size_t sx = 1, sy = static_cast<std::size_t>(nx), sz = static_cast<std::size_t>(nx) * ny;
  const float* val = volume.values.data();
  const double eps = 1e-9;
  for (int b = 0; b < s.height; ++b) {
    const Eigen::Vector3d row = i0 + b * dj;
    std::uint8_t* out = s.pixels.data() + static_cast<std::size_t>(b) * s.width;
    for (int a = 0; a < s.width; ++a) {
      const Eigen::Vector3d q = row + a * di;
      // Inside the hull of voxel centres (a sliver of rounding allowed at its faces).
      if (!(q.x() >= -eps && q.y() >= -eps && q.z() >= -eps && q.x() <= nx - 1 + eps && q.y() <= ny - 1 + eps &&
            q.z() <= nz - 1 + eps))
        continue;
      const double x = std::clamp(q.x(), 0.0, nx - 1.0), y = std::clamp(q.y(), 0.0, ny - 1.0),
                   z = std::clamp(q.z(), 0.0, nz - 1.0);
      const int i = std::min(static_cast<int>(x), std::max(nx - 2, 0)),
                j = std::min(static_cast<int>(y), std::max(ny - 2, 0)),
                k = std::min(static_cast<int>(z), std::max(nz - 2, 0));
      const double fx = x - i, fy = y - j, fz = z - k;
      const std::size_t base = i * sx + j * sy + k * sz;
      // One voxel thick along an axis: its neighbour is itself.
      const std::size_t ox = nx > 1 ? sx : 0, oy = ny > 1 ? sy : 0, oz = nz > 1 ? sz : 0;
      const double c00 = val[base] + fx * (val[base + ox] - val[base]);
      const double c10 = val[base + oy] + fx * (val[base + oy + ox] - val[base + oy]);
      const double c01 = val[base + oz] + fx * (val[base + oz + ox] - val[base + oz]);
      const double c11 = val[base + oz + oy] + fx * (val[base + oz + oy + ox] - val[base + oz + oy]);
      const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
      const double value = c0 + fz * (c1 - c0);
      // A window so narrow or wide that the scale overflows maps NaN to black.
      const double t = (value - wlo) * scale;
      if (!(t > 0)) continue;
      out[a] = static_cast<std::uint8_t>(std::lround(std::min(t, 255.0)));
    }
  }
  return s;
}

std::vector<double> volume_quantiles(const Volume& volume, const std::vector<double>& q, std::size_t samples) {
  const std::size_t n = volume.values.size();
  const std::size_t stride = std::max<std::size_t>(1, n / std::max<std::size_t>(1, samples));
  std::vector<float> pick;
  pick.reserve(n / stride + 1);
  for (std::size_t i = 0; i < n; i += stride)
    if (std::isfinite(volume.values[i])) pick.push_back(volume.values[i]);
  std::vector<double> out;
  for (double t : q) {
    if (pick.empty()) {
      out.push_back(0);
      continue;
    }
    const std::size_t k =
        std::min(pick.size() - 1, static_cast<std::size_t>(std::llround(std::clamp(t, 0.0, 1.0) * (pick.size() - 1))));
    std::nth_element(pick.begin(), pick.begin() + static_cast<std::ptrdiff_t>(k), pick.end());
    out.push_back(pick[k]);
  }
  return out;
}

}  // namespace meshpde
