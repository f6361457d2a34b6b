#include "meshpde/mesh/generators.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

GeneratedMesh make(const std::vector<Eigen::Vector3d>& pts, const std::vector<Eigen::Vector3i>& tris) {
  GeneratedMesh m;
  m.V.resize(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i) m.V.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
  m.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t f = 0; f < tris.size(); ++f) m.F.row(static_cast<Eigen::Index>(f)) = tris[f].transpose();
  return m;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw InputError(what);
}

}  // namespace

GeneratedMesh latlong_sphere(int n, double radius) {
  require(n >= 2, fmt::format("latlong sphere needs n >= 2, got {}", n));
  const int m = 2 * n;
  std::vector<Eigen::Vector3d> p;
  p.emplace_back(0, 0, radius);
  for (int k = 1; k < n; ++k) {
    const double th = M_PI * k / n;
    for (int j = 0; j < m; ++j) {
      const double ph = 2 * M_PI * j / m;
      p.emplace_back(radius * std::sin(th) * std::cos(ph), radius * std::sin(th) * std::sin(ph), radius * std::cos(th));
    }
  }
  p.emplace_back(0, 0, -radius);
  const int south = static_cast<int>(p.size()) - 1;
  auto ring = [&](int k, int j) { return 1 + (k - 1) * m + (j % m); };
  std::vector<Eigen::Vector3i> t;
  for (int j = 0; j < m; ++j) t.emplace_back(0, ring(1, j), ring(1, j + 1));
  for (int k = 1; k + 1 < n; ++k)
    for (int j = 0; j < m; ++j) {
      t.emplace_back(ring(k, j), ring(k + 1, j), ring(k + 1, j + 1));
      t.emplace_back(ring(k, j), ring(k + 1, j + 1), ring(k, j + 1));
    }
  for (int j = 0; j < m; ++j) t.emplace_back(south, ring(n - 1, j + 1), ring(n - 1, j));
  return make(p, t);
}

GeneratedMesh geodesic_sphere(BaseSolid base, int frequency, double radius) {
  require(frequency >= 1, fmt::format("sphere frequency must be >= 1, got {}", frequency));
  std::vector<Eigen::Vector3d> c;
  std::vector<Eigen::Vector3i> faces;
  if (base == BaseSolid::Icosahedron) {
    const double g = (1 + std::sqrt(5.0)) / 2;
    c = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
         {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
    faces = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  } else {
    c = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
    faces = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  }
  for (auto& v : c) v.normalize();
  const int n = frequency;
  std::vector<Eigen::Vector3d> p = c;
  // Interior points of a base edge (a < b), k = 1..n-1 counted from a.
  std::map<std::pair<int, int>, int> edge_start;
  auto edge_point = [&](int a, int b, int k) -> int {
    const bool flip = a > b;
    const int lo = flip ? b : a, hi = flip ? a : b, kk = flip ? n - k : k;
    auto [it, inserted] = edge_start.try_emplace({lo, hi}, static_cast<int>(p.size()));
    if (inserted)
      for (int s = 1; s < n; ++s) p.push_back(c[lo] + (c[hi] - c[lo]) * (double(s) / n));
    return it->second + kk - 1;
  };
  std::vector<Eigen::Vector3i> t;
  std::vector<int> idx;
  for (const auto& f : faces) {
    // Grid point (i, j), i + j <= n, at a + (b - a) i/n + (c - a) j/n.
    const int a = f[0], b = f[1], cc = f[2];
    idx.assign((n + 1) * (n + 1), -1);
    auto id = [&](int i, int j) -> int& { return idx[i * (n + 1) + j]; };
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        if (i == 0 && j == 0)
          id(i, j) = a;
        else if (i == n)
          id(i, j) = b;
        else if (j == n)
          id(i, j) = cc;
        else if (j == 0)
          id(i, j) = edge_point(a, b, i);
        else if (i == 0)
          id(i, j) = edge_point(a, cc, j);
        else if (i + j == n)
          id(i, j) = edge_point(b, cc, j);
        else {
          id(i, j) = static_cast<int>(p.size());
          p.push_back(c[a] + (c[b] - c[a]) * (double(i) / n) + (c[cc] - c[a]) * (double(j) / n));
        }
      }
    for (int i = 0; i < n; ++i)
      for (int j = 0; i + j < n; ++j) {
        t.emplace_back(id(i, j), id(i + 1, j), id(i, j + 1));
        if (i + j + 1 < n) t.emplace_back(id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
      }
  }
  for (auto& v : p) v = v.normalized() * radius;
  return make(p, t);
}

GeneratedMesh icosphere(int level, double radius) {
  require(level >= 0 && level <= 11, fmt::format("icosphere level must be in [0, 11], got {}", level));
  return geodesic_sphere(BaseSolid::Icosahedron, 1 << level, radius);
}

GeneratedMesh tube(double radius, double length, int rings, int segments, bool caps) {
  require(rings >= 2 && segments >= 3, "tube needs rings >= 2 and segments >= 3");
  std::vector<Eigen::Vector3d> p;
  for (int k = 0; k < rings; ++k)
    for (int j = 0; j < segments; ++j) {
      const double ph = 2 * M_PI * j / segments;
      p.emplace_back(radius * std::cos(ph), radius * std::sin(ph), length * k / (rings - 1));
    }
  std::vector<Eigen::Vector3i> t;
  auto id = [&](int k, int j) { return k * segments + (j % segments); };
  for (int k = 0; k + 1 < rings; ++k)
    for (int j = 0; j < segments; ++j) {
      t.emplace_back(id(k, j), id(k, j + 1), id(k + 1, j + 1));
      t.emplace_back(id(k, j), id(k + 1, j + 1), id(k + 1, j));
    }
  if (!caps) return make(p, t);
  const std::size_t wall = t.size();
  const int bottom = static_cast<int>(p.size()), top = bottom + 1;
  p.emplace_back(0, 0, 0);
  p.emplace_back(0, 0, length);
  for (int j = 0; j < segments; ++j) t.emplace_back(bottom, id(0, j + 1), id(0, j));               // facing -z
  for (int j = 0; j < segments; ++j) t.emplace_back(top, id(rings - 1, j), id(rings - 1, j + 1));  // facing +z
  GeneratedMesh m = make(p, t);
  m.face_labels.resize(m.F.rows());
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    m.face_labels[f] = static_cast<std::size_t>(f) < wall ? 1 : static_cast<std::size_t>(f) < wall + segments ? 2 : 3;
  return m;
}

GeneratedMesh plane_grid(int nx, int ny, double sx, double sy) {
  require(nx >= 1 && ny >= 1, "plane grid needs nx, ny >= 1");
  std::vector<Eigen::Vector3d> p;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) p.emplace_back(sx * i / nx, sy * j / ny, 0.0);
  std::vector<Eigen::Vector3i> t;
  auto id = [&](int i, int j) { return j * (nx + 1) + i; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      t.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
      t.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
    }
  return make(p, t);
}

