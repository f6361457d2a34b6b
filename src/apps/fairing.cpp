#include "meshpde/apps/fairing.h"

#include <fmt/format.h>

#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde {

const std::vector<double>& TriangleQuality::bin_edges() {
  static const std::vector<double> edges = {0, 0.01, 0.1, 0.5, 1, 2, 10, std::numeric_limits<double>::infinity()};
  return edges;
}

TriangleQuality triangle_quality(const Positions& V, const Triangles& F, const std::vector<int>& faces) {
  std::vector<int> list = faces;
  if (list.empty())
    for (int f = 0; f < F.rows(); ++f) list.push_back(f);
  TriangleQuality q;
  q.area_histogram.assign(TriangleQuality::bin_edges().size() - 1, 0);
  std::vector<double> area;
  double amin = std::numeric_limits<double>::infinity(), amax = 0;
  for (int f : list) {
    const Eigen::Vector3d p[3] = {V.row(F(f, 0)), V.row(F(f, 1)), V.row(F(f, 2))};
    const double A = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
    area.push_back(A);
    if (!(A > 0)) continue;
    amin = std::min(amin, A);
    amax = std::max(amax, A);
  }
  q.min_angle_deg = smallest_angle_deg(V, F, list);
  q.area_ratio = amax > 0 ? amax / amin : 0;
  double mean = 0;
  for (double A : area) mean += A / static_cast<double>(area.size());
  const auto& edges = TriangleQuality::bin_edges();
  for (double A : area) {
    const double r = mean > 0 ? A / mean : 0;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b)
      if (r >= edges[b] && r < edges[b + 1]) ++q.area_histogram[b];
  }
  return q;
}

FairResult fair(const Mesh& mesh, const std::vector<int>& fixed, const FairParams& p) {
  const int nv = mesh.num_vertices();
  if (p.order != 1 && p.order != 2) throw InputError(fmt::format("fairing order must be 1 or 2, got {}", p.order));
  if (fixed.empty()) throw InputError("fairing needs at least one fixed vertex");
  std::vector<char> is_fixed(nv, 0);
  for (int v : fixed) {
    if (v < 0 || v >= nv) throw InputError(fmt::format("fixed vertex {} does not exist (the mesh has {})", v, nv));
    is_fixed[v] = 1;
  }
  if (p.regularize && (!(p.dt > 0) || p.steps < 1 || !(p.damping >= 0)))
    throw InputError("regularization needs dt > 0, steps >= 1 and damping >= 0");
  // Faces touching a free vertex: where the triangulation can change.
  std::vector<int> free_faces;
  const auto& F = mesh.triangles();
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (!is_fixed[F(f, 0)] || !is_fixed[F(f, 1)] || !is_fixed[F(f, 2)]) free_faces.push_back(f);

  FairResult r;
  r.before = triangle_quality(mesh.positions(), F, free_faces);
  const double g1 = p.order == 1 ? 1.0 : 0.0, g2 = p.order == 2 ? 1.0 : 0.0;
  if (!p.regularize) {
    std::vector<int> free;
    for (int v = 0; v < nv; ++v)
      if (!is_fixed[v]) free.push_back(v);
    const MeshOperators mo = build_mesh_operators(mesh, p.laplacian);
    r.laplacian = mo.kind;
    r.laplacian_reason = mo.reason;
    SteadySolveResult s = solve_steady(mo.mesh, mo.ops, PdeCoefficients{.g0 = 0, .g1 = g1, .g2 = g2}, free,
                                       mesh.positions(), p.solver, kAutoGlobalFromFreeVertices, p.cg);
    r.V = std::move(s.values);
    r.solver = s.solver;
    r.worst_residual = s.relative_residual;
    r.cg_iterations = s.iterations;
    r.converged = s.converged;
    r.message = s.message;
    r.after = triangle_quality(r.V, F, free_faces);
    return r;
  }
  // Regularized: backward Euler steps, each on area-weighted operators of the current
  // surface.
  Mesh current = mesh;
  const int rounds = p.steps;
  r.solver = SteadySolver::Iterative;
  for (int k = 0; k < rounds; ++k) {
    OperatorOptions oo;
    oo.face_weights = face_areas(current);
    const double mean_area = oo.face_weights.mean();
    if (mean_area > 0) oo.face_weights /= mean_area;
    MeshOperators mo;
    mo.mesh = current;
    mo.ops = build_cotan_operators(current, oo);
    mo.reason = "area-weighted cotangent operators of the regularization";
    r.laplacian = mo.kind;
    r.laplacian_reason = mo.reason;
    // Damping acts on M (length^2): dividing by the mean area makes dt and damping
    // unit-free, so the same parameters work for a bunny in metres or a vessel in mm.
    const double b1 = p.damping / (mean_area > 0 ? mean_area : 1.0);
    const PdeCoefficients c{.alpha = 0, .b1 = b1, .b2 = 0, .g0 = 0, .g1 = g1, .g2 = g2};
    PdeSession s(mo.mesh, mo.ops, 3, c, DomainOptions{.seed_rings = 0});
    s.cg_options = p.cg;
    s.set_values(current.positions());
    for (int v = 0; v < nv; ++v) {
      if (is_fixed[v]) s.constrain(v, std::span<const double>(current.positions().row(v).data(), 3));
    }
    std::vector<int> free;
    for (int v = 0; v < nv; ++v)
      if (!is_fixed[v]) free.push_back(v);
    s.activate(free);
    const StepResult sr = s.step(p.dt);
    r.cg_iterations += sr.cg.iterations;
    r.worst_residual = std::max(r.worst_residual, sr.cg.relative_residual);
    if (!sr.cg.converged()) {  // stop at the last good surface; the caller reports it
      r.converged = false;
      r.message = fmt::format("step {} of {}: {}", k + 1, rounds, sr.cg.message);
      break;
    }
    Positions next = s.values();
    for (int v = 0; v < nv; ++v)
      if (is_fixed[v]) next.row(v) = mesh.positions().row(v);  // exactly unchanged
    current.set_positions(next);
  }
  r.V = current.positions();
  r.after = triangle_quality(r.V, F, free_faces);
  return r;
}

}  // namespace meshpde
