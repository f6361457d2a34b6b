// The finite-element correction's solve: the operators of the region's copy, the
// boundary's foundation, the handles' constraints, image guidance and the dynamic steps.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <set>

#include "correction_internal.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/topology.h"

namespace meshpde::correction {

FemSetup fem_setup(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem) {
  FemSetup s;
  s.mo = build_mesh_operators(mesh, p.laplacian, operator_weights(p, mesh.num_vertices()));
  std::set<int> handles;
  for (const auto& h : problem.held) handles.insert(h.vertex);
  for (int v : problem.region)
    if (!handles.count(v) && s.mo.ops.mass[v] > 0) s.free.push_back(v);
  s.length_scale = p.radius > 0 ? p.radius : std::max(1e-12, p.rings * mean_edge_length(mesh));
  return s;
}

// The boundary's foundation on the diagonal (#V values; zero for the clamp): the
// fade's kappa(r) M_i, r the edge-path distance from the nearest handle vertex, or
// smooth's kappa(s) M_i, s the surface distance from the handles.
Eigen::VectorXd foundations(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const FemSetup& s) {
  const int nv = mesh.num_vertices();
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(nv);
  if (fades(p)) {
    const std::vector<int>& hv = problem.sources;
    const double R = p.radius;
    // Scaled as the operator is (the dynamic mode weighs it by the elasticity).
    const double kappa0 =
        kFadeStrength * (p.dynamic ? p.tissue.elasticity : 1.0) * (p.g2 / std::pow(R, 4) + p.g1 / (R * R));
    std::vector<char> is_free(static_cast<std::size_t>(nv), 0);
    for (int v : s.free) is_free[static_cast<std::size_t>(v)] = 1;
    for (const auto& [v, dist] : geodesic_distances(mesh, hv, kFadeReach * R + 1e-9 * R)) {
      const double x = std::max(0.0, (dist - kFadeStart * R) / ((1 - kFadeStart) * R));
      if (is_free[static_cast<std::size_t>(v)]) extra[v] += kappa0 * x * x * x * s.mo.ops.mass[v];
    }
  }
  if (smooth(p)) {
    // Scaled as the operator is (the dynamic mode weighs it by the elasticity). Refuses
    // a radius too small for the foundation's scale even when every region vertex is a
    // handle's own (below), which carries none.
    const double e = p.dynamic ? p.tissue.elasticity : 1.0;
    const SmoothFoundation kappa(p.radius, e * p.g1, e * p.g2);
    // The triangles a handle point lies on carry no foundation: with a radius below
    // an edge they are the whole region, and they must move.
    std::vector<char> own(static_cast<std::size_t>(nv), 0);
    for (const auto& h : problem.loaded)
      for (const int v : h.corners) own[static_cast<std::size_t>(v)] = 1;
    for (std::size_t k = 0; k < problem.region.size(); ++k) {
      const int v = problem.region[k];
      if (own[static_cast<std::size_t>(v)]) continue;
      extra[v] += kappa(problem.distance[k]) * s.mo.ops.mass[v];
    }
  }
  return extra;
}

HandleConstraints::HandleConstraints(const SteadyDirectSolver& solver, const std::vector<LoadedHandle>& handles, int nv)
    : handles_(handles) {
  const int n = static_cast<int>(handles.size());
  if (n == 0) return;
  Field load = Field::Zero(nv, n);
  for (int l = 0; l < n; ++l)
    for (const auto& [v, w] : handles[static_cast<std::size_t>(l)].load) load(v, l) = w;
  U_ = solver.solve(Field::Zero(nv, n), &load);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k)
    for (const auto& [v, w] : handles[static_cast<std::size_t>(k)].reading) S.row(k) += w * U_.row(v);
  lu_.compute(S);
  if (lu_.rank() < n || !(std::abs(lu_.determinant()) > 0))
    throw InputError("two handles are too close to be moved independently: give them further apart, or one handle");
}

