// InterpolationSolver: interpolation with a kept factor, updated for changed
// constraints by a bordered system and its Schur complement (apps/interpolation.h).
//
// Notation: C0 the constrained vertices when the factor was made, F0 the free ones then
// (A_00 = A restricted to F0, inverted by its own factor, or by the Laplacian's
// through the mixed form: FactoredBlock below), C the constraints
// now. P = C0 \ C (released: now unknowns outside F0), Q = C \ C0 (added: inside F0,
// held by Lagrange multipliers). The unknowns y on F0 and P, with y_Q = u_Q, solve
//
//     [ A_00  G ] [ y0 ]   [ b0 ]      G = [ A_0P  E_Q ],  H = [ A_PP  0 ]
//     [ G^T   H ] [ w  ] = [ c  ]                              [ 0     0 ]
//
// with c = (b_P, u_Q) and w = (y_P, multipliers): the rows of Q are met by their
// multipliers, the rest are the current system's. Eliminating y0 gives
// S w = c - G^T A_00^-1 b0 with S = H - G^T A_00^-1 G, then y0 = A_00^-1 (b0 - G w).
//
// What makes a click cheap is what is kept between solves, each column solved once
// (with refinement) when it first appears: T = A_00^-1 G, a column per border vertex;
// z0 = A_00^-1 b0 for the values C0 held at the last solve; and the response
// z_c = A_00^-1 (-A_0c) of each vertex c of C0 whose value has changed since the
// factorization (at most kHeldColumns of them), so that a new value there moves z0 by
// z_c times the change. A solve is then dense arithmetic on kept columns (w from S,
// y0 = z0 - T w) and one residual through the products; only a vertex new to the
// border, or a C0 vertex's first change, costs a solve with the factor.
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>

#include "../pde/free_parts.h"
#include "../pde/mixed_bilaplacian.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

// Residuals above this relative size are refined by another bordered solve, while a
// step at least halves it: on large meshes the residual's rounding floor lies above the
// tolerance (1.5e-13 to 5e-13 at 537k vertices), and steps that only graze it cost a
// solve each for nothing. A higher tolerance would let answers on ill-conditioned
// meshes drift past 1e-10 of a fresh solve (docs/solvers-measurements.md, "Painting").
constexpr double kRefineTolerance = 1e-13;
constexpr double kRefineGain = 0.5;
constexpr int kMaxRefinements = 4;
// Below this smallest eigenvalue of the scaled Schur complement (update_border) it is not
// trusted and the system is factored afresh.
constexpr double kMinSchurEigenvalue = 1e-12;
// Responses z_c kept for at most this many vertices of C0 (n0 doubles each); beyond,
// or for more than kMaxColumnSolves new ones at once, z0 is solved afresh instead.
constexpr int kHeldColumns = 64;
constexpr int kMaxColumnSolves = 4;
// With at most this many values held when the factor is made, their responses are
// solved with the first solve (igea-134k: 8 responses added a tenth to a fifth to it).
constexpr int kResponsesAhead = 16;
// A refactorization reuses the last factor's order while the free set changed by at
// most this fraction of its vertices.
constexpr double kReuseOrderChanges = 0.05;

// A_00^-1 and A_00's couplings: A_00's own factor, or the Laplacian's with the
// mixed form's kept columns.
struct FactoredBlock {
  std::unique_ptr<SteadyDirectSolver> direct;
  std::unique_ptr<detail::MixedBilaplacianSolver> mixed;

  int num_free() const { return direct ? direct->num_free() : mixed->num_free(); }
  const std::vector<int>& free_vertices() const { return direct ? direct->free_vertices() : mixed->free_vertices(); }
  int free_index(int v) const { return direct ? direct->free_index(v) : mixed->free_index(v); }
  Eigen::VectorXd coupling(int v) const { return direct ? direct->coupling(v) : mixed->coupling(v); }
  // Refined (the kept columns), and one plain solve (the refinement of an answer).
  Eigen::MatrixXd solve_rhs(const Eigen::MatrixXd& B) const {
    return direct ? direct->solve_rhs(B) : mixed->solve_rhs(B);
  }
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const { return direct ? direct->factor().solve(B) : mixed->solve(B); }
  // The column of a vertex added since the factorization (its load a unit row of its
  // own): refined for K D K's factor, plain through the Laplacian's, whose residual
  // lies in that vertex's row, which the vertex's multiplier takes (igea-134k: answers
  // from plain columns at a relative residual of about 2e-13 with no refinement step).
  Eigen::MatrixXd added_column(const Eigen::MatrixXd& B) const {
    return direct ? direct->solve_rhs(B) : mixed->solve(B);
  }
  NestedDissection vertex_order() const { return direct ? direct->vertex_order() : mixed->vertex_order(); }
};

