#include "meshpde/apps/local_drag.h"

#include <fmt/format.h>

#include <algorithm>
#include <queue>
#include <unordered_map>

#include "meshpde/core/errors.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde {

std::vector<int> geodesic_ball(const Mesh& mesh, int source, double radius) {
  const auto& V = mesh.positions();
  std::unordered_map<int, double> dist{{source, 0.0}};
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
  heap.emplace(0.0, source);
  std::vector<int> out;
  while (!heap.empty()) {
    const auto [d, v] = heap.top();
    heap.pop();
    if (d > dist[v]) continue;
    out.push_back(v);
    for (int w : mesh.neighbors(v)) {
      const double dw = d + (V.row(v) - V.row(w)).norm();
      if (dw >= radius) continue;
      auto it = dist.find(w);
      if (it == dist.end() || dw < it->second) {
        dist[w] = dw;
        heap.emplace(dw, w);
      }
    }
  }
  return out;
}

std::vector<int> ring_ball(const Mesh& mesh, int source, int rings) {
  std::unordered_map<int, int> level{{source, 0}};
  std::vector<int> out{source};
  for (std::size_t k = 0; k < out.size(); ++k) {
    const int v = out[k];
    if (level[v] >= rings) continue;
    for (int w : mesh.neighbors(v))
      if (level.emplace(w, level[v] + 1).second) out.push_back(w);
  }
  return out;
}

DragResult drag_vertex(const Mesh& mesh, const FemOperators& ops, const DragParams& p) {
  if (p.vertex < 0 || p.vertex >= mesh.num_vertices())
    throw InputError(
        fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", p.vertex, mesh.num_vertices()));
  if (!p.displacement.allFinite()) throw InputError("displacement is not finite");
  if (p.radius <= 0 && p.rings <= 0) throw InputError("give a region of influence: a radius > 0 or rings > 0");
  if (ops.mass[p.vertex] <= 0) throw InputError(fmt::format("handle vertex {} has no incident area", p.vertex));
  DragResult r;
  r.region = p.radius > 0 ? geodesic_ball(mesh, p.vertex, p.radius) : ring_ball(mesh, p.vertex, p.rings);
  if (p.solver == SteadySolver::Direct) {
    r.region.erase(std::remove(r.region.begin(), r.region.end(), p.vertex), r.region.end());
    std::vector<int> free;
    for (int v : r.region)
      if (ops.mass[v] > 0) free.push_back(v);
    const SteadyDirectSolver solver(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = p.g1, .g2 = p.g2}, free);
    Field held = Field::Zero(mesh.num_vertices(), 3);
    held.row(p.vertex) = p.displacement.transpose();
    r.displacement = solver.solve(held);
    r.cg = CgResult{.status = CgStatus::Converged,
                    .iterations = 0,
                    .relative_residual = solver.last_relative_residual(),
                    .message = {}};
    // Reaction at the handle: row of Kt applied to the solution (steady: no inertia).
    for (int c = 0; c < 3; ++c) {
      auto d = [&](int j) { return r.displacement(j, c); };
      r.reaction[c] = p.g1 * stiffness_row(mesh, ops, p.vertex, d) + p.g2 * bilaplacian_row(mesh, ops, p.vertex, d);
    }
  } else {
    PdeSession s(mesh, ops, 3, PdeCoefficients{.alpha = 0, .b1 = 0, .b2 = 0, .g1 = p.g1, .g2 = p.g2},
                 DomainOptions{.seed_rings = 0});
    s.cg_options = p.cg;
    s.activate(r.region);
    s.constrain(p.vertex, std::span<const double>(p.displacement.data(), 3));
    r.region.erase(std::remove(r.region.begin(), r.region.end(), p.vertex), r.region.end());
    r.cg = s.solve_steady().cg;
    r.displacement = s.values();
    r.reaction = s.reaction_forces().row(0).transpose();
  }
  r.V = mesh.positions() + r.displacement;
  const double scale = p.displacement.norm();
  for (int v : r.region) {
    const double d = r.displacement.row(v).norm();
    r.max_displacement = std::max(r.max_displacement, d);
    r.moved_vertices += d > 1e-6 * scale;
  }
  r.max_displacement = std::max(r.max_displacement, scale);
  r.moved_vertices += scale > 0;
  return r;
}

