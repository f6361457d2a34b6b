#include "meshpde/apps/interpolation.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <nlohmann/json.hpp>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/text_records.h"
#include "meshpde/operators/connection.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

namespace {

Field solve_scalar_like(const Mesh& mesh, const FemOperators& ops, int m,
                        const std::vector<InterpolationConstraint>& cons, const InterpolationParams& p, CgResult& cg,
                        SteadySolver& used) {
  std::vector<char> held(mesh.num_vertices(), 0);
  Field u = Field::Zero(mesh.num_vertices(), m);
  for (const auto& c : cons) {
    held[c.vertex] = 1;
    u.row(c.vertex) = c.value.transpose();
  }
  std::vector<int> free;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (!held[v] && ops.mass[v] > 0) free.push_back(v);
  SteadySolveResult s = solve_steady(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = p.g1, .g2 = p.g2}, free, u, p.solver,
                                     kAutoGlobalFromFreeVertices, p.cg);
  used = s.solver;
  cg = s.cg();
  return std::move(s.values);
}

}  // namespace

InterpolationResult interpolate(const Mesh& mesh, const FemOperators& ops, FieldKind kind,
                                const std::vector<InterpolationConstraint>& cons, const InterpolationParams& p) {
  const int nv = mesh.num_vertices();
  const int m = kind == FieldKind::Scalar ? 1 : 3;
  if (cons.empty()) throw InputError("interpolation needs at least one constrained vertex");
  if (!(p.g1 >= 0 && p.g2 >= 0) || p.g1 + p.g2 <= 0) throw InputError("interpolation needs g1, g2 >= 0, not both 0");
  std::vector<char> seen(nv, 0);
  for (const auto& c : cons) {
    if (c.vertex < 0 || c.vertex >= nv)
      throw InputError(fmt::format("constraint vertex {} does not exist (the mesh has {})", c.vertex, nv));
    if (seen[c.vertex]) throw InputError(fmt::format("vertex {} is constrained twice", c.vertex));
    seen[c.vertex] = 1;
    if (c.value.size() != m)
      throw InputError(fmt::format("constraint at vertex {} has {} values, expected {}", c.vertex, c.value.size(), m));
    if (!c.value.allFinite()) throw InputError(fmt::format("constraint at vertex {} is not finite", c.vertex));
    if (ops.mass[c.vertex] <= 0) throw InputError(fmt::format("constraint vertex {} has no incident area", c.vertex));
  }
  InterpolationResult r;
  if (kind != FieldKind::Tangent || p.method == TangentMethod::Componentwise) {
    r.values = solve_scalar_like(mesh, ops, m, cons, p, r.cg, r.solver);
    if (kind == FieldKind::Tangent) {
      const Eigen::MatrixX3d N = vertex_normals(mesh);
      for (int i = 0; i < nv; ++i) {
        const Eigen::RowVector3d n = N.row(i);
        r.values.row(i) -= r.values.row(i).dot(n) * n;
      }
    }
    return r;
  }
  // Connection-aware: directions through the connection Laplacian, magnitudes as a scalar.
  const Connection conn = build_connection(mesh);
  std::vector<InterpolationConstraint> mags;
  Eigen::VectorXd dir_fixed = Eigen::VectorXd::Zero(2 * nv);
  for (const auto& c : cons) {
    const Eigen::Vector3d v = c.value;
    const Eigen::RowVector3d n = conn.normal.row(c.vertex);
    const Eigen::Vector3d t = v - v.dot(n.transpose()) * n.transpose();
    const double a = tangent_angle(conn, c.vertex, t);
    dir_fixed[2 * c.vertex] = std::cos(a);
    dir_fixed[2 * c.vertex + 1] = std::sin(a);
    mags.push_back({c.vertex, Eigen::VectorXd::Constant(1, t.norm())});
  }
  const Field magnitude = solve_scalar_like(mesh, ops, 1, mags, p, r.cg, r.solver);
  if (!r.cg.converged()) return r;  // the caller reports it; the directions would not help
  // Kt for directions: g1 L + g2 L D L on the 2-vectors, solved directly on free DOFs.
  const Eigen::SparseMatrix<double> L = connection_laplacian(mesh, conn, ops.Kii, ops.Kij);
  Eigen::SparseMatrix<double> D2(2 * nv, 2 * nv);
  {
    std::vector<Eigen::Triplet<double>> t;
    for (int i = 0; i < nv; ++i) {
      t.emplace_back(2 * i, 2 * i, ops.D(i));
      t.emplace_back(2 * i + 1, 2 * i + 1, ops.D(i));
    }
    D2.setFromTriplets(t.begin(), t.end());
  }
  const Eigen::SparseMatrix<double> A = p.g1 * L + p.g2 * (L * D2 * L);
  std::vector<int> free_index(2 * nv, -1), free_dofs;
  for (int i = 0; i < nv; ++i)
    if (!seen[i] && ops.mass[i] > 0)
      for (int k = 0; k < 2; ++k) {
        free_index[2 * i + k] = static_cast<int>(free_dofs.size());
        free_dofs.push_back(2 * i + k);
      }
  const int nf = static_cast<int>(free_dofs.size());
  std::vector<Eigen::Triplet<double>> t;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nf);
  for (int col = 0; col < A.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it) {
      const int fr = free_index[it.row()], fc = free_index[it.col()];
      if (fr < 0) continue;
      if (fc >= 0)
        t.emplace_back(fr, fc, it.value());
      else
        rhs[fr] -= it.value() * dir_fixed[it.col()];
    }
  Eigen::SparseMatrix<double> Aff(nf, nf);
  Aff.setFromTriplets(t.begin(), t.end());
  SparseCholesky solver;
  solver.factorize(Aff);
  const Eigen::VectorXd x = solver.solve(rhs);
  Eigen::VectorXd dir = dir_fixed;
  for (int k = 0; k < nf; ++k) dir[free_dofs[k]] = x[k];
  r.values = Field::Zero(nv, 3);
  for (int i = 0; i < nv; ++i) {
    if (seen[i]) continue;
    const double a = std::atan2(dir[2 * i + 1], dir[2 * i]);
    if (std::hypot(dir[2 * i], dir[2 * i + 1]) > 0)
      r.values.row(i) = tangent_vector(conn, i, a, magnitude(i, 0)).transpose();
  }
  for (const auto& c : cons) {
    const Eigen::RowVector3d n = conn.normal.row(c.vertex);
    const Eigen::RowVector3d v = c.value.transpose();
    r.values.row(c.vertex) = v - v.dot(n) * n;  // exact (tangential part of the given vector)
  }
  return r;
}

