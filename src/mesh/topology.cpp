#include "meshpde/mesh/topology.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>

namespace meshpde {

namespace {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

double longest_edge_sq(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return std::max({(a - b).squaredNorm(), (b - c).squaredNorm(), (c - a).squaredNorm()});
}

}  // namespace

double triangle_area(const Mesh& mesh, int f) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
  return 0.5 * (b - a).cross(c - a).norm();
}

bool is_degenerate(const Mesh& mesh, int f) {
  const auto& F = mesh.triangles();
  if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 2) == F(f, 0)) return true;
  const auto& V = mesh.positions();
  const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
  return triangle_area(mesh, f) <= kDegenerateAreaRelTol * longest_edge_sq(a, b, c);
}

namespace {
// The interior angle of triangle f at its corner c, in degrees.
double corner_angle_deg(const Positions& V, const Triangles& F, int f, int c) {
  const Eigen::Vector3d p = V.row(F(f, c)), u = V.row(F(f, (c + 1) % 3)).transpose() - p,
                        w = V.row(F(f, (c + 2) % 3)).transpose() - p;
  return std::atan2(u.cross(w).norm(), u.dot(w)) * 180.0 / M_PI;
}
}  // namespace

double smallest_angle_deg(const Positions& V, const Triangles& F, const std::vector<int>& faces) {
  double smallest = 180;
  const auto n = static_cast<int>(faces.empty() ? F.rows() : static_cast<Eigen::Index>(faces.size()));
  for (int k = 0; k < n; ++k) {
    const int f = faces.empty() ? k : faces[static_cast<std::size_t>(k)];
    const Eigen::Vector3d p[3] = {V.row(F(f, 0)), V.row(F(f, 1)), V.row(F(f, 2))};
    if (!((p[1] - p[0]).cross(p[2] - p[0]).norm() > 0)) continue;
    for (int c = 0; c < 3; ++c) smallest = std::min(smallest, corner_angle_deg(V, F, f, c));
  }
  return smallest;
}

double mean_edge_length(const Mesh& mesh) {
  const auto& V = mesh.positions();
  const auto& E = mesh.edges();
  double sum = 0;
  for (int e = 0; e < mesh.num_edges(); ++e) sum += (V.row(E(e, 0)) - V.row(E(e, 1))).norm();
  return mesh.num_edges() ? sum / mesh.num_edges() : 0.0;
}

Eigen::MatrixX3d vertex_normals(const Mesh& mesh) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  Eigen::MatrixX3d N = Eigen::MatrixX3d::Zero(mesh.num_vertices(), 3);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) N.row(F(f, k)) += n.transpose();
  }
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const double nn = N.row(i).norm();
    if (nn > 0) N.row(i) /= nn;
  }
  return N;
}

Eigen::MatrixX3d outward_vertex_normals(const Mesh& mesh) {
  Eigen::MatrixX3d N = vertex_normals(mesh);
  const MeshReport r = analyze(mesh);
  if (r.boundary_loops == 0 && r.signed_volume < 0) N = -N;
  return N;
}

std::vector<int> vertex_components(const Mesh& mesh, int* count) {
  const int nv = mesh.num_vertices();
  UnionFind uf(nv);
  const auto& E = mesh.edges();
  for (int e = 0; e < mesh.num_edges(); ++e) uf.unite(E(e, 0), E(e, 1));
  std::vector<int> label(nv, -1);
  int n = 0;
  for (int v = 0; v < nv; ++v) {
    const int r = uf.find(v);
    if (label[r] < 0) label[r] = n++;
    label[v] = label[r];
  }
  if (count) *count = n;
  return label;
}