DragSession::DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles,
                         const DragSessionParams& params)
    : mesh_(mesh), ops_(ops), params_(params), handles_(std::move(handles)) {
  const int nv = mesh.num_vertices();
  if (handles_.empty()) throw InputError("a drag session needs at least one handle");
  for (int h : handles_) {
    if (h < 0 || h >= nv)
      throw InputError(fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", h, nv));
    if (ops.mass[h] <= 0) throw InputError(fmt::format("handle vertex {} has no incident area", h));
    if (std::count(handles_.begin(), handles_.end(), h) > 1)
      throw InputError(fmt::format("handle vertex {} is listed twice", h));
  }
  if (params.radius <= 0 && params.rings <= 0)
    throw InputError("give a region of influence: a radius > 0 or rings > 0");
  std::vector<int> region =
      params.radius > 0 ? geodesic_ball(mesh, handles_[0], params.radius) : ring_ball(mesh, handles_[0], params.rings);
  auto handle = [&](int v) { return std::find(handles_.begin(), handles_.end(), v) != handles_.end(); };
  std::vector<int> free;
  for (int v : region)
    if (!handle(v) && ops.mass[v] > 0) free.push_back(v);
  handle_in_region_.assign(handles_.size(), false);
  build(std::move(free));
}

void DragSession::build(std::vector<int> free) {
  solver_ = std::make_unique<SteadyDirectSolver>(
      mesh_, ops_, PdeCoefficients{.g0 = 0, .g1 = params_.g1, .g2 = params_.g2}, std::move(free));
  ++factorizations_;
  // Handles outside the free set couple through the right-hand side; handles inside it
  // (added earlier) are constrained by the Green's-function updates of add_handle().
  const std::vector<int> outside_handles = [&] {
    std::vector<int> o;
    for (std::size_t k = 0; k < handles_.size(); ++k)
      if (!handle_in_region_[k]) o.push_back(handles_[k]);
    return o;
  }();
  Eigen::MatrixXd rhs(solver_->num_free(), static_cast<Eigen::Index>(outside_handles.size()));
  for (std::size_t k = 0; k < outside_handles.size(); ++k)
    rhs.col(static_cast<Eigen::Index>(k)) = solver_->coupling(outside_handles[k]);
  const Eigen::MatrixXd outside_basis = solver_->solve_rhs(rhs);
  ++solves_;
  basis_.setZero(solver_->num_free(), static_cast<Eigen::Index>(handles_.size()));
  for (std::size_t k = 0, o = 0; k < handles_.size(); ++k)
    if (!handle_in_region_[k])
      basis_.col(static_cast<Eigen::Index>(k)) = outside_basis.col(static_cast<Eigen::Index>(o++));
  // Handles inside the free set (added earlier, kept as rows across a grow): constrain
  // them again, one by one, as add_handle() did.
  for (std::size_t k = 0; k < handles_.size(); ++k)
    if (handle_in_region_[k]) {
      handle_in_region_[k] = false;
      constrain(k);
    }
}

void DragSession::constrain(std::size_t k) {
  const int row = solver_->free_index(handles_[k]);
  // g: the Green's function of the current constrained system at the handle. A^-1 e is
  // the unconstrained one; subtracting the current basis columns of the handles already
  // constrained inside the region (each 1 at its own handle, 0 at the others, harmonic
  // elsewhere) zeroes it at those handles and keeps A g = e on the remaining free rows.
  Eigen::VectorXd e = Eigen::VectorXd::Zero(solver_->num_free());
  e[row] = 1;
  Eigen::VectorXd g = solver_->solve_rhs(e);
  ++solves_;
  for (std::size_t j = 0; j < handles_.size(); ++j)
    if (handle_in_region_[j]) g -= g[solver_->free_index(handles_[j])] * basis_.col(static_cast<Eigen::Index>(j));
  if (!(std::abs(g[row]) > 0))
    throw SolverError(
        fmt::format("vertex {} cannot become a handle: its Green's function vanishes there", handles_[k]));
  const Eigen::VectorXd y = g / g[row];
  // Every other column must now be 0 at the new handle: subtract its value there times
  // the new column (1 there, harmonic on the remaining free rows).
  for (Eigen::Index j = 0; j < basis_.cols(); ++j)
    if (j != static_cast<Eigen::Index>(k)) basis_.col(j) -= basis_(row, j) * y;
  basis_.col(static_cast<Eigen::Index>(k)) = y;
  handle_in_region_[k] = true;
}

void DragSession::add_handle(int vertex) {
  if (solver_->free_index(vertex) < 0 || std::find(handles_.begin(), handles_.end(), vertex) != handles_.end())
    throw InputError(fmt::format("vertex {} is not a free vertex of the drag region", vertex));
  handles_.push_back(vertex);
  handle_in_region_.push_back(false);
  basis_.conservativeResize(Eigen::NoChange, basis_.cols() + 1);
  basis_.col(basis_.cols() - 1).setZero();
  constrain(handles_.size() - 1);
}

void DragSession::grow(int rings) {
  if (rings < 1) throw InputError("grow by at least one ring");
  std::vector<int> free = solver_->free_vertices();
  std::vector<char> mark(static_cast<std::size_t>(mesh_.num_vertices()), 0);
  for (int v : free) mark[static_cast<std::size_t>(v)] = 1;
  for (std::size_t k = 0; k < handles_.size(); ++k)
    if (!handle_in_region_[k]) mark[static_cast<std::size_t>(handles_[k])] = 1;
  std::vector<int> front = free;
  for (int r = 0; r < rings; ++r) {
    std::vector<int> next;
    for (int v : front)
      for (int w : mesh_.neighbors(v))
        if (!mark[static_cast<std::size_t>(w)] && ops_.mass[w] > 0) {
          mark[static_cast<std::size_t>(w)] = 1;
          next.push_back(w);
        }
    free.insert(free.end(), next.begin(), next.end());
    front = std::move(next);
  }
  build(std::move(free));
}

Eigen::MatrixXd DragSession::displacements(const Eigen::MatrixXd& d) const {
  if (d.rows() != static_cast<Eigen::Index>(handles_.size()) || d.cols() != 3)
    throw InputError(
        fmt::format("expected {} x 3 handle displacements, got {} x {}", handles_.size(), d.rows(), d.cols()));
  return basis_ * d;
}

Positions DragSession::positions(const Eigen::MatrixXd& d) const {
  const Eigen::MatrixXd x = displacements(d);
  Positions V = mesh_.positions();
  const auto& free = region();
  for (std::size_t k = 0; k < free.size(); ++k) V.row(free[k]) += x.row(static_cast<Eigen::Index>(k));
  for (std::size_t k = 0; k < handles_.size(); ++k)
    V.row(handles_[k]) = mesh_.positions().row(handles_[k]) + d.row(static_cast<Eigen::Index>(k));
  return V;
}

}  // namespace meshpde
