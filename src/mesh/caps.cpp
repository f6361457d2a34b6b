#include "meshpde/mesh/caps.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

constexpr double kFlatFraction = 0.01;  // flatness allowed, as a fraction of the patch's diameter
constexpr double kNormalSpreadDeg = 5.0;
constexpr double kRimTurnDeg = 30.0;
// A cap meets its wall square (SimVascular's and VMTK's turn by about 90 degrees); the flat
// facets of a marching-cubes surface turn by about 45 degrees.
constexpr double kRimMeanTurnDeg = 60.0;

Eigen::Vector3d face_normal(const Mesh& m, int f, double* area = nullptr) {
  const auto& V = m.positions();
  const auto& F = m.triangles();
  const Eigen::Vector3d n = (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0))).transpose();
  if (area) *area = 0.5 * n.norm();
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

// The plane of a patch: its vertices' mean and the covariance's least eigenvector.
Cap fit(const Mesh& m, std::vector<int> faces, int label) {
  Cap c;
  c.label = label;
  std::set<int> vs;
  for (const int f : faces) {
    double a = 0;
    face_normal(m, f, &a);
    c.area += a;
    for (int k = 0; k < 3; ++k) vs.insert(m.triangles()(f, k));
  }
  c.faces = std::move(faces);
  c.vertices.assign(vs.begin(), vs.end());
  const auto& V = m.positions();
  for (const int v : c.vertices) c.centre += V.row(v).transpose();
  c.centre /= static_cast<double>(c.vertices.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const int v : c.vertices) {
    const Eigen::Vector3d d = V.row(v).transpose() - c.centre;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  c.normal = es.eigenvectors().col(0);
  // Point it along the patch's triangles.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const int f : c.faces) {
    double a = 0;
    const Eigen::Vector3d n = face_normal(m, f, &a);
    sum += a * n;
  }
  if (sum.dot(c.normal) < 0) c.normal = -c.normal;
  for (const int v : c.vertices)
    c.flatness = std::max(c.flatness, std::abs(c.normal.dot(V.row(v).transpose() - c.centre)));
  return c;
}

double diameter(const Mesh& m, const Cap& c) {
  double d = 0;
  for (const int v : c.vertices) d = std::max(d, (m.positions().row(v).transpose() - c.centre).norm());
  return 2 * d;
}

bool flat(const Mesh& m, const Cap& c) {
  return c.vertices.size() >= 3 && c.flatness <= kFlatFraction * diameter(m, c);
}

// Edges as vertex pairs with the faces on them.
std::map<std::pair<int, int>, std::vector<int>> edge_faces(const Mesh& m) {
  std::map<std::pair<int, int>, std::vector<int>> out;
  const auto& F = m.triangles();
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      if (a != b) out[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  return out;
}

}  // namespace

CapRule parse_cap_rule(const std::string& text) {
  if (text == "labels") return CapRule::Labels;
  if (text == "auto") return CapRule::Auto;
  if (text == "off") return CapRule::Off;
  throw InputError(fmt::format("caps '{}': expected labels, auto or off", text));
}

const char* to_string(CapRule rule) {
  switch (rule) {
    case CapRule::Labels:
      return "labels";
    case CapRule::Auto:
      return "auto";
    case CapRule::Off:
      return "off";
  }
  return "labels";
}

std::vector<Cap> caps_from_labels(const Mesh& m, const Eigen::VectorXi& labels) {
  if (labels.size() != m.num_faces())
    throw InputError(fmt::format("{} face labels for {} triangles", labels.size(), m.num_faces()));
  std::map<int, std::vector<int>> by_label;
  for (int f = 0; f < m.num_faces(); ++f) by_label[labels[f]].push_back(f);
  if (by_label.size() < 2) return {};
  std::vector<Cap> patches;
  for (auto& [label, faces] : by_label) patches.push_back(fit(m, std::move(faces), label));
  const auto wall =
      std::max_element(patches.begin(), patches.end(), [](const Cap& a, const Cap& b) { return a.area < b.area; });
  std::vector<Cap> caps;
  for (auto it = patches.begin(); it != patches.end(); ++it)
    if (it != wall && flat(m, *it)) caps.push_back(std::move(*it));
  return caps;
}