void HandleConstraints::apply(Field& d, double fraction) const {
  std::vector<Eigen::Vector3d> targets;
  for (const auto& h : handles_) targets.push_back(fraction * h.displacement);
  apply(d, targets);
}

void HandleConstraints::apply(Field& d, const std::vector<Eigen::Vector3d>& targets) const {
  const int n = static_cast<int>(handles_.size());
  if (n == 0) return;
  Eigen::MatrixXd rhs(n, 3);
  for (int k = 0; k < n; ++k) {
    Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
    for (const auto& [v, w] : handles_[static_cast<std::size_t>(k)].reading) at += w * d.row(v);
    rhs.row(k) = targets[static_cast<std::size_t>(k)].transpose() - at;
  }
  const Eigen::MatrixXd c = lu_.solve(rhs);
  d += U_ * c;
}

namespace {

// One Fem solve on `mesh` (the region and its margin only) for the handles scaled by
// `fraction`; returns d.
Field fem_solve_local(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, double fraction,
                      CorrectionResult& r) {
  FemSetup s = fem_setup(mesh, p, problem);
  r.laplacian = s.mo.kind;
  r.laplacian_reason = s.mo.reason;
  const int nv = mesh.num_vertices();
  Field held = Field::Zero(nv, 3);
  for (const auto& h : problem.held) held.row(h.vertex) = fraction * h.displacement.transpose();
  const bool guided = p.image.edges != nullptr;
  const double L = s.length_scale;
  // Stiffness of the region's slowest mode (wavelength about 2 L), per unit area.
  const double stiff = std::max(p.g2 * std::pow(M_PI / L, 4) + p.g1 * std::pow(M_PI / L, 2), 1e-300);
  Eigen::VectorXd extra = foundations(mesh, p, problem, s);
  // Image guidance: every free vertex of the region inside the image is tied to its
  // target by a spring lambda M_i; weight 1 makes the pull as strong as the region's
  // slowest bending mode, so edges win over smoothness at that scale and above. A
  // vertex outside the image (a region across the edge of the scan's field of view)
  // has nothing to be pulled to: it gets no spring and follows the drag unguided,
  // instead of being tied to where it was.
  std::vector<int> pulled;
  int outside = 0;
  const double lambda = p.image.weight * stiff;
  if (guided)
    for (int v : s.free) {
      if (!p.image.edges->sample(mesh.positions().row(v).transpose(), p.image.space)) {
        ++outside;
        continue;
      }
      pulled.push_back(v);
      extra[v] += lambda * s.mo.ops.mass[v];
    }
  // Dynamic: implicit steps of alpha M d'' + b1 M d' + Kt d = f with the thesis's
  // parameters (TissueParams, apps/vessel_correction.h), per vertex: alpha_i M_i and
  // b1_i M_i, and (alpha_i / dt^2 + b1_i / dt) M_i joins the diagonal. Scalars are
  // constant fields.
  const double e = p.tissue.elasticity;  // the largest of an elasticity field (normalized())
  Eigen::VectorXd alpha = Eigen::VectorXd::Zero(nv), b1 = Eigen::VectorXd::Zero(nv);
  double alpha_min = std::numeric_limits<double>::infinity();
  for (int v : s.free) {
    alpha[v] = std::max(tissue_at(p.tissue.mass_field, p.tissue.mass, v), 1e-6);
    alpha_min = std::min(alpha_min, alpha[v]);
  }
  if (s.free.empty()) alpha_min = std::max(p.tissue.mass, 1e-6);
  const double k_eff = std::max(e, 1e-6) * stiff;
  const double omega = std::sqrt(k_eff / alpha_min);
  // A quarter of 1/omega a step (omega of the stiffest, lightest tissue): backward
  // Euler's own damping stays small against the tissue's (so viscosity matters), and
  // the default 50 steps span 12.5 / omega.
  const double dt = 0.25 / omega;
  for (int v : s.free) {
    const double k_v = std::max(tissue_at(p.tissue.elasticity_field, e, v), 1e-6) * stiff;
    b1[v] = 2 * tissue_at(p.tissue.viscosity_field, p.tissue.viscosity, v) * std::sqrt(alpha[v] * k_v);
  }
  const PdeCoefficients coef{.g0 = 0, .g1 = p.dynamic ? e * p.g1 : p.g1, .g2 = p.dynamic ? e * p.g2 : p.g2};
  if (p.dynamic)
    for (int v : s.free) extra[v] += (alpha[v] / (dt * dt) + b1[v] / dt) * s.mo.ops.mass[v];
  // Auto: the multigrid's try on a large static, unguided region without the fade's
  // foundation (the cases the global solver takes), kept where it converges; the direct
  // solve (with its condition estimate) otherwise.
  const bool plain_static = !p.dynamic && !guided && !(extra.maxCoeff() > 0) && problem.loaded.empty();
  r.solver = p.solver == SteadySolver::Auto ? SteadySolver::Direct : p.solver;
  if (p.solver == SteadySolver::Auto && plain_static && auto_tries_multigrid(s.mo.mesh, coef, s.free))
    if (std::optional<SteadySolveResult> g = try_multigrid_solve(s.mo.mesh, s.mo.ops, coef, s.free, held)) {
      r.solver = SteadySolver::Global;
      r.relative_residual = std::max(r.relative_residual, g->relative_residual);
      return std::move(g->values);
    }
  if (r.solver != SteadySolver::Direct) {  // static and unguided (validate() made sure)
    SteadySolveResult sr =
        solve_steady(s.mo.mesh, s.mo.ops, coef, s.free, held, r.solver, kAutoGlobalFromFreeVertices, p.cg);
    r.relative_residual = std::max(r.relative_residual, sr.relative_residual);
    if (!sr.converged) {
      r.converged = false;
      r.solver_message = sr.message;
    }
    return std::move(sr.values);
  }
  const SteadyDirectSolver solver(s.mo.mesh, s.mo.ops, coef, s.free, SparseCholesky::Backend::Auto,
                                  extra.maxCoeff() > 0 ? extra : Eigen::VectorXd());
  const HandleConstraints constraints(solver, problem.loaded, nv);
  const Eigen::MatrixX3d normals = guided ? vertex_normals(mesh) : Eigen::MatrixX3d();
  const auto& V = mesh.positions();
  auto image_load = [&](const Field& d, Field& f) {
    if (!guided) return;
    Positions Q = V + d;
    const ImageTargets t = find_targets(p.image, pulled, Q, normals);
    for (std::size_t k = 0; k < t.vertices.size(); ++k) {
      const int i = t.vertices[k];
      // lambda M_i (target - p_i): the spring's rest point, relative to the original position.
      f.row(i) += lambda * s.mo.ops.mass[i] * (t.target[k] - V.row(i).transpose()).transpose();
    }
  };
  Field d = held;
  double worst = 0;
  if (!p.dynamic) {
    const int passes = guided ? std::max(1, p.image.passes) : 1;
    for (int pass = 0; pass < passes; ++pass) {
      Field f = Field::Zero(nv, 3);
      image_load(d, f);
      d = solver.solve(held, guided ? &f : nullptr);
      worst = std::max(worst, solver.last_relative_residual());
      constraints.apply(d, fraction);
    }
  } else {
    Field prev = Field::Zero(nv, 3), cur = Field::Zero(nv, 3);
    for (const auto& h : problem.held) cur.row(h.vertex) = prev.row(h.vertex) = held.row(h.vertex);
    for (int step = 0; step < p.steps; ++step) {
      Field f = Field::Zero(nv, 3);
      for (int v : s.free)
        f.row(v) = s.mo.ops.mass[v] * (alpha[v] / (dt * dt) * (2 * cur.row(v) - prev.row(v)) + b1[v] / dt * cur.row(v));
      image_load(cur, f);
      Field next = solver.solve(held, &f);
      worst = std::max(worst, solver.last_relative_residual());
      constraints.apply(next, fraction);
      prev = cur;
      cur = next;
    }
    d = cur;
  }
  r.relative_residual = std::max(r.relative_residual, worst);
  // Whether these solves can be trusted to 1e-5 of the drag (badly shaped meshes with
  // the plain cotangent operator cannot): a few extra solves with the same factor.
  const SteadyDirectSolver::Conditioning cond = solver.conditioning();
  r.condition_estimate = std::max(r.condition_estimate, cond.condition_1);
  r.error_bound = std::max(r.error_bound, cond.relative_error);
  if (!cond.sufficient) r.accuracy_warning = cond.message;
  if (guided) {
    r.pulled_vertices = static_cast<int>(pulled.size());
    r.image_outside_vertices = outside;
    r.image_mean_edge_before = mean_edge_strength(p.image, pulled, V);
    r.image_mean_edge_after = mean_edge_strength(p.image, pulled, V + d);
  }
  return d;
}

}  // namespace