GeneratedMesh fins(int k, int n) {
  require(k >= 1 && n >= 1, "fins need k >= 1 sheets of n >= 1 quads");
  std::vector<Eigen::Vector3d> p;
  for (int j = 0; j <= n; ++j) p.emplace_back(0, 0, double(j) / n);  // shared axis
  std::vector<Eigen::Vector3i> t;
  for (int s = 0; s < k; ++s) {
    const double ph = 2 * M_PI * s / k;
    const Eigen::Vector3d dir(std::cos(ph), std::sin(ph), 0);
    const int base = static_cast<int>(p.size());
    for (int i = 1; i <= n; ++i)
      for (int j = 0; j <= n; ++j) p.push_back(dir * (double(i) / n) + Eigen::Vector3d(0, 0, double(j) / n));
    auto id = [&](int i, int j) { return i == 0 ? j : base + (i - 1) * (n + 1) + j; };
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        t.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
        t.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
      }
  }
  return make(p, t);
}

namespace {

double capsule(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
  const Eigen::Vector3d ab = b - a;
  const double h = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - a - ab * h).norm() - r;
}
// Polynomial smooth minimum (blend radius k).
double smin(double a, double b, double k) {
  const double h = std::clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0);
  return b + (a - b) * h - k * h * (1 - h);
}

}  // namespace

