#include "meshpde/image/volume.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "meshpde/core/errors.h"

namespace meshpde {

Space parse_space(std::string_view text) {
  std::string t(text);
  std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
  if (t == "lps") return Space::LPS;
  if (t == "ras") return Space::RAS;
  throw InputError(fmt::format("unknown coordinate space '{}' (expected lps or ras)", text));
}

const char* to_string(Space space) {
  return space == Space::LPS ? "LPS" : "RAS";
}

Eigen::Vector3d Volume::index_to_lps(const Eigen::Vector3d& ijk) const {
  return origin + direction * spacing.cwiseProduct(ijk);
}

Eigen::Vector3d Volume::lps_to_index(const Eigen::Vector3d& p_lps) const {
  // direction is orthonormal for every format we read, but a sheared NIfTI sform is
  // legal, so invert it properly.
  return (direction.inverse() * (p_lps - origin)).cwiseQuotient(spacing);
}

namespace {

// Corner and weights of the trilinear cell holding continuous index x, or false
// when x lies outside [0, n-1] on some axis.
struct Cell {
  int i0[3];
  double t[3];
};

bool locate(const Volume& v, const Eigen::Vector3d& x, Cell& c) {
  for (int a = 0; a < 3; ++a) {
    const double n1 = v.dims[a] - 1;
    // 1e-6 voxel of slack: headers store geometry in float32, so a point computed
    // from it can land a rounding error outside the last voxel centre.
    if (!(x[a] >= -1e-6 && x[a] <= n1 + 1e-6)) return false;
    const double xa = std::clamp(x[a], 0.0, n1);
    int i = static_cast<int>(std::floor(xa));
    if (i >= v.dims[a] - 1) i = std::max(0, v.dims[a] - 2);
    c.i0[a] = i;
    c.t[a] = v.dims[a] == 1 ? 0.0 : xa - i;
  }
  return true;
}

double corner(const Volume& v, const Cell& c, int di, int dj, int dk) {
  const int i = std::min(c.i0[0] + di, v.dims[0] - 1);
  const int j = std::min(c.i0[1] + dj, v.dims[1] - 1);
  const int k = std::min(c.i0[2] + dk, v.dims[2] - 1);
  return v.at(i, j, k);
}

}  // namespace

std::optional<double> Volume::sample_lps(const Eigen::Vector3d& p_lps) const {
  Cell c{};
  if (!locate(*this, lps_to_index(p_lps), c)) return std::nullopt;
  double value = 0;
  for (int dk = 0; dk < 2; ++dk)
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di) {
        const double w = (di ? c.t[0] : 1 - c.t[0]) * (dj ? c.t[1] : 1 - c.t[1]) * (dk ? c.t[2] : 1 - c.t[2]);
        value += w * corner(*this, c, di, dj, dk);
      }
  return value;
}

std::optional<Eigen::Vector3d> Volume::gradient_lps(const Eigen::Vector3d& p_lps) const {
  Cell c{};
  if (!locate(*this, lps_to_index(p_lps), c)) return std::nullopt;
  Eigen::Vector3d g_index = Eigen::Vector3d::Zero();  // d value / d index
  for (int dk = 0; dk < 2; ++dk)
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di) {
        const double f = corner(*this, c, di, dj, dk);
        const double wi = di ? c.t[0] : 1 - c.t[0], wj = dj ? c.t[1] : 1 - c.t[1], wk = dk ? c.t[2] : 1 - c.t[2];
        g_index[0] += (di ? 1 : -1) * wj * wk * f;
        g_index[1] += (dj ? 1 : -1) * wi * wk * f;
        g_index[2] += (dk ? 1 : -1) * wi * wj * f;
      }
  // ijk = S^-1 D^-1 (p - o), so grad_p = D^-T S^-1 grad_ijk.
  return Eigen::Vector3d(direction.inverse().transpose() * g_index.cwiseQuotient(spacing));
}

void Volume::validate() const {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0) throw InputError(fmt::format("{}: dimension {} is {}", name, a, dims[a]));
    if (!(spacing[a] > 0) || !std::isfinite(spacing[a]))
      throw InputError(fmt::format("{}: spacing along axis {} is {} (must be positive)", name, a, spacing[a]));
  }
  if (!origin.allFinite()) throw InputError(fmt::format("{}: origin is not finite", name));
  const double det = direction.determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-6)
    throw InputError(fmt::format("{}: direction matrix is singular (determinant {})", name, det));
  if (values.size() != num_voxels())
    throw InputError(fmt::format("{}: {} values for {} voxels", name, values.size(), num_voxels()));
}