// One column of G: its nonzeros on F0's rows (local indices), and for a released vertex
// its couplings to the other released vertices (the column of A_PP).
struct BorderColumn {
  int vertex = 0;
  bool released = false;  // in P (an unknown), else in Q (a multiplier)
  std::vector<std::pair<int, double>> g;
  double h_diagonal = 0;                         // A_pp of a released vertex
  std::vector<std::pair<int, double>> coupling;  // a released vertex's -A_{i,p} (steady_coupling)
  Eigen::VectorXd t;                             // A_00^-1 g, on F0's rows
};

}  // namespace

struct InterpolationSolver::Impl {
  std::unique_ptr<MeshOperators> owned;  // the operators built by the owning constructor
  const Mesh* mesh = nullptr;
  const FemOperators* ops = nullptr;
  FieldKind kind = FieldKind::Scalar;
  InterpolationParams params;
  int m = 1;
  LaplacianKind laplacian = LaplacianKind::Cotan;
  std::string laplacian_reason;
  std::map<int, Eigen::VectorXd> cons;

  std::unique_ptr<FactoredBlock> base;
  std::vector<char> base_held;  // #V: in C0
  std::vector<BorderColumn> border;
  std::vector<int> border_vertices;  // P and Q (sorted), the border S was built for
  Eigen::MatrixXd S;
  Eigen::PartialPivLU<Eigen::MatrixXd> S_lu;
  int factorizations = 0;
  int reused_orders = 0;  // factorizations in the last factor's order (reuse_ordering)
  // z0 = A_00^-1 b0 for the values z0_values held at C0's vertices (absent: released),
  // and the responses z_c of the C0 vertices that have changed.
  Eigen::MatrixXd z0;
  std::map<int, Eigen::VectorXd> z0_values;
  bool z0_valid = false;
  std::map<int, Eigen::VectorXd> responses;

  static void check(FieldKind kind, const InterpolationParams& params) {
    if (!(params.g1 >= 0 && params.g2 >= 0) || params.g1 + params.g2 <= 0)
      throw InputError("interpolation needs g1, g2 >= 0, not both 0");
    if (kind == FieldKind::Tangent && params.method == TangentMethod::Connection)
      throw InputError(
          "InterpolationSolver interpolates tangent fields componentwise; the connection method has no kept factor "
          "(use interpolate())");
    if (params.solver != SteadySolver::Auto && params.solver != SteadySolver::Direct)
      throw InputError(
          fmt::format("InterpolationSolver keeps a direct factor; solver {} is not one", to_string(params.solver)));
  }

  void init(const Mesh& the_mesh, const FemOperators& the_ops, FieldKind the_kind, const InterpolationParams& p) {
    if (the_ops.mass.size() != the_mesh.num_vertices())
      throw InputError(
          fmt::format("operators of {} vertices for a mesh of {}", the_ops.mass.size(), the_mesh.num_vertices()));
    mesh = &the_mesh;
    ops = &the_ops;
    kind = the_kind;
    params = p;
    m = the_kind == FieldKind::Scalar ? 1 : 3;
  }

  PdeCoefficients coefficients() const { return PdeCoefficients{.g0 = 0, .g1 = params.g1, .g2 = params.g2}; }

  // A U over the whole mesh (U is #V x m).
  Field apply(const Field& U) const {
    Field Y = Field::Zero(U.rows(), U.cols());
    if (params.g1 != 0) Y += params.g1 * apply_stiffness(*mesh, *ops, U);
    if (params.g2 != 0) Y += params.g2 * apply_bilaplacian(*mesh, *ops, U);
    return Y;
  }

