#include "meshpde/apps/local_drag.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>

#include "../core/index_map.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/refinement.h"

namespace meshpde {

DragResult drag_vertex(const Mesh& mesh, const FemOperators& ops, const DragParams& p) {
  if (p.vertex < 0 || p.vertex >= mesh.num_vertices())
    throw InputError(
        fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", p.vertex, mesh.num_vertices()));
  if (!p.displacement.allFinite()) throw InputError("displacement is not finite");
  if (std::isnan(p.radius)) throw InputError("the region's radius is not a number");
  if (p.radius <= 0 && p.rings <= 0) throw InputError("give a region of influence: a radius > 0 or rings > 0");
  if (ops.mass[p.vertex] <= 0) throw InputError(fmt::format("handle vertex {} has no incident area", p.vertex));
  DragResult r;
  if (std::isnan(p.handle_radius)) throw InputError("the handle's radius is not a number");
  if (p.boundary == RegionBoundary::Smooth && p.radius > 0) {
    if (p.solver == SteadySolver::Global || p.solver == SteadySolver::Iterative)
      throw InputError(
          fmt::format("the smooth boundary solves with the direct solver, not '{}': ask for the clamp "
                      "boundary to solve with it",
                      to_string(p.solver)));
    // The smooth rule's solve is DragSession's (one factor, refined), so both agree.
    const DragSession s(
        mesh, ops, {p.vertex},
        DragSessionParams{
            .radius = p.radius, .handle_radius = p.handle_radius, .g1 = p.g1, .g2 = p.g2, .boundary = p.boundary});
    const Eigen::MatrixXd x = s.displacements(p.displacement.transpose());
    r.displacement = Field::Zero(mesh.num_vertices(), 3);
    for (std::size_t k = 0; k < s.region().size(); ++k)
      r.displacement.row(s.region()[k]) = x.row(static_cast<Eigen::Index>(k));
    r.displacement.row(p.vertex) = p.displacement.transpose();
    r.region = s.region();
    std::erase(r.region, p.vertex);  // a handle with a size is a row of the solve
    r.solver = SteadySolver::Direct;
    r.cg.relative_residual = s.last_relative_residual();
    r.reaction = s.forces(p.displacement.transpose()).row(0).transpose();
  } else {
    if (p.handle_radius > 0)
      throw InputError("a handle with a size needs the smooth boundary and a region given by radius");
    r.region = region_around(mesh, p.vertex, RegionSpec{.radius = p.radius, .rings = p.radius > 0 ? 0 : p.rings});
    r.region.erase(std::remove(r.region.begin(), r.region.end(), p.vertex), r.region.end());
    std::vector<int> free;
    for (int v : r.region)
      if (ops.mass[v] > 0) free.push_back(v);
    Field held = Field::Zero(mesh.num_vertices(), 3);
    held.row(p.vertex) = p.displacement.transpose();
    SteadySolveResult s = solve_steady(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = p.g1, .g2 = p.g2}, free, held,
                                       p.solver, kAutoGlobalFromFreeVertices, p.cg);
    r.displacement = std::move(s.values);
    r.solver = s.solver;
    r.cg = s.cg();
    // Reaction at the handle: row of Kt applied to the solution (steady: no inertia).
    for (int c = 0; c < 3; ++c) {
      auto d = [&](int j) { return r.displacement(j, c); };
      r.reaction[c] = p.g1 * stiffness_row(mesh, ops, p.vertex, d) + p.g2 * bilaplacian_row(mesh, ops, p.vertex, d);
    }
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

struct DragSession::Factor {
  // Factored rows: the core of the region (nested dissection order), then, with a margin, the
  // region's outermost ring and one ring outside it. Every `levels` entry is a leading
  // block that can be the region (its factor is the leading block of L).
  std::vector<int> vertices;
  IndexMap row;                   // vertex -> row of `vertices`
  Eigen::SparseMatrix<double> A;  // Kt on `vertices`, symmetric, both triangles
  // Cholesky factor in the order of `vertices`: every leading block's factor is the
  // leading block of L. Without margins (one level, the whole factor) and with enough
  // rows, the two-thread split factor instead.
  LeadingBlockCholesky chol;
  SplitCholesky split;
  bool use_split = false;
  std::vector<Eigen::Index> levels;  // possible region sizes, ascending
  std::size_t level = 0;             // levels[level] == active
  Eigen::Index active = 0;           // leading rows in use (the region)
  double norm_inf = 0;               // |A_aa|_inf of the leading block (set_active)

  void set_active(Eigen::Index n) {
    active = n;
    norm_inf = 0;  // |A_aa|_inf = |A_aa|_1 (symmetric)
    for (Eigen::Index j = 0; j < n; ++j) {
      double sum = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
        if (it.row() < n) sum += std::abs(it.value());
      norm_inf = std::max(norm_inf, sum);
    }
  }

  // X = A_aa^-1 X for the leading `active` rows (all columns in one pass over L).
  void solve_leading(Eigen::MatrixXd& X) const { X = use_split ? split.solve(X) : chol.solve_leading(X); }
  // Y = A_aa X on the leading rows (row-major copies: each entry of A updates all columns).
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Eigen::MatrixXd multiply_leading(const Eigen::MatrixXd& X) const {
    const RowMajor Xr = X;
    RowMajor Y = RowMajor::Zero(active, X.cols());
    const Eigen::Index m = X.cols();
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    const double* val = A.valuePtr();
    for (Eigen::Index j = 0; j < active; ++j) {
      const double* xj = Xr.data() + j * m;
      for (int q = outer[j]; q < outer[j + 1]; ++q)
        if (inner[q] < active) {
          double* yi = Y.data() + static_cast<Eigen::Index>(inner[q]) * m;
          for (Eigen::Index c = 0; c < m; ++c) yi[c] += val[q] * xj[c];
        }
    }
    return Y;
  }
};

namespace {
// From this many core vertices (no margins) the region is factored on two threads
// (SplitCholesky). Measured against one factor of the whole region, same runs: 867 rows
// 1.0 against 1.2 ms, 1,950 rows 2.5 against 3.2 ms, 9,888 rows 11-13 against 15 ms.
constexpr Eigen::Index kSplitFactorFrom = 1000;
}  // namespace

DragSession::~DragSession() = default;
DragSession::DragSession(DragSession&&) noexcept = default;

struct DragSession::Region {
  std::vector<int> vertices;
  bool smooth = false;
  std::vector<std::pair<int, double>> foundation;  // Smooth: (vertex, kappa(s) M_i)
  std::vector<HandleLoad> loads;                   // per handle; an empty load: a held vertex
  std::vector<bool> at_point;                      // per handle
  double size = 0;                                 // the handles' size
};

DragSession::Region DragSession::region_of(const Mesh& mesh, const FemOperators& ops, std::vector<int>& handles,
                                           const std::vector<SurfacePoint>& points, const DragSessionParams& p) {
  if (handles.empty() && points.empty()) throw InputError("a drag session needs at least one handle");
  for (const int h : handles)
    if (h < 0 || h >= mesh.num_vertices())
      throw InputError(
          fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", h, mesh.num_vertices()));
  for (std::size_t k = 0; k < points.size(); ++k)
    check_surface_point(mesh, points[k], fmt::format("handle point {}", k));
  if (std::isnan(p.radius)) throw InputError("the region's radius is not a number");
  if (std::isnan(p.handle_radius)) throw InputError("the handle's radius is not a number");
  if (p.radius <= 0 && p.rings <= 0) throw InputError("give a region of influence: a radius > 0 or rings > 0");
  if (p.boundary == RegionBoundary::Fade)
    throw InputError("a drag session's region ends by the smooth boundary or the clamp, not the fade");
  Region r;
  r.at_point.assign(handles.size(), false);
  r.at_point.resize(handles.size() + points.size(), true);
  for (const SurfacePoint& q : points) handles.push_back(nearest_corner(mesh, q));
  r.loads.resize(handles.size());
  if (p.radius <= 0 || p.boundary == RegionBoundary::Clamp) {
    if (!points.empty() || p.handle_radius > 0)
      throw InputError(
          "handles at surface points or with a size need the smooth boundary and a region given by radius");
    r.vertices = region_around(mesh, handles[0], RegionSpec{.radius = p.radius, .rings = p.radius > 0 ? 0 : p.rings});
    return r;
  }
  if (p.margin || p.inner_margin)
    throw InputError(
        "margins grow and shrink a region by rings, and the smooth boundary's region is fixed by its radius: "
        "ask for the clamp boundary with margins");
  // The correction's smooth rule: the surface within the radius of every handle, each
  // free vertex tied by the foundation of its distance from the nearest; handles of a
  // quarter of the radius by default, a point's triangle always in the region.
  r.smooth = true;
  r.size = p.handle_radius < 0 ? kHandleRadiusFraction * p.radius : p.handle_radius;
  const SmoothFoundation kappa(p.radius, p.g1, p.g2);
  std::unordered_map<int, double> distance;
  GeodesicSources sources{.vertices = std::vector<int>(handles.begin(), handles.end() - std::ssize(points)),
                          .points = points};
  for (const auto& [v, s] : geodesic_distances_from(mesh, sources, p.radius)) distance.emplace(v, s);
  for (const SurfacePoint& q : points)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles()(q.face, k);
      distance.emplace(v, (mesh.positions().row(v).transpose() - position(mesh, q)).norm());
    }
  bool anchored = false;
  for (const auto& [v, s] : distance) {
    r.vertices.push_back(v);
    if (const double k = kappa(s) * ops.mass[v]; k > 0) r.foundation.emplace_back(v, k);
    anchored = anchored || s > kSmoothStart * p.radius;
  }
  std::sort(r.vertices.begin(), r.vertices.end());
  std::sort(r.foundation.begin(), r.foundation.end());
  // A region without a foundation that covers its whole part of the surface moves with
  // its handles as a rigid body, which no load can do (the system would be singular):
  // its handles are then held at their vertices (a point's nearest corner), as a
  // correction's are.
  for (std::size_t k = 0; k < r.vertices.size() && !anchored; ++k)
    for (const int w : mesh.neighbors(r.vertices[k]))
      if (!distance.count(w)) anchored = true;
  if (!anchored) {
    r.at_point.assign(handles.size(), false);
    return r;
  }
  for (std::size_t k = 0; k < handles.size(); ++k)
    if (r.at_point[k] || r.size > 0)
      r.loads[k] = handle_load(
          mesh, handles[k], r.at_point[k] ? std::optional(points[k - (handles.size() - points.size())]) : std::nullopt,
          r.size);
  return r;
}

DragSession::DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles,
                         const DragSessionParams& params)
    : DragSession(mesh, ops, std::move(handles), std::vector<SurfacePoint>(), params) {}

DragSession::DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles,
                         const std::vector<SurfacePoint>& points, const DragSessionParams& params)
    : DragSession(mesh, ops, handles, region_of(mesh, ops, handles, points, params), params) {}

DragSession::DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles,
                         const std::vector<int>& region, const DragSessionParams& params)
    : DragSession(mesh, ops, handles,
                  Region{region,
                         false,
                         {},
                         std::vector<HandleLoad>(handles.size()),
                         std::vector<bool>(handles.size(), false),
                         0.0},
                  params) {}