GeneratedMesh y_bifurcation(const BifurcationParams& q) {
  require(q.trunk_radius > 0 && q.branch_radius > 0 && q.cell > 0 && q.trunk_length > 0 && q.branch_length > 0,
          "bifurcation radii, lengths and cell size must be positive");
  require(q.cell < 0.5 * std::min(q.trunk_radius, q.branch_radius),
          "bifurcation cell size must be below half the smallest radius");
  const double half = q.angle_deg * M_PI / 360.0;
  const Eigen::Vector3d o(0, 0, 0), trunk_end(0, 0, -q.trunk_length);
  const Eigen::Vector3d b1 = q.branch_length * Eigen::Vector3d(std::sin(half), 0, std::cos(half));
  const Eigen::Vector3d b2 = q.branch_length * Eigen::Vector3d(-std::sin(half), 0, std::cos(half));
  const Eigen::Vector3d dent_center(q.trunk_radius + q.dent_radius - q.dent_depth, 0, -0.5 * q.trunk_length);
  // With caps the vessels run on past their ends and the planes there cut them square.
  const Eigen::Vector3d u1 = b1.normalized(), u2 = b2.normalized();
  const double run = q.caps ? 2 * std::max(q.trunk_radius, q.branch_radius) : 0;
  auto cut = [&](int c, const Eigen::Vector3d& p) {  // signed distance beyond end plane c
    return c == 0 ? -(p.z() + q.trunk_length) : c == 1 ? (p - b1).dot(u1) : (p - b2).dot(u2);
  };
  auto sdf = [&](const Eigen::Vector3d& p) {
    double d = smin(capsule(p, trunk_end - Eigen::Vector3d(0, 0, run), o, q.trunk_radius),
                    capsule(p, o, b1 + run * u1, q.branch_radius), q.blend);
    d = smin(d, capsule(p, o, b2 + run * u2, q.branch_radius), q.blend);
    if (q.dent) d = -smin(-d, (p - dent_center).norm() - q.dent_radius, 1.0);  // smooth subtraction
    if (q.caps) d = std::max({d, cut(0, p), cut(1, p), cut(2, p)});
    return d;
  };
  // Grid over the bounding box.
  const double pad = 2 * q.cell + std::max(q.trunk_radius, q.branch_radius);
  const Eigen::Vector3d lo(std::min({0.0, b1.x(), b2.x()}) - pad, -pad, -q.trunk_length - pad);
  const Eigen::Vector3d hi(std::max({0.0, b1.x(), b2.x()}) + pad, pad, std::max(b1.z(), 0.0) + pad);
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / q.cell));
  const int ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / q.cell));
  const int nz = static_cast<int>(std::ceil((hi.z() - lo.z()) / q.cell));
  auto node = [&](int i, int j, int k) { return (static_cast<long long>(k) * (ny + 1) + j) * (nx + 1) + i; };
  auto node_pos = [&](long long id) {
    const long long i = id % (nx + 1), j = (id / (nx + 1)) % (ny + 1), k = id / ((nx + 1) * (ny + 1));
    return Eigen::Vector3d(lo.x() + q.cell * i, lo.y() + q.cell * j, lo.z() + q.cell * k);
  };
  std::vector<double> phi(static_cast<std::size_t>((nx + 1)) * (ny + 1) * (nz + 1));
  for (long long id = 0; id < static_cast<long long>(phi.size()); ++id) {
    double v = sdf(node_pos(id));
    if (std::abs(v) < 1e-9 * q.cell) v = 1e-9 * q.cell;  // keep crossings off grid nodes
    phi[id] = v;
  }
  std::vector<Eigen::Vector3d> pts;
  std::unordered_map<long long, int> edge_vertex;  // key: lo_node * N + hi_node
  const long long N = static_cast<long long>(phi.size());
  auto crossing = [&](long long a, long long b) {
    if (a > b) std::swap(a, b);
    const long long key = a * N + b;
    auto [it, inserted] = edge_vertex.try_emplace(key, static_cast<int>(pts.size()));
    if (inserted) {
      const double t = phi[a] / (phi[a] - phi[b]);
      pts.push_back(node_pos(a) + t * (node_pos(b) - node_pos(a)));
    }
    return it->second;
  };
  std::vector<Eigen::Vector3i> tris;
  // Each cube is split into six tetrahedra around its main diagonal (0 -> 7); the
  // split is the same in every cube, so neighbouring faces match.
  static const int kTets[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7}, {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
  auto emit = [&](int a, int b, int c, const Eigen::Vector3d& outward) {
    Eigen::Vector3i t(a, b, c);
    const Eigen::Vector3d n = (pts[b] - pts[a]).cross(pts[c] - pts[a]);
    if (n.dot(outward) < 0) std::swap(t[1], t[2]);
    tris.push_back(t);
  };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        long long corner[8];
        for (int c = 0; c < 8; ++c) corner[c] = node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        for (const auto& tet : kTets) {
          long long in[4], out[4];
          int ni = 0, no = 0;
          for (int c : tet) (phi[corner[c]] < 0 ? in[ni++] : out[no++]) = corner[c];
          if (ni == 0 || no == 0) continue;
          Eigen::Vector3d cin = Eigen::Vector3d::Zero(), cout = Eigen::Vector3d::Zero();
          for (int s = 0; s < ni; ++s) cin += node_pos(in[s]) / ni;
          for (int s = 0; s < no; ++s) cout += node_pos(out[s]) / no;
          const Eigen::Vector3d outward = cout - cin;
          if (ni == 1 || no == 1) {
            const long long apex = ni == 1 ? in[0] : out[0];
            const long long* others = ni == 1 ? out : in;
            emit(crossing(apex, others[0]), crossing(apex, others[1]), crossing(apex, others[2]), outward);
          } else {
            const int a = crossing(in[0], out[0]), b = crossing(in[0], out[1]);
            const int c = crossing(in[1], out[1]), d = crossing(in[1], out[0]);
            emit(a, b, c, outward);
            emit(a, c, d, outward);
          }
        }
      }
  GeneratedMesh m = make(pts, tris);
  // Relax: move each vertex toward the centroid of its neighbours, then project
  // back onto the zero level with Newton steps along the numerical gradient.
  Mesh mesh(m.V, m.F);
  auto gradient = [&](const Eigen::Vector3d& p) {
    const double h = 1e-4 * q.cell;
    Eigen::Vector3d g;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e[c] = h;
      g[c] = (sdf(p + e) - sdf(p - e)) / (2 * h);
    }
    return g;
  };
  Positions V = m.V;
  for (int it = 0; it < q.relax_iterations; ++it) {
    Positions W = V;
    for (int v = 0; v < mesh.num_vertices(); ++v) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int w : mesh.neighbors(v)) c += V.row(w).transpose();
      c /= mesh.degree(v);
      Eigen::Vector3d p = V.row(v).transpose() + 0.5 * (c - V.row(v).transpose());
      for (int s = 0; s < 3; ++s) {
        const Eigen::Vector3d g = gradient(p);
        p -= sdf(p) * g / std::max(g.squaredNorm(), 1e-12);
      }
      W.row(v) = p.transpose();
    }
    V = W;
  }
  m.V = V;
  if (q.caps) {
    // A triangle whose corners all lie on an end plane is that end's cap.
    m.face_labels = Eigen::VectorXi::Ones(m.F.rows());
    const double tol = 1e-6 * q.cell;
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      for (int c = 0; c < 3; ++c) {
        bool on = true;
        for (int k = 0; k < 3; ++k) on = on && std::abs(cut(c, V.row(m.F(f, k)).transpose())) < tol;
        if (on) m.face_labels[f] = 2 + c;
      }
  }
  return m;
}

