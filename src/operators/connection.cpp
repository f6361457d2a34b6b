#include "meshpde/operators/connection.h"

#include <fmt/format.h>

#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

double Connection::transport(const Mesh& mesh, int i, int slot) const {
  const int j = mesh.neighbors()[slot];
  const int back = mesh.find_slot(j, i);
  return phi[slot] - phi[back] + M_PI;
}

Connection build_connection(const Mesh& mesh) {
  const int nv = mesh.num_vertices();
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  Connection c;
  c.normal = Eigen::MatrixX3d::Zero(nv, 3);
  c.e1 = Eigen::MatrixX3d::Zero(nv, 3);
  c.e2 = Eigen::MatrixX3d::Zero(nv, 3);
  c.phi = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(mesh.neighbors().size()));
  c.theta = Eigen::VectorXd::Zero(nv);
  c.boundary.assign(nv, 0);
  // For each vertex: next[slot of a] = slot of b for every face (i, a, b) in CCW order.
  std::vector<int> next(mesh.neighbors().size(), -1), prev_count(mesh.neighbors().size(), 0);
  std::vector<double> corner(mesh.neighbors().size(), 0.0);  // angle at i between a and next
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (is_degenerate(mesh, f)) continue;
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, k), a = F(f, (k + 1) % 3), b = F(f, (k + 2) % 3);
      const int sa = mesh.find_slot(i, a), sb = mesh.find_slot(i, b);
      if (next[sa] != -1)
        throw InputError(
            fmt::format("vector fields need an edge-manifold, consistently oriented mesh: edge ({}, {}) "
                        "is used twice in the same direction around vertex {}",
                        i, a, i));
      next[sa] = sb;
      ++prev_count[sb];
      const Eigen::Vector3d u = V.row(a) - V.row(i), w = V.row(b) - V.row(i);
      corner[sa] = std::atan2(u.cross(w).norm(), u.dot(w));
      c.normal.row(i) += u.cross(w).transpose();
    }
  }
  const auto off = mesh.offsets();
  for (int i = 0; i < nv; ++i) {
    const double nn = c.normal.row(i).norm();
    if (nn > 0) c.normal.row(i) /= nn;
    if (mesh.degree(i) == 0) continue;
    // Start at a boundary edge (a slot with no predecessor) if there is one.
    int start = off[i];
    for (int s = off[i]; s < off[i + 1]; ++s)
      if (prev_count[s] == 0) {
        start = s;
        c.boundary[i] = 1;
      }
    double sum = 0;
    int s = start, visited = 0;
    std::vector<std::pair<int, double>> order;
    while (s != -1 && visited <= mesh.degree(i)) {
      order.emplace_back(s, sum);
      ++visited;
      if (next[s] == -1) break;
      sum += corner[s];
      s = next[s];
      if (s == start) break;
    }
    if (static_cast<int>(order.size()) != mesh.degree(i))
      throw InputError(fmt::format("vector fields need each vertex to be a single fan; vertex {} is not", i));
    c.theta[i] = sum;
    const double scale = sum > 0 ? (c.boundary[i] ? M_PI : 2 * M_PI) / sum : 1.0;
    for (const auto& [slot, angle] : order) c.phi[slot] = angle * scale;
    const Eigen::Vector3d n = c.normal.row(i);
    Eigen::Vector3d r = V.row(mesh.neighbors()[start]) - V.row(i);
    r -= r.dot(n) * n;
    c.e1.row(i) = r.normalized();
    c.e2.row(i) = n.cross(r.normalized());
  }
  return c;
}

double tangent_angle(const Connection& c, int i, const Eigen::Vector3d& v) {
  return std::atan2(v.dot(c.e2.row(i)), v.dot(c.e1.row(i)));
}

Eigen::Vector3d tangent_vector(const Connection& c, int i, double a, double r) {
  return r * (std::cos(a) * c.e1.row(i).transpose() + std::sin(a) * c.e2.row(i).transpose());
}

Eigen::SparseMatrix<double> connection_laplacian(const Mesh& mesh, const Connection& c, const Eigen::VectorXd& Kii,
                                                 const Eigen::VectorXd& Kij) {
  const int nv = mesh.num_vertices();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(2 * nv + 4 * mesh.neighbors().size());
  const auto off = mesh.offsets();
  for (int i = 0; i < nv; ++i) {
    t.emplace_back(2 * i, 2 * i, Kii[i]);
    t.emplace_back(2 * i + 1, 2 * i + 1, Kii[i]);
    for (int s = off[i]; s < off[i + 1]; ++s) {
      const int j = mesh.neighbors()[s];
      const double r = c.transport(mesh, i, s), w = Kij[s];
      // Block w R(r): row i, column j; R is the rotation by r (complex multiplication).
      t.emplace_back(2 * i, 2 * j, w * std::cos(r));
      t.emplace_back(2 * i, 2 * j + 1, -w * std::sin(r));
      t.emplace_back(2 * i + 1, 2 * j, w * std::sin(r));
      t.emplace_back(2 * i + 1, 2 * j + 1, w * std::cos(r));
    }
  }
  Eigen::SparseMatrix<double> L(2 * nv, 2 * nv);
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

}  // namespace meshpde