MeshReport analyze(const Mesh& mesh, const ShapeWarningThresholds& thresholds) {
  MeshReport r;
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  const int nv = mesh.num_vertices(), nf = mesh.num_faces(), ne = mesh.num_edges();
  r.vertices = nv;
  r.faces = nf;
  r.edges = ne;

  // Edge -> incident faces, with the direction each face traverses the edge.
  std::vector<int> face_count(ne, 0), forward(ne, 0), backward(ne, 0);
  std::vector<char> referenced(nv, 0);
  double min_area = std::numeric_limits<double>::infinity(), max_area = 0;
  double min_angle = std::numeric_limits<double>::infinity(), max_angle = 0;
  for (int f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) referenced[F(f, c)] = 1;
    const bool degenerate = is_degenerate(mesh, f);
    if (degenerate) {
      ++r.degenerate_faces;
    } else {
      const double A = triangle_area(mesh, f);
      r.area += A;
      min_area = std::min(min_area, A);
      max_area = std::max(max_area, A);
      for (int c = 0; c < 3; ++c) {
        const double ang = corner_angle_deg(V, F, f, c);
        min_angle = std::min(min_angle, ang);
        max_angle = std::max(max_angle, ang);
      }
      const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
      r.signed_volume += a.dot(b.cross(c)) / 6.0;
    }
    for (int c = 0; c < 3; ++c) {
      const int a = F(f, c), b = F(f, (c + 1) % 3);
      if (a == b) continue;
      const int e = mesh.edge_ids()[mesh.find_slot(a, b)];
      ++face_count[e];
      (a < b ? forward[e] : backward[e])++;
    }
  }
  if (min_area <= max_area) {
    r.area_ratio = max_area / min_area;
    r.min_angle_deg = min_angle;
    r.max_angle_deg = max_angle;
  }

  // Boundary edges, loops, non-manifold edges, orientation.
  UnionFind boundary(nv);
  std::vector<char> on_boundary(nv, 0);
  const auto& E = mesh.edges();
  for (int e = 0; e < ne; ++e) {
    if (face_count[e] == 1) {
      ++r.boundary_edges;
      boundary.unite(E(e, 0), E(e, 1));
      on_boundary[E(e, 0)] = on_boundary[E(e, 1)] = 1;
    } else if (face_count[e] >= 3) {
      ++r.nonmanifold_edges;
    } else if (face_count[e] == 2 && (forward[e] == 2 || backward[e] == 2)) {
      ++r.inconsistent_edges;
    }
  }
  r.mean_edge_length = mean_edge_length(mesh);
  r.orientation_consistent = r.inconsistent_edges == 0;
  for (int v = 0; v < nv; ++v)
    if (on_boundary[v] && boundary.find(v) == v) ++r.boundary_loops;

  // Non-manifold vertices: incident triangles that are not connected to each
  // other through edges at that vertex form more than one fan.
  // Vertex -> incident faces (CSR); a face that repeats a vertex is listed once.
  auto first_occurrence = [&](int f, int c) {
    for (int k = 0; k < c; ++k)
      if (F(f, k) == F(f, c)) return false;
    return true;
  };
  std::vector<int> vf_offset(nv + 1, 0);
  for (int f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c)
      if (first_occurrence(f, c)) ++vf_offset[F(f, c) + 1];
  for (int v = 0; v < nv; ++v) vf_offset[v + 1] += vf_offset[v];
  std::vector<int> vf(vf_offset[nv]);
  {
    std::vector<int> fill(vf_offset.begin(), vf_offset.end() - 1);
    for (int f = 0; f < nf; ++f)
      for (int c = 0; c < 3; ++c)
        if (first_occurrence(f, c)) vf[fill[F(f, c)]++] = f;
  }
  for (int v = 0; v < nv; ++v) {
    const int b = vf_offset[v], n = vf_offset[v + 1] - b;
    if (n <= 1) continue;
    // Faces around v are joined when they share an edge (v, w): key by w.
    std::vector<std::pair<int, int>> spokes;  // (other vertex, local face index)
    for (int k = 0; k < n; ++k) {
      const int f = vf[b + k];
      for (int c = 0; c < 3; ++c)
        if (F(f, c) != v) spokes.emplace_back(F(f, c), k);
    }
    std::sort(spokes.begin(), spokes.end());
    UnionFind fan(n);
    for (std::size_t s = 1; s < spokes.size(); ++s)
      if (spokes[s].first == spokes[s - 1].first) fan.unite(spokes[s].second, spokes[s - 1].second);
    int fans = 0;
    for (int k = 0; k < n; ++k) fans += fan.find(k) == k;
    if (fans > 1) ++r.nonmanifold_vertices;
  }

  // Components over referenced vertices; unreferenced vertices; Euler characteristic.
  int ncomp_all = 0;
  const auto label = vertex_components(mesh, &ncomp_all);
  std::vector<char> comp_used(ncomp_all, 0);
  int referenced_count = 0;
  for (int v = 0; v < nv; ++v) {
    if (referenced[v]) {
      comp_used[label[v]] = 1;
      ++referenced_count;
    } else {
      ++r.unreferenced_vertices;
    }
  }
  r.components = static_cast<int>(std::count(comp_used.begin(), comp_used.end(), 1));
  r.euler_characteristic = referenced_count - ne + nf;

  // Duplicate positions: exact equality, as produced by unwelded seams.
  std::vector<int> order(nv);
  std::iota(order.begin(), order.end(), 0);
  auto less = [&](int a, int b) {
    for (int c = 0; c < 3; ++c)
      if (V(a, c) != V(b, c)) return V(a, c) < V(b, c);
    return false;
  };
  std::sort(order.begin(), order.end(), less);
  for (int k = 1; k < nv; ++k)
    if (!less(order[k - 1], order[k])) ++r.duplicate_vertices;

  if (nv > 0) {
    r.bbox_min = V.colwise().minCoeff().transpose();
    r.bbox_max = V.colwise().maxCoeff().transpose();
  }

  if (r.nonmanifold_edges) r.warnings.push_back(fmt::format("{} non-manifold edges", r.nonmanifold_edges));
  if (r.nonmanifold_vertices) r.warnings.push_back(fmt::format("{} non-manifold vertices", r.nonmanifold_vertices));
  if (r.degenerate_faces)
    r.warnings.push_back(
        fmt::format("{} degenerate triangles (they contribute nothing to the operators)", r.degenerate_faces));
  if (!r.orientation_consistent)
    r.warnings.push_back(fmt::format("orientation inconsistent across {} edges", r.inconsistent_edges));
  if (r.duplicate_vertices)
    r.warnings.push_back(fmt::format("{} vertices duplicate the position of another", r.duplicate_vertices));
  if (r.unreferenced_vertices)
    r.warnings.push_back(fmt::format("{} unreferenced vertices (held fixed by the solvers)", r.unreferenced_vertices));
  if (r.area_ratio > 0 && (r.min_angle_deg < thresholds.min_angle_deg || r.area_ratio > thresholds.area_ratio))
    r.warnings.push_back(
        fmt::format("badly shaped: smallest angle {:.3g} deg, area ratio {:.3g}; cotangent operators and "
                    "iterative solvers lose accuracy on such meshes (with the automatic Laplacian each "
                    "solver judges the part it works on, a correction its region, and uses intrinsic Delaunay "
                    "operators where that is badly shaped)",
                    r.min_angle_deg, r.area_ratio));
  return r;
}