  // up_to: InterpolationSolver::laplacian_factor_up_to.
  void factor(int up_to) {
    const int nv = mesh->num_vertices();
    base_held.assign(static_cast<std::size_t>(nv), 0);
    for (const auto& [v, x] : cons) base_held[static_cast<std::size_t>(v)] = 1;
    std::vector<int> free;
    for (int v = 0; v < nv; ++v)
      if (!base_held[static_cast<std::size_t>(v)] && ops->mass[v] > 0) free.push_back(v);
    // A refactorization after a few changed constraints keeps the last factor's order
    // for the vertices still free (reuse_ordering): no new ordering, and at most a row
    // more per new free vertex.
    NestedDissection reused;
    int changes = 0;
    if (base) {
      const NestedDissection last = base->vertex_order();
      if (!last.order.empty()) reused = reuse_ordering(last, free, nv, &changes);
    }
    const bool reuse =
        !reused.order.empty() && static_cast<double>(changes) <= kReuseOrderChanges * static_cast<double>(free.size());
    base.reset();  // a failed factorization leaves no stale factor behind
    border.clear();
    border_vertices.clear();
    z0_valid = false;
    responses.clear();
    auto block = std::make_unique<FactoredBlock>();
    const NestedDissection* order = reuse ? &reused : nullptr;
    if (params.g1 == 0 && static_cast<int>(cons.size()) <= up_to) {
      try {
        block->mixed = std::make_unique<detail::MixedBilaplacianSolver>(*mesh, *ops, params.g2, free, order);
      } catch (const SolverError&) {
        // K_FF did not factor: K D K's own factor instead (below), which says what is
        // wrong if anything is (a part without a constraint fails both).
      }
    }
    if (!block->mixed) {
      // CHOLMOD's ordering, one factor: every click sweeps it. The mesh ordering's
      // factor (solvers/ordering.h) is analyzed faster but has more fill: on igea-134k
      // in `meshpde bench --only paint` the first solve took 2.7 s against 4.2 s, and a
      // click 87 ms against 74 ms (docs/solvers-measurements.md).
      block->direct = std::make_unique<SteadyDirectSolver>(*mesh, *ops, coefficients(), std::move(free),
                                                           SparseCholesky::Backend::Auto, Eigen::VectorXd(),
                                                           DirectOrdering::Cholmod, order);
    }
    base = std::move(block);
    ++factorizations;
    reused_orders += reuse;
  }

  // z0 = A_00^-1 b0 for the values held now at C0's vertices (`outside`: #V x m, those
  // values and zero elsewhere): from the kept z0 and responses where few values changed,
  // else solved afresh.
  const Eigen::MatrixXd& held_response(const Field& outside) {
    std::vector<int> moved;  // C0 vertices whose value differs from z0's
    if (z0_valid) {
      for (const auto& [v, x] : cons)
        if (base_held[static_cast<std::size_t>(v)]) {
          const auto it = z0_values.find(v);
          if (it == z0_values.end() || it->second != x) moved.push_back(v);
        }
      for (const auto& [v, x] : z0_values)
        if (!cons.count(v)) moved.push_back(v);
    }
    std::vector<int> missing;
    for (const int v : moved)
      if (!responses.count(v)) missing.push_back(v);
    const bool incremental = z0_valid && static_cast<int>(missing.size()) <= kMaxColumnSolves &&
                             static_cast<int>(responses.size() + missing.size()) <= kHeldColumns;
    if (incremental) {
      if (!missing.empty()) {
        Eigen::MatrixXd B(base->num_free(), static_cast<Eigen::Index>(missing.size()));
        for (std::size_t j = 0; j < missing.size(); ++j)
          B.col(static_cast<Eigen::Index>(j)) = base->coupling(missing[j]);
        const Eigen::MatrixXd Zm = base->solve_rhs(B);  // the new columns in one pass of sweeps
        for (std::size_t j = 0; j < missing.size(); ++j) responses[missing[j]] = Zm.col(static_cast<Eigen::Index>(j));
      }
      for (const int v : moved) {
        const auto now = cons.find(v);
        const auto then = z0_values.find(v);
        Eigen::RowVectorXd change = Eigen::RowVectorXd::Zero(m);
        if (now != cons.end()) change += now->second.transpose();
        if (then != z0_values.end()) change -= then->second.transpose();
        z0 += responses[v] * change;
        if (now != cons.end())
          z0_values[v] = now->second;
        else
          z0_values.erase(v);
      }
      return z0;
    }
    Eigen::MatrixXd b0, c;
    load_rhs(apply(outside), b0, c);
    z0 = base->solve_rhs(b0);
    z0_values.clear();
    for (const auto& [v, x] : cons)
      if (base_held[static_cast<std::size_t>(v)]) z0_values[v] = x;
    z0_valid = true;
    // The responses of a few held vertices ahead of their first change, in one pass of
    // sweeps with the first solve: a new value at a vertex painted before then costs no
    // sweep.
    if (responses.empty() && !z0_values.empty() && static_cast<int>(z0_values.size()) <= kResponsesAhead) {
      Eigen::MatrixXd B(base->num_free(), static_cast<Eigen::Index>(z0_values.size()));
      Eigen::Index j = 0;
      for (const auto& [v, x] : z0_values) B.col(j++) = base->coupling(v);
      const Eigen::MatrixXd Z = base->solve_rhs(B);
      j = 0;
      for (const auto& [v, x] : z0_values) responses[v] = Z.col(j++);
    }
    return z0;
  }

