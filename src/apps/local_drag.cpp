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

}  // namespace meshpde