// A correction's parameters and problem in a region copy's numbering.
CorrectionParams localized(const RegionCopy& c, const CorrectionParams& p) {
  CorrectionParams lp = p;
  auto localize = [&](const Eigen::VectorXd& field, Eigen::VectorXd& local) {
    if (field.size() == 0) return;
    local.resize(static_cast<Eigen::Index>(c.to_mesh.size()));
    for (std::size_t k = 0; k < c.to_mesh.size(); ++k) local[static_cast<Eigen::Index>(k)] = field[c.to_mesh[k]];
  };
  localize(p.stiffness, lp.stiffness);
  localize(p.tissue.mass_field, lp.tissue.mass_field);
  localize(p.tissue.elasticity_field, lp.tissue.elasticity_field);
  localize(p.tissue.viscosity_field, lp.tissue.viscosity_field);
  return lp;
}

FemProblem localized(const RegionCopy& c, const FemProblem& problem) {
  FemProblem local;
  local.distance = problem.distance;
  local.region.reserve(problem.region.size());
  for (const int v : problem.region) local.region.push_back(c.local(v));
  for (const int v : problem.sources) local.sources.push_back(c.from_mesh.count(v) ? c.local(v) : -1);
  std::erase(local.sources, -1);
  for (CorrectionHandle h : problem.held) {
    h.vertex = c.local(h.vertex);
    local.held.push_back(h);
  }
  // A load reaching beyond the copy (a handle larger than the region) acts on held
  // vertices there, where it does nothing.
  auto in_copy = [&](const std::vector<std::pair<int, double>>& weights) {
    std::vector<std::pair<int, double>> out;
    for (const auto& [v, w] : weights)
      if (const auto it = c.from_mesh.find(v); it != c.from_mesh.end()) out.emplace_back(it->second, w);
    return out;
  };
  for (const LoadedHandle& h : problem.loaded) {
    LoadedHandle l{{in_copy(h.load), in_copy(h.reading), {}}, h.displacement};
    for (const int v : h.corners) l.corners.push_back(c.local(v));
    local.loaded.push_back(std::move(l));
  }
  return local;
}

Field fem_solve(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, double fraction,
                CorrectionResult& r) {
  const RegionCopy c = copy_region(mesh, problem.region, kCorrectionMarginRings);
  if (c.whole) return fem_solve_local(mesh, p, problem, fraction, r);
  const Field dl = fem_solve_local(c.mesh, localized(c, p), localized(c, problem), fraction, r);
  Field d = Field::Zero(mesh.num_vertices(), 3);
  for (std::size_t k = 0; k < c.to_mesh.size(); ++k) d.row(c.to_mesh[k]) = dl.row(static_cast<Eigen::Index>(k));
  return d;
}

}  // namespace meshpde::correction