  std::vector<int> changed() const {
    std::vector<int> p, q;
    for (int v = 0; v < static_cast<int>(base_held.size()); ++v)
      if (base_held[static_cast<std::size_t>(v)] && !cons.count(v)) p.push_back(v);
    for (const auto& [v, x] : cons)
      if (!base_held[static_cast<std::size_t>(v)]) q.push_back(v);
    p.insert(p.end(), q.begin(), q.end());
    std::sort(p.begin(), p.end());
    return p;
  }

  // Brings the border to `vertices` (sorted): the columns of vertices no longer in it are
  // dropped from S, each new one costs one solve (its column t of A_00^-1 G gives its
  // row and column of S; a released vertex of C0 may have it as its response). Returns false
  // when S is close to singular.
  bool update_border(const std::vector<int>& vertices) {
    std::vector<BorderColumn> kept;
    std::vector<int> from;  // kept column -> its index in the old S
    for (std::size_t j = 0; j < border.size(); ++j)
      if (std::binary_search(vertices.begin(), vertices.end(), border[j].vertex)) {
        kept.push_back(std::move(border[j]));
        from.push_back(static_cast<int>(j));
      }
    const int k0 = static_cast<int>(kept.size()), k = static_cast<int>(vertices.size());
    Eigen::MatrixXd S2 = Eigen::MatrixXd::Zero(k, k);
    for (int i = 0; i < k0; ++i)
      for (int j = 0; j < k0; ++j) S2(i, j) = S(from[static_cast<std::size_t>(i)], from[static_cast<std::size_t>(j)]);
    border = std::move(kept);
    border_vertices = vertices;
    for (const int v : vertices) {
      if (std::any_of(border.begin(), border.begin() + k0, [v](const BorderColumn& c) { return c.vertex == v; }))
        continue;
      BorderColumn col;
      col.vertex = v;
      col.released = base_held[static_cast<std::size_t>(v)] != 0;
      const int j = static_cast<int>(border.size());
      if (col.released) {
        // A_{i,p} = -coupling: steady_coupling gives the right-hand side of a unit value.
        col.coupling = steady_coupling(*mesh, *ops, coefficients(), v);
        for (const auto& [i, value] : col.coupling) {
          if (const int li = base->free_index(i); li >= 0) col.g.emplace_back(li, -value);
          if (i == v) col.h_diagonal = -value;
          for (int r = 0; r < j; ++r)  // H = A_PP between released vertices
            if (border[static_cast<std::size_t>(r)].released && border[static_cast<std::size_t>(r)].vertex == i)
              S2(r, j) = S2(j, r) = -value;
        }
        S2(j, j) = col.h_diagonal;
      } else {
        col.g.emplace_back(base->free_index(v), 1.0);
      }
      if (const auto it = responses.find(v); col.released && it != responses.end()) {
        col.t = -it->second;  // g = A_0p = -coupling(p)
      } else {
        Eigen::VectorXd gj = Eigen::VectorXd::Zero(base->num_free());
        for (const auto& [li, value] : col.g) gj[li] = value;
        col.t = col.released ? base->solve_rhs(gj).col(0) : base->added_column(gj).col(0);
        if (col.released && static_cast<int>(responses.size()) < kHeldColumns) responses[v] = -col.t;
      }
      border.push_back(std::move(col));
      const Eigen::VectorXd& t = border.back().t;
      for (int r = 0; r <= j; ++r) {
        double gt = 0;
        for (const auto& [li, value] : border[static_cast<std::size_t>(r)].g) gt += value * t[li];
        S2(r, j) -= gt;
        if (r != j) S2(j, r) = S2(r, j);
      }
    }
    S = std::move(S2);
    if (k == 0) return true;
    S_lu.compute(S);
    // Conditioning judged on S scaled by what its diagonal would be without the
    // elimination: A_pp for a released vertex (S_pp cancels towards rounding as p's
    // part of the mesh loses its last constraint), |S_qq| for an added one; the scaled
    // entries are of order 1, so a tiny eigenvalue means a nearly singular border.
    // rcond of S itself cannot see that (a 1 x 1 S has rcond 1).
    Eigen::VectorXd scale(k);
    for (int j = 0; j < k; ++j) {
      const BorderColumn& c = border[static_cast<std::size_t>(j)];
      const double d = c.released ? c.h_diagonal : std::abs(S(j, j));
      if (!(d > 0)) return false;
      scale[j] = 1 / std::sqrt(d);
    }
    const Eigen::MatrixXd scaled = scale.asDiagonal() * S * scale.asDiagonal();
    const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(scaled).eigenvalues();
    return eigenvalues.cwiseAbs().minCoeff() >= kMinSchurEigenvalue;
  }