Volume gaussian_smooth(const Volume& volume, double sigma_mm) {
  Volume out = volume;
  if (!(sigma_mm > 0)) return out;
  std::vector<float> line;
  for (int axis = 0; axis < 3; ++axis) {
    const double sigma = sigma_mm / volume.spacing[axis];
    const int radius = static_cast<int>(std::ceil(3 * sigma));
    if (radius < 1 || volume.dims[axis] < 2) continue;
    std::vector<double> kernel(2 * radius + 1);
    double sum = 0;
    for (int r = -radius; r <= radius; ++r) sum += kernel[r + radius] = std::exp(-0.5 * r * r / (sigma * sigma));
    for (double& k : kernel) k /= sum;
    const std::size_t stride = axis == 0   ? 1
                               : axis == 1 ? volume.dims[0]
                                           : std::size_t(volume.dims[0]) * volume.dims[1];
    const int n = volume.dims[axis];
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    const std::size_t s1 = a1 == 0 ? 1 : a1 == 1 ? volume.dims[0] : std::size_t(volume.dims[0]) * volume.dims[1];
    const std::size_t s2 = a2 == 0 ? 1 : a2 == 1 ? volume.dims[0] : std::size_t(volume.dims[0]) * volume.dims[1];
    line.resize(n);
    for (int u = 0; u < volume.dims[a1]; ++u)
      for (int w = 0; w < volume.dims[a2]; ++w) {
        const std::size_t base = u * s1 + w * s2;
        for (int x = 0; x < n; ++x) line[x] = out.values[base + x * stride];
        for (int x = 0; x < n; ++x) {
          double acc = 0;
          for (int r = -radius; r <= radius; ++r) acc += kernel[r + radius] * line[std::clamp(x + r, 0, n - 1)];
          out.values[base + x * stride] = static_cast<float>(acc);
        }
      }
  }
  return out;
}

Volume gradient_magnitude(const Volume& volume, double sigma_mm) {
  const Volume s = gaussian_smooth(volume, sigma_mm);
  Volume out = s;
  const Eigen::Matrix3d J = volume.direction.inverse().transpose();
  const auto& d = volume.dims;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        const int idx[3] = {i, j, k};
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) {
          if (d[a] < 2) {
            g[a] = 0;
            continue;
          }
          int lo[3] = {i, j, k}, hi[3] = {i, j, k};
          lo[a] = std::max(0, idx[a] - 1);
          hi[a] = std::min(d[a] - 1, idx[a] + 1);
          g[a] = (s.at(hi[0], hi[1], hi[2]) - s.at(lo[0], lo[1], lo[2])) / ((hi[a] - lo[a]) * volume.spacing[a]);
        }
        out.values[i + std::size_t(d[0]) * (j + std::size_t(d[1]) * k)] = static_cast<float>((J * g).norm());
      }
  return out;
}

VolumeReport describe(const Volume& v) {
  VolumeReport r;
  r.dims = v.dims;
  r.spacing = v.spacing;
  r.origin = v.origin;
  r.direction = v.direction;
  static const char* letters[3][2] = {{"L", "R"}, {"P", "A"}, {"S", "I"}};  // +x, -x in LPS, ...
  for (int a = 0; a < 3; ++a) {
    Eigen::Index k = 0;
    const Eigen::Vector3d axis = v.direction.col(a);
    const double largest = axis.cwiseAbs().maxCoeff(&k);
    r.orientation += letters[k][axis[k] >= 0 ? 0 : 1];
    if (largest < std::cos(M_PI / 180.0)) r.oblique = true;
  }
  r.bbox_min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  r.bbox_max = -r.bbox_min;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? v.dims[0] - 1 : 0, (c & 2) ? v.dims[1] - 1 : 0, (c & 4) ? v.dims[2] - 1 : 0);
    const Eigen::Vector3d p = v.index_to_lps(ijk);
    r.bbox_min = r.bbox_min.cwiseMin(p);
    r.bbox_max = r.bbox_max.cwiseMax(p);
  }
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, sum = 0;
  std::size_t finite = 0;
  for (const float x : v.values) {
    if (!std::isfinite(x)) {
      ++r.nonfinite;
      continue;
    }
    lo = std::min(lo, static_cast<double>(x));
    hi = std::max(hi, static_cast<double>(x));
    sum += x;
    ++finite;
  }
  if (finite > 0) {
    r.min = lo;
    r.max = hi;
    r.mean = sum / static_cast<double>(finite);
  }
  return r;
}

std::string to_json(const VolumeReport& r) {
  const auto vec = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) rows.push_back(vec(r.direction.row(i).transpose()));
  const nlohmann::json j = {{"kind", "volume"},
                            {"dims", {r.dims[0], r.dims[1], r.dims[2]}},
                            {"spacing", vec(r.spacing)},
                            {"origin", vec(r.origin)},
                            {"direction", rows},
                            {"frame", "LPS"},
                            {"orientation", r.orientation},
                            {"oblique", r.oblique},
                            {"bbox_min", vec(r.bbox_min)},
                            {"bbox_max", vec(r.bbox_max)},
                            {"min", r.min},
                            {"max", r.max},
                            {"mean", r.mean},
                            {"nonfinite", r.nonfinite}};
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace meshpde
