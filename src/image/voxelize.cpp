#include "meshpde/image/voxelize.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <utility>

#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

// Where the rows sit, in (fine) voxels off the centres' lines, and the second offset for
// a row whose crossings do not sum to zero.
constexpr double kOffset[2][2] = {{3.2361e-5, 2.8284e-5}, {-4.1231e-5, 3.6056e-5}};

struct Crossing {
  double x;     // where along the row (fine index)
  int winding;  // +1 or -1
  bool operator<(const Crossing& o) const { return x < o.x; }
};

int sign(double x) {
  return (x > 0) - (x < 0);
}

// Which side of the edge u -> v (projected on the row plane (y, z)) the point p is on;
// computed from the edge's lower-numbered end, so that the two triangles of an edge get
// the exactly opposite answer, and broken by an infinitesimal shift of p when it lies on
// the edge's line (a fixed shift: every triangle sees the same point).
int side(const Eigen::Vector2d& u, int iu, const Eigen::Vector2d& v, int iv, const Eigen::Vector2d& p) {
  if (iv < iu) return -side(v, iv, u, iu, p);
  const double e = (v.x() - u.x()) * (p.y() - u.y()) - (v.y() - u.y()) * (p.x() - u.x());
  if (e != 0) return sign(e);
  if (v.y() != u.y()) return -sign(v.y() - u.y());
  return sign(v.x() - u.x());
}

std::size_t boundary_edges(const Triangles& F) {
  std::vector<std::pair<int, int>> edges;
  edges.reserve(static_cast<std::size_t>(F.rows()) * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = F(f, c), b = F(f, (c + 1) % 3);
      if (a != b) edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  std::size_t open = 0;
  for (std::size_t k = 0; k < edges.size();) {
    std::size_t m = k;
    while (m < edges.size() && edges[m] == edges[k]) ++m;
    open += (m - k) % 2;  // an odd number of triangles on an edge leaves it open
    k = m;
  }
  return open;
}

}  // namespace

VoxelBox whole_grid(const Volume& grid) {
  return {{0, 0, 0}, {grid.dims[0], grid.dims[1], grid.dims[2]}};
}

VoxelBox voxel_box_around(const Volume& grid, const std::vector<Eigen::Vector3d>& points, double margin) {
  VoxelBox b{{grid.dims[0], grid.dims[1], grid.dims[2]}, {0, 0, 0}};
  for (const auto& p : points) {
    const Eigen::Vector3d q = grid.lps_to_index(p);
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = std::min(b.lo[a], static_cast<int>(std::max(0.0, std::ceil(q[a] - margin))));
      b.hi[a] = std::max(b.hi[a], static_cast<int>(std::min<double>(grid.dims[a], std::floor(q[a] + margin) + 1)));
    }
  }
  if (b.empty()) return {};
  return b;
}