  // The bordered solve from z0 = A_00^-1 b0: y0 on F0 (rows in the order of the
  // factor's free list) and w; no solve with the factor (T is kept).
  std::pair<Eigen::MatrixXd, Eigen::MatrixXd> bordered_solve(Eigen::MatrixXd y, const Eigen::MatrixXd& c) const {
    const Eigen::Index k = static_cast<Eigen::Index>(border.size());
    if (k == 0) return {std::move(y), Eigen::MatrixXd(0, y.cols())};
    Eigen::MatrixXd rhs = c;
    for (Eigen::Index i = 0; i < k; ++i)
      for (const auto& [li, value] : border[static_cast<std::size_t>(i)].g) rhs.row(i) -= value * y.row(li);
    const Eigen::MatrixXd w = S_lu.solve(rhs);
    for (Eigen::Index j = 0; j < k; ++j) y -= border[static_cast<std::size_t>(j)].t * w.row(j);
    return {std::move(y), w};
  }

  // -(A U) on the rows of F0 (b0) and of the border's released vertices, zero at its
  // added ones (c): the right-hand side of the bordered system for the load -(A U)
  // with the added vertices held at zero, as a residual's correction needs.
  void load_rhs(const Field& AU, Eigen::MatrixXd& b0, Eigen::MatrixXd& c) const {
    const std::vector<int>& free = base->free_vertices();
    b0.resize(static_cast<Eigen::Index>(free.size()), m);
    for (std::size_t i = 0; i < free.size(); ++i) b0.row(static_cast<Eigen::Index>(i)) = -AU.row(free[i]);
    c = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(border.size()), m);
    for (std::size_t j = 0; j < border.size(); ++j)
      if (border[j].released) c.row(static_cast<Eigen::Index>(j)) = -AU.row(border[j].vertex);
  }
};

InterpolationSolver::InterpolationSolver(const Mesh& mesh, FieldKind kind, const InterpolationParams& params)
    : impl_(std::make_unique<Impl>()) {
  if (kind == FieldKind::Tangent && params.laplacian == LaplacianKind::IntrinsicDelaunay)
    throw InputError("tangent fields need the cotangent operators of the input triangles (laplacian cotan or auto)");
  impl_->check(kind, params);
  // Owned behind a pointer: the solver refers to this mesh and these operators.
  impl_->owned = std::make_unique<MeshOperators>(
      build_mesh_operators(mesh, kind == FieldKind::Tangent ? LaplacianKind::Cotan : params.laplacian));
  impl_->init(impl_->owned->mesh, impl_->owned->ops, kind, params);
  impl_->laplacian = impl_->owned->kind;
  impl_->laplacian_reason = kind == FieldKind::Tangent && params.laplacian == LaplacianKind::Auto
                                ? "tangent fields use the input triangles"
                                : impl_->owned->reason;
}

InterpolationSolver::InterpolationSolver(const Mesh& mesh, const FemOperators& ops, FieldKind kind,
                                         const InterpolationParams& params)
    : impl_(std::make_unique<Impl>()) {
  impl_->check(kind, params);
  impl_->init(mesh, ops, kind, params);
}