GeneratedMesh subdivide_midpoint(const Positions& V, const Triangles& F) {
  Mesh mesh(V, F);
  GeneratedMesh m;
  const int nv = mesh.num_vertices(), ne = mesh.num_edges();
  m.V.resize(nv + ne, 3);
  m.V.topRows(nv) = V;
  for (int e = 0; e < ne; ++e) m.V.row(nv + e) = 0.5 * (V.row(mesh.edges()(e, 0)) + V.row(mesh.edges()(e, 1)));
  m.F.resize(4 * F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int a = F(f, 0), b = F(f, 1), c = F(f, 2);
    auto mid = [&](int x, int y) { return nv + mesh.edge_ids()[mesh.find_slot(x, y)]; };
    const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    m.F.row(4 * f + 0) << a, ab, ca;
    m.F.row(4 * f + 1) << ab, b, bc;
    m.F.row(4 * f + 2) << ca, bc, c;
    m.F.row(4 * f + 3) << ab, bc, ca;
  }
  return m;
}

DentHandle dent_handle(const Positions& V, const BifurcationParams& q) {
  // The dent is centred on the trunk's wall at +x, halfway up the trunk.
  const Eigen::Vector3d bottom(q.trunk_radius - q.dent_depth, 0, -0.5 * q.trunk_length);
  DentHandle h;
  (V.rowwise() - bottom.transpose()).rowwise().squaredNorm().minCoeff(&h.vertex);
  const Eigen::Vector3d p = V.row(h.vertex).transpose();
  const double r_xy = std::hypot(p.x(), p.y());
  h.move = (q.trunk_radius - r_xy) * Eigen::Vector3d(p.x() / r_xy, p.y() / r_xy, 0);
  return h;
}

const std::vector<std::string>& generator_names() {
  static const std::vector<std::string> names{"latlong",     "icosphere", "geodesic", "tube",
                                              "bifurcation", "plane",     "fins"};
  return names;
}

GeneratedMesh generate(const std::string& kind, const GeneratorParams& p) {
  if (kind == "latlong") return latlong_sphere(p.n, p.radius);
  if (kind == "icosphere") return icosphere(p.level, p.radius);
  if (kind == "geodesic") return geodesic_sphere(p.base, p.frequency, p.radius);
  if (kind == "tube") return tube(p.radius, p.length, p.rings, p.segments, p.caps);
  if (kind == "bifurcation") {
    BifurcationParams b = p.bifurcation;
    b.caps = b.caps || p.caps;
    return y_bifurcation(b);
  }
  if (kind == "plane") return plane_grid(p.nx, p.ny, p.size, p.size);
  if (kind == "fins") return fins(p.k, p.n);
  std::string names;
  for (const auto& n : generator_names()) names += (names.empty() ? "" : ", ") + n;
  throw InputError(fmt::format("unknown mesh kind '{}' (expected one of: {})", kind, names));
}

}  // namespace meshpde