std::vector<Cap> find_flat_caps(const Mesh& m) {
  const int nf = m.num_faces();
  std::vector<Eigen::Vector3d> normal(static_cast<std::size_t>(nf));
  double total = 0;
  for (int f = 0; f < nf; ++f) {
    double a = 0;
    normal[static_cast<std::size_t>(f)] = face_normal(m, f, &a);
    total += a;
  }
  const auto edges = edge_faces(m);
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(nf));
  for (const auto& [e, faces] : edges)
    if (faces.size() == 2) {
      neighbours[static_cast<std::size_t>(faces[0])].push_back(faces[1]);
      neighbours[static_cast<std::size_t>(faces[1])].push_back(faces[0]);
    }
  const double spread = std::cos(kNormalSpreadDeg * M_PI / 180), rim = std::cos(kRimTurnDeg * M_PI / 180);
  std::vector<char> seen(static_cast<std::size_t>(nf), 0);
  std::vector<Cap> caps;
  for (int seed = 0; seed < nf; ++seed) {
    if (seen[static_cast<std::size_t>(seed)] || normal[static_cast<std::size_t>(seed)].squaredNorm() == 0) continue;
    const Eigen::Vector3d n0 = normal[static_cast<std::size_t>(seed)];
    std::vector<int> patch{seed}, stack{seed};
    seen[static_cast<std::size_t>(seed)] = 1;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      for (const int g : neighbours[static_cast<std::size_t>(f)])
        if (!seen[static_cast<std::size_t>(g)] && normal[static_cast<std::size_t>(g)].dot(n0) >= spread) {
          seen[static_cast<std::size_t>(g)] = 1;
          patch.push_back(g);
          stack.push_back(g);
        }
    }
    if (patch.size() < 3) continue;
    Cap c = fit(m, patch, -1);
    if (!flat(m, c) || c.area >= 0.25 * total) continue;
    // Its rim: the patch's boundary edges, where the surface turns sharply, in one loop.
    std::set<int> in(c.faces.begin(), c.faces.end());
    std::map<int, std::vector<int>> loop;  // rim vertex -> its rim neighbours
    std::size_t boundary = 0, sharp = 0;
    double turn = 0;
    for (const int f : c.faces)
      for (int k = 0; k < 3; ++k) {
        const int a = m.triangles()(f, k), b = m.triangles()(f, (k + 1) % 3);
        const auto& faces = edges.at({std::min(a, b), std::max(a, b)});
        const int other = faces.size() == 2 ? (faces[0] == f ? faces[1] : faces[0]) : -1;
        if (other >= 0 && in.count(other)) continue;
        ++boundary;
        loop[a].push_back(b);
        loop[b].push_back(a);
        if (other < 0) continue;
        const double cosine = normal[static_cast<std::size_t>(other)].dot(normal[static_cast<std::size_t>(f)]);
        turn += std::acos(std::clamp(cosine, -1.0, 1.0)) * 180 / M_PI;
        if (cosine <= rim) ++sharp;
      }
    bool one_loop =
        !loop.empty() && std::all_of(loop.begin(), loop.end(), [](const auto& v) { return v.second.size() == 2; });
    if (one_loop) {  // walk it: every rim vertex is reached from the first
      std::set<int> reached{loop.begin()->first};
      std::vector<int> todo{loop.begin()->first};
      while (!todo.empty()) {
        const int v = todo.back();
        todo.pop_back();
        for (const int w : loop.at(v))
          if (reached.insert(w).second) todo.push_back(w);
      }
      one_loop = reached.size() == loop.size();
    }
    c.rim_turn_deg = boundary ? turn / static_cast<double>(boundary) : 0;
    if (boundary >= 3 && sharp == boundary && c.rim_turn_deg >= kRimMeanTurnDeg && one_loop)
      caps.push_back(std::move(c));
  }
  return caps;
}

std::vector<Cap> find_caps(const Mesh& m, const Eigen::VectorXi& labels, CapRule rule) {
  if (rule == CapRule::Off) return {};
  if (labels.size() > 0) return caps_from_labels(m, labels);
  return rule == CapRule::Auto ? find_flat_caps(m) : std::vector<Cap>{};
}

std::vector<int> cap_vertices(const std::vector<Cap>& caps) {
  std::set<int> vs;
  for (const auto& c : caps) vs.insert(c.vertices.begin(), c.vertices.end());
  return {vs.begin(), vs.end()};
}

}  // namespace meshpde