std::vector<std::uint8_t> voxelize(const Positions& V, const Triangles& F, const Volume& grid, int K,
                                   const VoxelBox* box_in) {
  if (K < 1 || K > 8) throw InputError(fmt::format("oversampling {}: expected 1 to 8", K));
  if (!V.allFinite()) throw InputError("the surface has a coordinate that is not finite");
  if (F.rows() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= V.rows()))
    throw InputError("the surface has a triangle index out of range");
  if (const std::size_t open = boundary_edges(F); open > 0)
    throw InputError(fmt::format(
        "the surface is not closed ({} boundary edges): voxels inside it are only defined for a closed surface", open));
  const std::size_t nx = static_cast<std::size_t>(grid.dims[0]), ny = static_cast<std::size_t>(grid.dims[1]);
  std::vector<std::uint8_t> out(grid.num_voxels(), 0);
  const VoxelBox box = box_in ? *box_in : whole_grid(grid);
  if (box.empty()) return out;
  // Vertices in fine index coordinates: voxel (i, j, k) spans fine samples K i .. K i + K - 1.
  const Eigen::Matrix3d to_index = (grid.direction * grid.spacing.asDiagonal()).inverse();
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> Q(V.rows(), 3);
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d q = to_index * (V.row(v).transpose() - grid.origin);
    Q.row(v) = (K * (q.array() + 0.5) - 0.5).matrix().transpose();
  }
  const int y0 = K * box.lo[1], y1 = K * box.hi[1], z0 = K * box.lo[2], z1 = K * box.hi[2];
  const int x0 = K * box.lo[0], x1 = K * box.hi[0];
  const std::size_t rows_y = static_cast<std::size_t>(y1 - y0);
  auto row_of = [&](int y, int z) {
    return static_cast<std::size_t>(z - z0) * rows_y + static_cast<std::size_t>(y - y0);
  };
  std::vector<std::vector<Crossing>> rows(rows_y * static_cast<std::size_t>(z1 - z0));

  // The crossings of the rows (y, z) with `only` (all rows of the box when empty) on offset `o`.
  auto cross = [&](int o, const std::vector<std::size_t>* only) {
    const double dy = kOffset[o][0], dz = kOffset[o][1];
    std::vector<char> wanted;
    if (only) {
      wanted.assign(rows.size(), 0);
      for (const std::size_t r : *only) wanted[r] = 1;
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      const int ia = F(f, 0), ib = F(f, 1), ic = F(f, 2);
      const Eigen::Vector2d a(Q(ia, 1), Q(ia, 2)), b(Q(ib, 1), Q(ib, 2)), c(Q(ic, 1), Q(ic, 2));
      const int ylo = std::max(y0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}) - dy)));
      const int yhi = std::min(y1 - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}) - dy)));
      const int zlo = std::max(z0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}) - dz)));
      const int zhi = std::min(z1 - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}) - dz)));
      for (int z = zlo; z <= zhi; ++z)
        for (int y = ylo; y <= yhi; ++y) {
          const std::size_t r = row_of(y, z);
          if (only && !wanted[r]) continue;
          const Eigen::Vector2d p(y + dy, z + dz);
          const int s = side(a, ia, b, ib, p);
          if (s == 0 || side(b, ib, c, ic, p) != s || side(c, ic, a, ia, p) != s) continue;
          // Where the row meets the triangle's plane: barycentric weights in the projection.
          const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
          if (area == 0) continue;
          const double wb = ((p.x() - a.x()) * (c.y() - a.y()) - (p.y() - a.y()) * (c.x() - a.x())) / area;
          const double wc = ((b.x() - a.x()) * (p.y() - a.y()) - (b.y() - a.y()) * (p.x() - a.x())) / area;
          const double x = (1 - wb - wc) * Q(ia, 0) + wb * Q(ib, 0) + wc * Q(ic, 0);
          rows[r].push_back({x, s});
        }
    }
  };
  cross(0, nullptr);
  std::vector<std::size_t> again;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    int total = 0;
    for (const auto& c : rows[r]) total += c.winding;
    if (total != 0) again.push_back(r);
  }
  if (!again.empty()) {
    for (const std::size_t r : again) rows[r].clear();
    cross(1, &again);
  }

  // Sweep each row: the winding number at each fine sample; a voxel is inside when more
  // than half of its K^3 samples are.
  std::vector<std::uint16_t> count(K > 1 ? out.size() : 0, 0);
  for (int z = z0; z < z1; ++z)
    for (int y = y0; y < y1; ++y) {
      std::vector<Crossing>& row = rows[row_of(y, z)];
      if (row.empty()) continue;
      std::sort(row.begin(), row.end());
      int winding = 0;
      std::size_t next = 0;
      const std::size_t base = nx * (static_cast<std::size_t>(y / K) + ny * static_cast<std::size_t>(z / K));
      for (int x = x0; x < x1; ++x) {
        while (next < row.size() && row[next].x <= x) winding += row[next++].winding;
        if (winding == 0) continue;
        const std::size_t voxel = base + static_cast<std::size_t>(x / K);
        if (K == 1)
          out[voxel] = 1;
        else
          ++count[voxel];
      }
    }
  if (K > 1) {
    const int half = K * K * K;
    for (std::size_t v = 0; v < out.size(); ++v) out[v] = 2 * count[v] > half;
  }
  return out;
}

}  // namespace meshpde