DragSession::DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles, const Region& region,
                         const DragSessionParams& params)
    : mesh_(mesh),
      ops_(ops),
      params_(params),
      handles_(std::move(handles)),
      loads_(region.loads),
      at_point_(region.at_point),
      handle_radius_(region.size),
      smooth_(region.smooth),
      foundation_(region.foundation) {
  const int nv = mesh.num_vertices();
  if (handles_.empty()) throw InputError("a drag session needs at least one handle");
  for (std::size_t k = 0; k < handles_.size(); ++k) {
    const int h = handles_[k];
    if (h < 0 || h >= nv)
      throw InputError(fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", h, nv));
    if (ops.mass[h] <= 0) throw InputError(fmt::format("handle vertex {} has no incident area", h));
    for (std::size_t j = 0; j < k && !at_point_[k]; ++j)
      if (!at_point_[j] && handles_[j] == h) throw InputError(fmt::format("handle vertex {} is listed twice", h));
  }
  // Held: the vertex handles without a load (outside the free rows, entering through
  // their coupling); a loaded handle's vertices are free rows.
  auto held = [&](int v) {
    for (std::size_t k = 0; k < handles_.size(); ++k)
      if (handles_[k] == v && loads_[k].load.empty()) return true;
    return false;
  };
  std::vector<int> free;
  for (int v : region.vertices) {
    if (v < 0 || v >= nv) throw InputError(fmt::format("region vertex {} does not exist (the mesh has {})", v, nv));
    if (!held(v) && ops.mass[v] > 0) free.push_back(v);
  }
  if (free.empty()) throw InputError("the drag region has no free vertex");
  handle_in_region_.assign(handles_.size(), false);
  build(std::move(free));
}

std::vector<int> DragSession::rings_around(const std::vector<int>& from, int rings) const {
  // Not the vertices themselves, nor a handle outside the region (held), nor a vertex
  // without area (held by every solver).
  std::unordered_set<int> taken(from.begin(), from.end());
  for (std::size_t k = 0; k < handles_.size(); ++k)
    if (!handle_in_region_[k]) taken.insert(handles_[k]);
  std::vector<int> out, front = from;
  for (int r = 0; r < rings; ++r) {
    std::vector<int> next;
    for (int v : front)
      for (int w : mesh_.neighbors(v))
        if (ops_.mass[w] > 0 && taken.insert(w).second) next.push_back(w);
    out.insert(out.end(), next.begin(), next.end());
    front = std::move(next);
  }
  return out;
}

std::vector<int> DragSession::outer_ring(const std::vector<int>& set) const {
  // Outside: not in the set, not a handle (held, often inside: the first handle is the
  // region's centre) and not a vertex without area (held by every solver).
  std::unordered_set<int> in(set.begin(), set.end());
  in.insert(handles_.begin(), handles_.end());
  std::vector<int> out;
  for (int v : set)
    for (int w : mesh_.neighbors(v))
      if (ops_.mass[w] > 0 && !in.count(w)) {
        out.push_back(v);
        break;
      }
  return out;
}

void DragSession::build(std::vector<int> free) {
  const PdeCoefficients coef{.g0 = 0, .g1 = params_.g1, .g2 = params_.g2};
  auto f = std::make_unique<Factor>();
  // The region's outermost ring (inner_margin) and one ring outside it (margin) are
  // factored last, in that order: the leading blocks are then the region without its
  // outer ring (shrink), the region, and the region with one more ring (grow).
  std::vector<int> inner, outer;
  if (params_.inner_margin) {
    inner = outer_ring(free);
    if (inner.size() == free.size()) inner.clear();  // no core would be left
  }
  if (params_.margin) outer = rings_around(free, 1);
  std::vector<int> core;
  if (inner.empty()) {
    core = std::move(free);
  } else {
    const std::unordered_set<int> ring(inner.begin(), inner.end());
    for (int v : free)
      if (!ring.count(v)) core.push_back(v);
  }
  // Fill-reducing order of the core by itself: nested dissection from positions and
  // adjacency, so the matrix is assembled once, already in its final order. Its top
  // level splits the core in two uncoupled halves and a separator: without margins the
  // halves are factored at the same time (SplitCholesky).
  NestedDissection nd =
      nested_dissection(mesh_, core, NestedDissectionParams{.separator_hops = params_.g2 != 0 ? 2 : 1});
  f->use_split = inner.empty() && outer.empty() && SplitCholesky::available() &&
                 static_cast<Eigen::Index>(core.size()) >= kSplitFactorFrom && nd.parts[1] > 0;
  f->vertices = std::move(nd.order);
  f->vertices.insert(f->vertices.end(), inner.begin(), inner.end());
  f->vertices.insert(f->vertices.end(), outer.begin(), outer.end());
  f->row = IndexMap(f->vertices.size());
  for (int v : f->vertices) f->row.insert(v);  // row k for vertices[k]
  const auto n_core = static_cast<Eigen::Index>(core.size());
  const auto n_region = n_core + static_cast<Eigen::Index>(inner.size());
  if (!inner.empty()) f->levels.push_back(n_core);
  f->levels.push_back(n_region);
  if (!outer.empty()) f->levels.push_back(n_region + static_cast<Eigen::Index>(outer.size()));
  f->level = inner.empty() ? 0 : 1;
  f->A = assemble_steady_matrix(mesh_, ops_, coef, f->vertices);
  f->A.makeCompressed();  // the products read its arrays directly
  // The smooth boundary's foundation on the diagonal (its vertices are all free rows).
  for (const auto& [v, k] : foundation_)
    if (const int row = f->row.find(v); row >= 0) f->A.coeffRef(row, row) += k;
  try {
    if (f->use_split)
      f->split.factorize(f->A, static_cast<Eigen::Index>(nd.parts[0]), static_cast<Eigen::Index>(nd.parts[1]));
    else
      f->chol.factorize(f->A);
  } catch (const SolverError&) {
    throw SolverError(
        fmt::format("the drag region's system ({} vertices) is not positive definite: does the region cover a "
                    "whole closed part of the mesh, or is a coefficient negative?",
                    f->vertices.size()));
  }
  factor_ = std::move(f);
  ++factorizations_;
  activate();
}

void DragSession::activate() {
  Factor& f = *factor_;
  f.set_active(f.levels[f.level]);
  region_.assign(f.vertices.begin(), f.vertices.begin() + static_cast<std::ptrdiff_t>(f.active));
  // Handles among the region's rows are constrained inside it; the others (outside the
  // factor, or in rows beyond the region) are held and enter through the right-hand side.
  for (std::size_t k = 0; k < handles_.size(); ++k) handle_in_region_[k] = region_index(handles_[k]) >= 0;
  compute_basis();
}

bool DragSession::split_factor() const {
  return factor_->use_split;
}

int DragSession::region_index(int v) const {
  const int k = factor_->row.find(v);
  return k >= factor_->active ? -1 : k;
}

Eigen::VectorXd DragSession::coupling(int v) const {
  Eigen::VectorXd b = Eigen::VectorXd::Zero(factor_->active);
  for (const auto& [i, value] :
       steady_coupling(mesh_, ops_, PdeCoefficients{.g0 = 0, .g1 = params_.g1, .g2 = params_.g2}, v))
    if (const int k = region_index(i); k >= 0) b[k] = value;
  return b;
}

Eigen::MatrixXd DragSession::solve(const Eigen::MatrixXd& b) {
  const Factor& f = *factor_;
  auto solve_columns = [&](const Eigen::MatrixXd& r) {
    Eigen::MatrixXd x = r;
    f.solve_leading(x);
    return x;
  };
  auto multiply_columns = [&](const Eigen::MatrixXd& x) { return f.multiply_leading(x); };
  // Refined against the factored matrix itself: at most five steps while the relative
  // residual exceeds 1e-12, keeps falling and is above the backward-stable level.
  // (SteadyDirectSolver refines against K D K's products by preconditioned CG instead,
  // which also removes the assembled matrix's rounding; solvers/refinement.h.)
  RefinedSolve r = refined_solve(b, solve_columns, multiply_columns, f.norm_inf, 1e-12, 5);
  residual_ = r.relative_residual;
  ++solves_;
  return std::move(r.x);
}

void DragSession::compute_basis() {
  // Held handles couple through the right-hand side; constrained ones (loaded, or
  // vertices among the free rows) through their loads. All columns come from one
  // multi-column solve (one pass over L).
  const auto [held, loaded] = held_and_constrained();
  const auto nh = static_cast<Eigen::Index>(held.size());
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(factor_->active, nh + static_cast<Eigen::Index>(loaded.size()));
  for (Eigen::Index j = 0; j < nh; ++j) rhs.col(j) = coupling(handles_[held[static_cast<std::size_t>(j)]]);
  for (std::size_t j = 0; j < loaded.size(); ++j) {
    const auto col = nh + static_cast<Eigen::Index>(j);
    const std::size_t k = loaded[j];
    if (loads_[k].load.empty()) {
      rhs(region_index(handles_[k]), col) = 1;  // a point load at the vertex: holds it
    } else {
      for (const auto& [v, w] : loads_[k].load)
        if (const int row = region_index(v); row >= 0) rhs(row, col) = w;
    }
  }
  const Eigen::MatrixXd x = solve(rhs);
  held_columns_ = x.leftCols(nh);
  green_ = x.rightCols(static_cast<Eigen::Index>(loaded.size()));
  finish_basis();
}

std::pair<std::vector<std::size_t>, std::vector<std::size_t>> DragSession::held_and_constrained() const {
  std::pair<std::vector<std::size_t>, std::vector<std::size_t>> out;
  for (std::size_t k = 0; k < handles_.size(); ++k) (constrained(k) ? out.second : out.first).push_back(k);
  return out;
}

std::vector<std::vector<std::pair<int, double>>> DragSession::readings() const {
  std::vector<std::vector<std::pair<int, double>>> out;
  for (std::size_t k = 0; k < handles_.size(); ++k)
    out.push_back(loads_[k].reading.empty() ? std::vector<std::pair<int, double>>{{handles_[k], 1.0}}
                                            : loads_[k].reading);
  return out;
}

void DragSession::finish_basis() {
  // d_F = H d_held + G lambda, with lambda from the constrained handles' readings:
  // C^T d = d_c, so S lambda = d_c - T d_held with S = C^T G and T the readings of the
  // held columns (a reading vertex that is a held handle reads that handle's value).
  const auto [held, loaded] = held_and_constrained();
  const auto nh = static_cast<Eigen::Index>(held.size()), nc = static_cast<Eigen::Index>(loaded.size());
  const auto all = readings();
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(nc, nc), T = Eigen::MatrixXd::Zero(nc, nh);
  for (Eigen::Index i = 0; i < nc; ++i)
    for (const auto& [v, w] : all[loaded[static_cast<std::size_t>(i)]]) {
      if (const int row = region_index(v); row >= 0) {
        S.row(i) += w * green_.row(row);
        T.row(i) += w * held_columns_.row(row);
      } else {
        for (Eigen::Index j = 0; j < nh; ++j)
          if (handles_[held[static_cast<std::size_t>(j)]] == v) T(i, j) += w;
      }
    }
  multipliers_.setZero(nc, static_cast<Eigen::Index>(handles_.size()));
  if (nc > 0) {
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(S);
    if (lu.rank() < nc || !(std::abs(lu.determinant()) > 0))
      throw InputError(
          "the handles are too close to be moved independently: give them further apart, or fewer handles");
    const Eigen::MatrixXd st = lu.solve(T);
    for (Eigen::Index j = 0; j < nh; ++j) multipliers_.col(static_cast<Eigen::Index>(held[j])) = -st.col(j);
    const Eigen::MatrixXd inv = lu.inverse();
    for (Eigen::Index i = 0; i < nc; ++i) multipliers_.col(static_cast<Eigen::Index>(loaded[i])) = inv.col(i);
  }
  basis_ = green_ * multipliers_;
  for (Eigen::Index j = 0; j < nh; ++j) basis_.col(static_cast<Eigen::Index>(held[j])) += held_columns_.col(j);
}

void DragSession::add_handle(int vertex) {
  if (region_index(vertex) < 0 || std::find(handles_.begin(), handles_.end(), vertex) != handles_.end())
    throw InputError(fmt::format("vertex {} is not a free vertex of the drag region", vertex));
  Eigen::MatrixXd e = Eigen::MatrixXd::Zero(factor_->active, 1);
  e(region_index(vertex), 0) = 1;
  const Eigen::MatrixXd g = solve(e);
  handles_.push_back(vertex);
  handle_in_region_.push_back(true);
  loads_.emplace_back();
  at_point_.push_back(false);
  // The constrained handles' columns stay in handle order: the new one is the last.
  green_.conservativeResize(Eigen::NoChange, green_.cols() + 1);
  green_.col(green_.cols() - 1) = g.col(0);
  try {
    finish_basis();
  } catch (const InputError&) {
    handles_.pop_back();
    handle_in_region_.pop_back();
    loads_.pop_back();
    at_point_.pop_back();
    green_.conservativeResize(Eigen::NoChange, green_.cols() - 1);
    finish_basis();
    throw InputError(fmt::format("vertex {} cannot become a handle: it cannot be moved apart from the others", vertex));
  }
}

void DragSession::grow(int rings) {
  if (rings < 1) throw InputError("grow by at least one ring");
  if (boundary() == RegionBoundary::Smooth)
    throw InputError(
        "the smooth boundary's region is fixed by its radius: make a session with a larger radius, or ask for the "
        "clamp boundary to grow it by rings");
  if (rings == 1 && factor_->level + 1 < factor_->levels.size()) {
    // The next ring was factored with the region, ordered after it: the grown region's
    // factor is a leading block of rows the factor already has.
    ++factor_->level;
    activate();
    return;
  }
  std::vector<int> free = region_;
  const std::vector<int> added = rings_around(region_, rings);
  free.insert(free.end(), added.begin(), added.end());
  build(std::move(free));
}

void DragSession::shrink(int rings) {
  if (rings < 1) throw InputError("shrink by at least one ring");
  if (boundary() == RegionBoundary::Smooth)
    throw InputError(
        "the smooth boundary's region is fixed by its radius: make a session with a smaller radius, or ask for the "
        "clamp boundary to shrink it by rings");
  if (rings == 1 && factor_->level > 0) {
    // The region's outermost ring was factored last: the smaller region's factor is
    // the leading block without it.
    --factor_->level;
    activate();
    return;
  }
  std::vector<int> free = region_;
  for (int r = 0; r < rings && !free.empty(); ++r) {
    const std::vector<int> ring = outer_ring(free);
    const std::unordered_set<int> drop(ring.begin(), ring.end());
    std::erase_if(free, [&](int v) { return drop.count(v) > 0; });
  }
  if (free.empty()) throw InputError(fmt::format("shrinking the drag region by {} rings leaves no free vertex", rings));
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
  const auto& free = region_;
  for (std::size_t k = 0; k < free.size(); ++k) V.row(free[k]) += x.row(static_cast<Eigen::Index>(k));
  // A vertex handle moves by exactly its displacement (a free row's value is that to rounding).
  for (std::size_t k = 0; k < handles_.size(); ++k)
    if (!at_point_[k]) V.row(handles_[k]) = mesh_.positions().row(handles_[k]) + d.row(static_cast<Eigen::Index>(k));
  return V;
}

Eigen::MatrixXd DragSession::forces(const Eigen::MatrixXd& d) const {
  const Eigen::MatrixXd x = displacements(d);  // checks d's shape
  const Eigen::MatrixXd lambda = multipliers_ * d;
  // The field near a held handle (its row reaches two rings): a region row, a vertex
  // handle's own displacement, else zero.
  auto field = [&](int j, int c) {
    if (const int k = region_index(j); k >= 0) return x(k, c);
    for (std::size_t h = 0; h < handles_.size(); ++h)
      if (handles_[h] == j && !at_point_[h]) return d(static_cast<Eigen::Index>(h), c);
    return 0.0;
  };
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(handles_.size()), 3);
  Eigen::Index next = 0;
  for (std::size_t k = 0; k < handles_.size(); ++k) {
    if (constrained(k)) {
      out.row(static_cast<Eigen::Index>(k)) = lambda.row(next++);  // the load sums to 1
      continue;
    }
    // A held vertex: the row of Kt at it applied to the field (it has no foundation).
    for (int c = 0; c < 3; ++c) {
      auto u = [&](int j) { return field(j, c); };
      out(static_cast<Eigen::Index>(k), c) = params_.g1 * stiffness_row(mesh_, ops_, handles_[k], u) +
                                             params_.g2 * bilaplacian_row(mesh_, ops_, handles_[k], u);
    }
  }
  return out;
}

}  // namespace meshpde