InterpolationSolver::~InterpolationSolver() = default;
InterpolationSolver::InterpolationSolver(InterpolationSolver&&) noexcept = default;
InterpolationSolver& InterpolationSolver::operator=(InterpolationSolver&&) noexcept = default;

void InterpolationSolver::set_value(int vertex, const Eigen::VectorXd& value) {
  Impl& s = *impl_;
  const int nv = s.mesh->num_vertices();
  if (vertex < 0 || vertex >= nv)
    throw InputError(fmt::format("constraint vertex {} does not exist (the mesh has {})", vertex, nv));
  if (value.size() != s.m)
    throw InputError(fmt::format("constraint at vertex {} has {} values, expected {}", vertex, value.size(), s.m));
  if (!value.allFinite()) throw InputError(fmt::format("constraint at vertex {} is not finite", vertex));
  if (s.ops->mass[vertex] <= 0) throw InputError(fmt::format("constraint vertex {} has no incident area", vertex));
  s.cons[vertex] = value;
}

void InterpolationSolver::remove(int vertex) {
  if (impl_->cons.erase(vertex) == 0) throw InputError(fmt::format("vertex {} is not constrained", vertex));
}

void InterpolationSolver::clear() {
  impl_->cons.clear();
}
bool InterpolationSolver::constrained(int vertex) const {
  return impl_->cons.count(vertex) != 0;
}
int InterpolationSolver::num_constraints() const {
  return static_cast<int>(impl_->cons.size());
}
int InterpolationSolver::factorizations() const {
  return impl_->factorizations;
}

bool InterpolationSolver::laplacian_factor() const {
  return impl_->base && impl_->base->mixed;
}

int InterpolationSolver::reused_orders() const {
  return impl_->reused_orders;
}

int InterpolationSolver::changed_constraints() const {
  return static_cast<int>(impl_->border_vertices.size());
}

std::vector<InterpolationConstraint> InterpolationSolver::constraints() const {
  std::vector<InterpolationConstraint> out;
  for (const auto& [v, x] : impl_->cons) out.push_back({v, x});
  return out;
}