std::string to_json(const MeshReport& r) {
  const auto vec = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  const nlohmann::json j = {{"vertices", r.vertices},
                            {"faces", r.faces},
                            {"edges", r.edges},
                            {"boundary_edges", r.boundary_edges},
                            {"boundary_loops", r.boundary_loops},
                            {"nonmanifold_edges", r.nonmanifold_edges},
                            {"nonmanifold_vertices", r.nonmanifold_vertices},
                            {"components", r.components},
                            {"degenerate_faces", r.degenerate_faces},
                            {"duplicate_vertices", r.duplicate_vertices},
                            {"unreferenced_vertices", r.unreferenced_vertices},
                            {"orientation_consistent", r.orientation_consistent},
                            {"inconsistent_edges", r.inconsistent_edges},
                            {"euler_characteristic", r.euler_characteristic},
                            {"area", r.area},
                            {"signed_volume", r.signed_volume},
                            {"min_angle_deg", r.min_angle_deg},
                            {"max_angle_deg", r.max_angle_deg},
                            {"area_ratio", r.area_ratio},
                            {"mean_edge_length", r.mean_edge_length},
                            {"bbox_min", vec(r.bbox_min)},
                            {"bbox_max", vec(r.bbox_max)},
                            {"warnings", r.warnings}};
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace meshpde