InterpolationResult interpolate(const Mesh& mesh, FieldKind kind, const std::vector<InterpolationConstraint>& cons,
                                const InterpolationParams& p) {
  LaplacianKind lk = p.laplacian;
  if (kind == FieldKind::Tangent) {
    if (lk == LaplacianKind::IntrinsicDelaunay)
      throw InputError("tangent fields need the cotangent operators of the input triangles (laplacian cotan or auto)");
    lk = LaplacianKind::Cotan;
  }
  const MeshOperators mo = build_mesh_operators(mesh, lk);
  InterpolationResult r = interpolate(mo.mesh, mo.ops, kind, cons, p);
  r.laplacian = mo.kind;
  r.laplacian_reason = kind == FieldKind::Tangent && p.laplacian == LaplacianKind::Auto
                           ? "tangent fields use the input triangles"
                           : mo.reason;
  return r;
}

std::vector<InterpolationConstraint> parse_constraints(const Mesh& mesh, const std::string& text, int m,
                                                       const std::string& path) {
  return parse_constraints([&](const std::string& spec) { return parse_vertex_spec(mesh, spec); }, text, m, path);
}

std::vector<InterpolationConstraint> parse_constraints(const std::function<int(const std::string&)>& vertex,
                                                       const std::string& text, int m, const std::string& path) {
  if (m < 1) throw InputError(fmt::format("{}: a constraint needs at least one value (asked for {})", path, m));
  // A vertex as the resolver reads it, its errors prefixed with the file and the place.
  auto parse_vertex = [&](const std::string& spec, const std::string& where) {
    try {
      return vertex(spec);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}: {}", path, where, e.what()));
    }
  };
  std::vector<InterpolationConstraint> out;
  auto add = [&](int v, std::vector<double> x, const std::string& where) {
    if (static_cast<int>(x.size()) != m)
      throw InputError(fmt::format("{}: {}: {} values, expected {}", path, where, x.size(), m));
    InterpolationConstraint c{v, Eigen::VectorXd(m)};
    for (int k = 0; k < m; ++k) {
      if (!std::isfinite(x[k])) throw InputError(fmt::format("{}: {}: value {} is not finite", path, where, k + 1));
      c.value[k] = x[k];
    }
    out.push_back(std::move(c));
  };
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && (text[first] == '{' || text[first] == '[')) {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {  // syntax, a number out of range, bad UTF-8
      throw InputError(fmt::format("{}: invalid JSON: {}", path, e.what()));
    }
    const nlohmann::json& list = j.is_array() ? j : j.value("constraints", nlohmann::json::array());
    if (!list.is_array()) throw InputError(fmt::format("{}: 'constraints' must be an array", path));
    for (std::size_t k = 0; k < list.size(); ++k) {
      const auto& e = list[k];
      const std::string where = fmt::format("constraint {}", k);
      if (!e.is_object() || !e.contains("vertex") || !e.contains("value"))
        throw InputError(fmt::format("{}: {}: needs 'vertex' and 'value'", path, where));
      const int v = e["vertex"].is_string() ? parse_vertex(e["vertex"].get<std::string>(), where)
                                            : parse_vertex(e["vertex"].dump(), where);
      std::vector<double> x;
      if (e["value"].is_number())
        x.push_back(e["value"].get<double>());
      else if (e["value"].is_array())
        for (const auto& q : e["value"]) {
          if (!q.is_number()) throw InputError(fmt::format("{}: {}: values must be numbers", path, where));
          x.push_back(q.get<double>());
        }
      else
        throw InputError(fmt::format("{}: {}: 'value' must be a number or an array", path, where));
      add(v, x, where);
    }
    return out;
  }
  for_each_text_record(text, FieldSeparator::Comma, [&](int line, const std::vector<std::string>& f) {
    const std::string where = fmt::format("line {}", line);
    if (out.empty() && !f[0].empty() && !std::isdigit(static_cast<unsigned char>(f[0][0]))) return;  // header
    const int v = parse_vertex(f[0], where);
    std::vector<double> x;
    for (std::size_t k = 1; k < f.size(); ++k) {
      char* end = nullptr;
      const double d = std::strtod(f[k].c_str(), &end);
      if (f[k].empty() || *end != '\0' || !std::isfinite(d))
        throw InputError(fmt::format("{}: {}: '{}' is not a number", path, where, f[k]));
      x.push_back(d);
    }
    add(v, x, where);
  });
  if (out.empty()) throw InputError(fmt::format("{}: no constraints", path));
  return out;
}

}  // namespace meshpde