InterpolationResult InterpolationSolver::solve() {
  Impl& s = *impl_;
  if (s.cons.empty()) throw InputError("interpolation needs at least one constrained vertex");
  const int nv = s.mesh->num_vertices();
  if (!s.base) s.factor(laplacian_factor_up_to);
  std::vector<int> border = s.changed();
  if (static_cast<int>(border.size()) > max_changes) {
    s.factor(laplacian_factor_up_to);
    border.clear();
  }
  // Held now, as a flag a vertex (the loops below visit every vertex: a map lookup
  // each cost several milliseconds a click on igea-134k), and the vertices free now:
  // the rows of the current system.
  std::vector<char> held_now(static_cast<std::size_t>(nv), 0);
  for (const auto& [v, x] : s.cons) held_now[static_cast<std::size_t>(v)] = 1;
  std::vector<int> now_free;
  for (int v = 0; v < nv; ++v)
    if (!held_now[static_cast<std::size_t>(v)] && s.ops->mass[v] > 0) now_free.push_back(v);
  if (border != s.border_vertices) {
    // A released constraint may leave its part of the mesh without any: undetermined,
    // which the bordered system would only show as rounding. Checked on the mesh.
    if (std::any_of(border.begin(), border.end(),
                    [&](int v) { return s.base_held[static_cast<std::size_t>(v)] != 0; })) {
      std::vector<int> local(static_cast<std::size_t>(nv), -1);
      for (std::size_t k = 0; k < now_free.size(); ++k)
        local[static_cast<std::size_t>(now_free[k])] = static_cast<int>(k);
      detail::require_held_parts(
          *s.mesh, now_free, [&](int v) { return local[static_cast<std::size_t>(v)]; }, [](int) { return false; });
    }
    if (!s.update_border(border))
      s.factor(laplacian_factor_up_to);  // S near singular: start from the current constraints
  }

  // u: the held values where they are held now; the unknowns are solved below.
  Field given = Field::Zero(nv, s.m);
  for (const auto& [v, x] : s.cons) given.row(v) = x.transpose();
  // The load of the held values outside the bordered system (C0 still held; Q's values
  // enter as the border's right-hand side).
  Field outside = given;
  for (const BorderColumn& col : s.border)
    if (!col.released) outside.row(col.vertex).setZero();
  // c: b_P = -(A outside) on P's rows (from their couplings: A is symmetric) and the
  // values at Q.
  Eigen::MatrixXd c(static_cast<Eigen::Index>(s.border.size()), s.m);
  for (std::size_t j = 0; j < s.border.size(); ++j) {
    const BorderColumn& col = s.border[j];
    if (col.released) {
      c.row(static_cast<Eigen::Index>(j)).setZero();
      for (const auto& [i, value] : col.coupling) c.row(static_cast<Eigen::Index>(j)) += value * outside.row(i);
    } else {
      c.row(static_cast<Eigen::Index>(j)) = given.row(col.vertex);
    }
  }
  auto [y0, w] = s.bordered_solve(s.held_response(outside), c);

  Field u = given;
  const std::vector<int>& free = s.base->free_vertices();
  // Adds a bordered solve's answer (or correction) to u's unknowns.
  auto place = [&](const Eigen::MatrixXd& x0, const Eigen::MatrixXd& xw) {
    for (std::size_t i = 0; i < free.size(); ++i)
      if (!held_now[static_cast<std::size_t>(free[i])]) u.row(free[i]) += x0.row(static_cast<Eigen::Index>(i));
    for (std::size_t j = 0; j < s.border.size(); ++j)
      if (s.border[j].released) u.row(s.border[j].vertex) += xw.row(static_cast<Eigen::Index>(j));
  };
  place(y0, w);

  // Residual of the current system on its free rows, through the products; refined by
  // the same bordered solve (the added vertices' rows are their multipliers') from one
  // plain solve: the kept columns are as accurate as the factor makes them, so the
  // correction is small and the solve's own rounding in it negligible.
  // The load A u_C, nonzero within two rings of the constraints: from their couplings
  // rather than a whole-mesh product (a few milliseconds a click at 134k vertices).
  Field load = Field::Zero(nv, s.m);
  for (const auto& [held, x] : s.cons)
    for (const auto& [i, value] : steady_coupling(*s.mesh, *s.ops, s.coefficients(), held))
      load.row(i) -= value * x.transpose();
  auto relative = [&](const Field& X, int k) {
    double xk = 0, bk = 0;
    for (int v : now_free) {
      xk += X(v, k) * X(v, k);
      bk += load(v, k) * load(v, k);
    }
    return bk > 0 ? std::sqrt(xk / bk) : std::sqrt(xk);
  };
  Field AU = s.apply(u);
  // The worst column's relative residual.
  auto worst = [&](const Field& X) {
    double r = 0;
    for (int k = 0; k < s.m; ++k) r = std::max(r, relative(X, k));
    return r;
  };
  double residual = worst(AU);
  int steps = 0;
  while (residual > kRefineTolerance && steps < kMaxRefinements) {
    Field AUfree = AU;
    for (const auto& [v, x] : s.cons) AUfree.row(v).setZero();
    Eigen::MatrixXd r0, rc;
    s.load_rhs(AUfree, r0, rc);  // -(A u) on the free rows: the residual
    auto [d0, dw] = s.bordered_solve(s.base->solve(r0), rc);
    place(d0, dw);
    // The kept z0 takes the correction too (y0 = z0 - T w: z0 + d0 + T dw gives the
    // refined y0 for the refined w), so that the clicks after this one start from it
    // instead of each paying this step again for the same drift.
    for (std::size_t j = 0; j < s.border.size(); ++j) d0 += s.border[j].t * dw.row(static_cast<Eigen::Index>(j));
    s.z0 += d0;
    AU = s.apply(u);
    const double next = worst(AU);
    ++steps;
    const bool gained = next < kRefineGain * residual;
    residual = std::min(residual, next);
    if (!gained) break;
  }

  InterpolationResult r;
  r.values = std::move(u);
  if (s.kind == FieldKind::Tangent) {
    const Eigen::MatrixX3d N = vertex_normals(*s.mesh);
    for (int i = 0; i < nv; ++i) {
      const Eigen::RowVector3d n = N.row(i);
      r.values.row(i) -= r.values.row(i).dot(n) * n;
    }
  }
  r.cg = CgResult{.status = CgStatus::Converged, .iterations = steps, .relative_residual = residual, .message = {}};
  r.solver = SteadySolver::Direct;
  r.laplacian = s.laplacian;
  r.laplacian_reason = s.laplacian_reason;
  return r;
}

}  // namespace meshpde
