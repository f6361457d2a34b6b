#include "meshpde/pde/steady_direct.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "../core/index_map.h"
#include "free_parts.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/refinement.h"

namespace meshpde {

namespace {
// Below this many columns a region's matrix is assembled on the calling thread (a 2k
// region's K D K takes under 2 ms).
constexpr int kParallelColumns = 4000;
}  // namespace

namespace {

// The rows of K that Kt_FF is made of: S = F and its one ring, numbered locally (F
// first, in the order given), and row s of K restricted to the free columns.
struct FreeStiffnessRows {
  std::vector<int> S;
  std::vector<int> row_start;                       // row r's entries: [row_start[r], row_start[r + 1])
  std::vector<std::pair<int, double>> row_entries;  // (local free index, K value), diagonal first
  std::vector<int> slot_start, slot_local;          // per free row: each adjacency slot's local number (-1: outside S)
  // Row s of K restricted to the held columns (K_SC, C the held vertices): (vertex, K
  // value), row s's entries in [held_start[s], held_start[s + 1]). What the held values
  // put on the right-hand side (SteadyDirectSolver::solve_free).
  std::vector<int> held_start;
  std::vector<std::pair<int, double>> held_entries;

  // K_SF (|S| x n) as a sparse matrix, columns sorted within each row.
  Eigen::SparseMatrix<double, Eigen::RowMajor> matrix(int n) const {
    Eigen::SparseMatrix<double, Eigen::RowMajor> K(static_cast<Eigen::Index>(S.size()), n);
    K.resizeNonZeros(static_cast<Eigen::Index>(row_entries.size()));
    std::copy(row_start.begin(), row_start.end(), K.outerIndexPtr());
    std::vector<std::pair<int, double>> sorted = row_entries;
    for (std::size_t r = 0; r < S.size(); ++r)
      std::sort(sorted.begin() + row_start[r], sorted.begin() + row_start[r + 1]);
    for (std::size_t e = 0; e < sorted.size(); ++e) {
      K.innerIndexPtr()[e] = sorted[e].first;
      K.valuePtr()[e] = sorted[e].second;
    }
    return K;
  }
};

// With `held`, also K_SC (held_start, held_entries): only SteadyDirectSolver's solves
// read it, so a bare assembly (a drag region's) does not collect it.
FreeStiffnessRows free_stiffness_rows(const Mesh& mesh, const FemOperators& ops, const std::vector<int>& vertices,
                                      bool held = false) {
  const int n = static_cast<int>(vertices.size());
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  FreeStiffnessRows rows;
  // S = F and its one ring, numbered locally (F first, in the order given): the only
  // hash lookups are these, one per adjacency slot of S's rows; the assembly below runs
  // on local numbers. Sized to the region, not the mesh.
  IndexMap local(2 * static_cast<std::size_t>(n));
  std::vector<int>& S = rows.S;
  S.reserve(2 * static_cast<std::size_t>(n));
  for (int v : vertices)
    if (local.insert(v).second) S.push_back(v);
  for (int k = 0; k < n; ++k)
    for (int q = off[vertices[k]]; q < off[vertices[k] + 1]; ++q)
      if (local.insert(nbr[q]).second) S.push_back(nbr[q]);
  // Row s of K restricted to the free columns: (local free index, K value), diagonal first.
  // The free rows' neighbours are all in S: their local numbers are kept by adjacency slot
  // (slot_local), so the columns below need no hash lookup (a 10k drag region, two
  // threads: the assembly went from 3.4 to 3.2 ms with this, to 2.6 ms with the
  // transpose at the end).
  std::vector<int>& row_start = rows.row_start;
  std::vector<std::pair<int, double>>& row_entries = rows.row_entries;
  std::vector<int>& slot_start = rows.slot_start;
  std::vector<int>& slot_local = rows.slot_local;
  row_start.assign(S.size() + 1, 0);
  row_entries.reserve(8 * S.size());
  if (held) rows.held_start.assign(S.size() + 1, 0);
  slot_start.assign(static_cast<std::size_t>(n) + 1, 0);
  slot_local.reserve(7 * static_cast<std::size_t>(n));
  for (std::size_t r = 0; r < S.size(); ++r) {
    const int i = S[r];
    const bool free_row = r < static_cast<std::size_t>(n);
    if (free_row)
      row_entries.emplace_back(static_cast<int>(r), ops.Kii[i]);
    else if (held)
      rows.held_entries.emplace_back(i, ops.Kii[i]);
    for (int q = off[i]; q < off[i + 1]; ++q) {
      const int j = local.find(nbr[q]);
      if (free_row) slot_local.push_back(j);
      if (j >= 0 && j < n)
        row_entries.emplace_back(j, ops.Kij[q]);
      else if (held)
        rows.held_entries.emplace_back(nbr[q], ops.Kij[q]);
    }
    row_start[r + 1] = static_cast<int>(row_entries.size());
    if (held) rows.held_start[r + 1] = static_cast<int>(rows.held_entries.size());
    if (free_row) slot_start[r + 1] = static_cast<int>(slot_local.size());
  }
  return rows;
}

// Kt_FF from those rows (assemble_steady_matrix's body).
Eigen::SparseMatrix<double> assemble_from_rows(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& c,
                                               const std::vector<int>& vertices, const Eigen::VectorXd& extra_diagonal,
                                               const FreeStiffnessRows& rows) {
  const int n = static_cast<int>(vertices.size());
  const bool extra = extra_diagonal.size() > 0;
  const auto off = mesh.offsets();
  const std::vector<int>& S = rows.S;
  const std::vector<int>& row_start = rows.row_start;
  const std::vector<std::pair<int, double>>& row_entries = rows.row_entries;
  const std::vector<int>& slot_start = rows.slot_start;
  const std::vector<int>& slot_local = rows.slot_local;
  // g2 D on S, once per row rather than once per use (each row is used by about seven
  // columns).
  std::vector<double> g2_D(S.size());
  for (std::size_t r = 0; r < S.size(); ++r) g2_D[r] = c.g2 * ops.D(S[r]);
  // Column k of Kt_FF = g0 M + g1 K + g2 (K_SF)^T D_S K_SF, scattered into a dense work
  // column; K is symmetric, so the free entries of row k are column k's. Columns are
  // independent: with enough of them each thread assembles a contiguous block into its
  // own arrays (row indices unsorted), and the transpose below gathers the blocks.
  struct ColumnBlock {
    std::vector<int> inner;
    std::vector<double> values;
  };
  const int threads = n >= kParallelColumns ? max_threads() : 1;
  std::vector<ColumnBlock> blocks(static_cast<std::size_t>(threads));
  std::vector<int> column_size(static_cast<std::size_t>(n), 0);  // entries of each assembled column
  auto assemble_block = [&](int t) {
    const int k0 = static_cast<int>(static_cast<long>(n) * t / threads);
    const int k1 = static_cast<int>(static_cast<long>(n) * (t + 1) / threads);
    ColumnBlock& block = blocks[static_cast<std::size_t>(t)];
    block.inner.reserve(20 * static_cast<std::size_t>(k1 - k0));
    block.values.reserve(20 * static_cast<std::size_t>(k1 - k0));
    std::vector<double> work(static_cast<std::size_t>(n), 0.0);
    std::vector<char> touched(static_cast<std::size_t>(n), 0);
    std::vector<int> pattern;
    auto add = [&](int row, double value) {
      if (!touched[row]) {
        touched[row] = 1;
        pattern.push_back(row);
      }
      work[row] += value;
    };
    for (int k = k0; k < k1; ++k) {
      const int v = vertices[k];
      pattern.clear();
      add(k, c.g0 * ops.mass[v] + (extra ? extra_diagonal[v] : 0.0));
      if (c.g1 != 0)
        for (int e = row_start[k]; e < row_start[k + 1]; ++e) add(row_entries[e].first, c.g1 * row_entries[e].second);
      if (c.g2 != 0) {
        // (K_SF)^T D_S K_SF column k: every s with K_sk != 0 (k itself and its
        // neighbours, all in S), then every free f with K_fs != 0.
        auto through = [&](int s, double k_sk) {
          const double w = k_sk * g2_D[static_cast<std::size_t>(s)];
          for (int e = row_start[s]; e < row_start[s + 1]; ++e) add(row_entries[e].first, w * row_entries[e].second);
        };
        through(k, ops.Kii[v]);
        for (int q = off[v], slot = slot_start[k]; q < off[v + 1]; ++q, ++slot) through(slot_local[slot], ops.Kij[q]);
      }
      for (int row : pattern) {
        block.inner.push_back(row);
        block.values.push_back(work[row]);
        work[row] = 0;
        touched[row] = 0;
      }
      column_size[static_cast<std::size_t>(k)] = static_cast<int>(pattern.size());
    }
  };
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel for schedule(static, 1) if (threads > 1) num_threads(threads)
#endif
  for (int t = 0; t < threads; ++t) assemble_block(t);
  // The columns' row indices are unsorted (sorting each column's two-ring took about as
  // long as assembling it). Their transpose, by counting, has sorted ones, and it is the
  // same matrix: Kt_FF is symmetric, pattern and values (up to rounding in the order of
  // the sums).
  std::vector<int> start(static_cast<std::size_t>(n) + 1, 0);
  for (const ColumnBlock& block : blocks)
    for (int row : block.inner) ++start[static_cast<std::size_t>(row) + 1];
  for (int k = 0; k < n; ++k) start[static_cast<std::size_t>(k) + 1] += start[static_cast<std::size_t>(k)];
  Eigen::SparseMatrix<double> A(n, n);
  A.resizeNonZeros(start.back());
  std::copy(start.begin(), start.end(), A.outerIndexPtr());
  int* inner = A.innerIndexPtr();
  double* values = A.valuePtr();
  int k = 0;
  for (const ColumnBlock& block : blocks)
    for (std::size_t e = 0, end = 0; e < block.inner.size(); ++k) {
      // column k of the assembly, its entries in order
      for (end += static_cast<std::size_t>(column_size[static_cast<std::size_t>(k)]); e < end; ++e) {
        const int at = start[static_cast<std::size_t>(block.inner[e])]++;
        inner[at] = k;
        values[at] = block.values[e];
      }
    }
  return A;
}

}  // namespace

Eigen::SparseMatrix<double> assemble_steady_matrix(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& c,
                                                   const std::vector<int>& vertices,
                                                   const Eigen::VectorXd& extra_diagonal) {
  return assemble_from_rows(mesh, ops, c, vertices, extra_diagonal, free_stiffness_rows(mesh, ops, vertices));
}

SteadyDirectSolver::SteadyDirectSolver(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& c,
                                       std::vector<int> free, SparseCholesky::Backend backend,
                                       const Eigen::VectorXd& extra_diagonal, DirectOrdering ordering,
                                       const NestedDissection* order)
    : mesh_(mesh), ops_(ops), c_(c), free_(std::move(free)), chol_(backend) {
  const int nv = mesh.num_vertices(), n = static_cast<int>(free_.size());
  const bool extra = extra_diagonal.size() > 0;
  if (extra && extra_diagonal.size() != nv)
    throw InputError(fmt::format("extra diagonal has {} values for {} vertices", extra_diagonal.size(), nv));
  if (extra && !(extra_diagonal.minCoeff() >= 0 && extra_diagonal.allFinite()))
    throw InputError("extra diagonal entries must be finite and non-negative");
  local_.reserve(2 * static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const int v = free_[k];
    if (v < 0 || v >= nv) throw InputError(fmt::format("free vertex {} does not exist (the mesh has {})", v, nv));
    if (!local_.emplace(v, k).second) throw InputError(fmt::format("free vertex {} is listed twice", v));
  }
  // Parts of the free set that touch no held vertex are undetermined without g0.
  if (c.g0 <= 0)
    detail::require_held_parts(
        mesh, free_, [&](int v) { return local_index(v); }, [&](int v) { return extra && extra_diagonal[v] > 0; });
  // The assembly's rows of K are kept as K_SF for multiply() (the refinement's products).
  FreeStiffnessRows rows = free_stiffness_rows(mesh, ops, free_, true);
  A_ = assemble_from_rows(mesh, ops, c, free_, extra_diagonal, rows);
  K_SF_ = rows.matrix(n);
  held_start_ = std::move(rows.held_start);
  held_entries_ = std::move(rows.held_entries);
  g2_D_S_.resize(static_cast<Eigen::Index>(rows.S.size()));
  for (std::size_t r = 0; r < rows.S.size(); ++r) g2_D_S_[static_cast<Eigen::Index>(r)] = c.g2 * ops.D(rows.S[r]);
  diagonal_.resize(n);
  for (int k = 0; k < n; ++k) diagonal_[k] = c.g0 * ops.mass[free_[k]] + (extra ? extra_diagonal[free_[k]] : 0.0);
  for (Eigen::Index k = 0; k < A_.outerSize(); ++k) {  // ||A||_inf = ||A||_1 (symmetric)
    double sum = 0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(A_, k); it; ++it) sum += std::abs(it.value());
    a_norm_inf_ = std::max(a_norm_inf_, sum);
  }
  const bool given = order != nullptr;
  if (given || ordering == DirectOrdering::Mesh || ordering == DirectOrdering::MeshSplit ||
      (ordering == DirectOrdering::Auto && c.g2 != 0 && n >= kMeshOrderingFrom && mesh_ordering_available() &&
       backend != SparseCholesky::Backend::Eigen && SparseCholesky::cholmod_available())) {
    // The free vertices in mesh order (or in the order given), as rows of A_.
    NestedDissection nd;
    if (given) {
      nd = *order;
      if (nd.order.size() != free_.size())
        throw InputError(
            fmt::format("the given order has {} vertices for {} free vertices", nd.order.size(), free_.size()));
      std::vector<char> seen(free_.size(), 0);
      for (int& v : nd.order) {
        const int k = local_index(v);
        if (k < 0 || seen[static_cast<std::size_t>(k)])
          throw InputError(
              fmt::format("the given order {} vertex {}", k < 0 ? "has a vertex that is not free:" : "repeats", v));
        seen[static_cast<std::size_t>(k)] = 1;
        v = k;
      }
    } else {
      MeshOrderingParams p;
      p.separator_hops = c.g2 != 0 ? 2 : 1;
      nd = mesh_nested_dissection(mesh, free_, p);
      for (int& v : nd.order) v = local_index(v);
    }
    // Its top level's two parts are factored on two threads (SparseCholesky's split
    // factor) when there is a separator between them.
    const bool split = (ordering == DirectOrdering::Auto || ordering == DirectOrdering::MeshSplit) && nd.parts[1] > 0 &&
                       nd.parts[0] + nd.parts[1] < nd.order.size();
    // A given order asked to be CHOLMOD's keeps CHOLMOD's supernodes (InterpolationSolver,
    // whose factor is swept at every click, reuses CHOLMOD's order).
    chol_.set_order(std::move(nd.order), split ? nd.parts[0] : 0, split ? nd.parts[1] : 0,
                    !(given && ordering == DirectOrdering::Cholmod));
  }
  chol_.factorize(A_);
}

NestedDissection SteadyDirectSolver::vertex_order() const {
  NestedDissection out;
  out.order = chol_.order();
  for (int& k : out.order) k = free_[static_cast<std::size_t>(k)];
  const auto parts = chol_.split_parts();
  const bool split = parts[1] > 0 && !out.order.empty();
  out.parts[0] = split ? parts[0] : out.order.size();
  out.parts[1] = split ? parts[1] : 0;
  return out;
}

Field SteadyDirectSolver::solve(const Field& u, const Field* f) const {
  const Eigen::MatrixXd x = solve_free(u, f);
  Field out = u;
  for (std::size_t k = 0; k < free_.size(); ++k) out.row(free_[k]) = x.row(static_cast<Eigen::Index>(k));
  return out;
}

Eigen::MatrixXd SteadyDirectSolver::solve_free(const Field& u, const Field* f) const {
  const int nv = mesh_.num_vertices(), n = static_cast<int>(free_.size());
  if (u.rows() != nv) throw InputError(fmt::format("values have {} rows for {} vertices", u.rows(), nv));
  if (f && (f->rows() != nv || f->cols() != u.cols())) throw InputError("forcing has the wrong shape");
  const int m = static_cast<int>(u.cols());
  // b_F = f_F - Kt_FC u_C = f_F - g1 w_F - g2 (K_SF)^T D_S w with w = K_SC u_C on S (F
  // first, then its one ring): the held values enter through the kept K_SC rows, with
  // no hash lookup (row by row through a hash of the free set, about fifty lookups a
  // free vertex, it took 1.6 s more of the 1.15M-vertex solve).
  Eigen::MatrixXd w(static_cast<Eigen::Index>(held_start_.size()) - 1, m);
  w.setZero();
  for (Eigen::Index r = 0; r < w.rows(); ++r) {
    const auto begin = static_cast<std::size_t>(held_start_[static_cast<std::size_t>(r)]);
    const auto end = static_cast<std::size_t>(held_start_[static_cast<std::size_t>(r) + 1]);
    for (std::size_t e = begin; e < end; ++e) {
      const auto& [vertex, k] = held_entries_[e];
      w.row(r) += k * u.row(vertex);
    }
  }
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, m);
  if (c_.g1 != 0) b -= c_.g1 * w.topRows(n);
  if (c_.g2 != 0) b -= K_SF_.transpose() * (g2_D_S_.asDiagonal() * w);
  if (f)
    for (int k = 0; k < n; ++k) b.row(k) += f->row(free_[static_cast<std::size_t>(k)]);
  return solve_rhs(b);
}

Eigen::MatrixXd SteadyDirectSolver::solve_rhs(const Eigen::MatrixXd& b) const {
  if (b.rows() != num_free())
    throw InputError(fmt::format("right-hand side has {} rows for {} free vertices", b.rows(), num_free()));
  // CG preconditioned by the factor, with the residuals through the products
  // (multiply()): the assembled matrix's own rounding is what it removes.
  RefinedSolve s = pcg_refined_solve(
      b, [&](const Eigen::MatrixXd& r) { return chol_.solve(r); },
      [&](const Eigen::MatrixXd& x) -> Eigen::MatrixXd { return multiply(x); }, a_norm_inf_, refine_tolerance,
      max_refinements);
  residual_ = s.relative_residual;
  refinements_ = s.steps;
  // Normwise backward error (Rigal and Gaches): the smallest relative change of A and b
  // that makes x exact; the forward error is about cond times this.
  backward_error_ = s.backward_error;
  return std::move(s.x);
}

Eigen::MatrixXd SteadyDirectSolver::multiply(const Eigen::MatrixXd& X) const {
  const Eigen::Index n = X.rows();
  Eigen::MatrixXd Y = diagonal_.asDiagonal() * X;
  if (c_.g1 != 0 || c_.g2 != 0) {
    const Eigen::MatrixXd KX = K_SF_ * X;  // K_SF X: its first n rows are K_FF X
    if (c_.g1 != 0) Y += c_.g1 * KX.topRows(n);
    if (c_.g2 != 0) Y += K_SF_.transpose() * (g2_D_S_.asDiagonal() * KX);
  }
  return Y;
}

std::vector<std::pair<int, double>> steady_coupling(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& c,
                                                    int v) {
  const int nv = mesh.num_vertices();
  if (v < 0 || v >= nv) throw InputError(fmt::format("vertex {} does not exist (the mesh has {})", v, nv));
  auto unit = [v](int j) { return j == v ? 1.0 : 0.0; };
  // Rows that Kt couples to v: v's one ring (M, K) and two rings (K D K).
  std::vector<int> near{v};
  for (int w : mesh.neighbors(v)) near.push_back(w);
  const std::size_t ring1 = near.size();
  for (std::size_t k = 1; k < ring1; ++k)
    for (int w : mesh.neighbors(near[k])) near.push_back(w);
  std::sort(near.begin(), near.end());
  near.erase(std::unique(near.begin(), near.end()), near.end());
  std::vector<std::pair<int, double>> out;
  out.reserve(near.size());
  for (int i : near) {
    double kt = (i == v ? c.g0 * ops.mass[i] : 0.0) + c.g1 * stiffness_row(mesh, ops, i, unit);
    if (c.g2 != 0) kt += c.g2 * bilaplacian_row(mesh, ops, i, unit);
    out.emplace_back(i, -kt);
  }
  return out;
}

Eigen::VectorXd SteadyDirectSolver::coupling(int v) const {
  if (v >= 0 && v < mesh_.num_vertices() && local_index(v) >= 0)
    throw InputError(fmt::format("vertex {} is free, not held", v));
  Eigen::VectorXd b = Eigen::VectorXd::Zero(num_free());
  for (const auto& [i, value] : steady_coupling(mesh_, ops_, c_, v))
    if (const int k = local_index(i); k >= 0) b[k] = value;
  return b;
}

SteadyDirectSolver::Conditioning SteadyDirectSolver::conditioning(double accuracy) const {
  // The condition number of the diagonally scaled matrix B = S A S, S = diag(A)^-1/2:
  // Cholesky's rounding errors are invariant under that scaling (van der Sluis), so
  // cond(B), not cond(A), is what bounds the error; cond(A) also counts the spread of
  // the vertex areas, which costs no accuracy.
  const Eigen::Index n = A_.rows();
  if (n == 0) return Conditioning{};  // no unknowns (a region that is its handles): exact
  const Eigen::VectorXd s = A_.diagonal().cwiseSqrt().cwiseInverse();
  if (inverse_norm_1_ < 0) {
    // Hager's estimator (Higham's refinement, LAPACK dlacon) of ||B^-1||_1: maximize
    // |B^-1 x|_1 over |x|_1 = 1 by a few steps of a subgradient ascent; B is symmetric.
    // B^-1 x = S^-1 A^-1 S^-1 x: two scalings around a solve with the existing factor.
    auto apply_inverse = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return chol_.solve(x.cwiseQuotient(s)).col(0).cwiseQuotient(s);
    };
    Eigen::VectorXd x = Eigen::VectorXd::Constant(n, 1.0 / static_cast<double>(n));
    double est = 0;
    Eigen::Index last = -1;
    for (int it = 0; it < 5; ++it) {
      const Eigen::VectorXd y = apply_inverse(x);
      const double norm = y.lpNorm<1>();
      if (it > 0 && norm <= est) break;
      est = norm;
      const Eigen::VectorXd sign = y.unaryExpr([](double t) { return t >= 0 ? 1.0 : -1.0; });
      const Eigen::VectorXd z = apply_inverse(sign);
      Eigen::Index j = 0;
      z.cwiseAbs().maxCoeff(&j);
      if (j == last || z.cwiseAbs()[j] <= z.dot(x)) break;
      last = j;
      x.setZero();
      x[j] = 1;
    }
    // Higham's extra test vector catches matrices the ascent underestimates.
    Eigen::VectorXd alt(n);
    for (Eigen::Index i = 0; i < n; ++i)
      alt[i] =
          (i % 2 ? -1.0 : 1.0) * (1.0 + static_cast<double>(i) / static_cast<double>(std::max<Eigen::Index>(1, n - 1)));
    const double alt_est = 2 * apply_inverse(alt).lpNorm<1>() / (3 * static_cast<double>(n));
    inverse_norm_1_ = std::max(est, alt_est);
  }
  double b_norm = 0;  // ||B||_1: the largest column sum of |s_i A_ij s_j| (B is symmetric)
  for (Eigen::Index k = 0; k < A_.outerSize(); ++k) {
    double sum = 0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(A_, k); it; ++it) sum += std::abs(it.value()) * s[it.row()];
    b_norm = std::max(b_norm, sum * s[k]);
  }
  Conditioning c;
  c.condition_1 = b_norm * inverse_norm_1_;
  c.relative_error = c.condition_1 * std::max(std::numeric_limits<double>::epsilon() / 2, backward_error_);
  c.sufficient = c.relative_error <= accuracy;
  if (!c.sufficient)
    c.message = fmt::format(
        "the system is too ill-conditioned for the requested accuracy: condition number about {:.1e}, so "
        "the answer may be off by {:.1e} of its size (asked: {:.0e}); badly shaped triangles cause this: "
        "use the intrinsic Delaunay Laplacian (intrinsic, or the automatic choice)",
        c.condition_1, c.relative_error, accuracy);
  return c;
}

SteadySolver parse_steady_solver(const std::string& name) {
  for (const SteadySolver s : {SteadySolver::Auto, SteadySolver::Direct, SteadySolver::Iterative, SteadySolver::Global})
    if (name == to_string(s)) return s;
  throw InputError(fmt::format("solver: expected 'auto', 'direct', 'global' or 'iterative', got '{}'", name));
}

const char* to_string(SteadySolver solver) {
  switch (solver) {
    case SteadySolver::Auto:
      return "auto";
    case SteadySolver::Direct:
      return "direct";
    case SteadySolver::Iterative:
      return "iterative";
    case SteadySolver::Global:
      return "global";
  }
  return "unknown";
}

bool auto_tries_multigrid(const Mesh& mesh, const PdeCoefficients& coefficients, const std::vector<int>& free,
                          int global_from) {
  if (!(coefficients.g2 > 0) || coefficients.g0 != 0 ||
      free.size() < static_cast<std::size_t>(std::max(global_from, 0)))
    return false;
  std::vector<char> is_free(static_cast<std::size_t>(mesh.num_vertices()), 0);
  for (const int v : free)
    if (v >= 0 && v < mesh.num_vertices()) is_free[static_cast<std::size_t>(v)] = 1;
  const Triangles& F = mesh.triangles();
  std::vector<int> around;
  for (int f = 0; f < F.rows(); ++f)
    if (is_free[static_cast<std::size_t>(F(f, 0))] || is_free[static_cast<std::size_t>(F(f, 1))] ||
        is_free[static_cast<std::size_t>(F(f, 2))])
      around.push_back(f);
  return smallest_angle_deg(mesh.positions(), F, around) >= kAutoMultigridMinAngleDeg;
}

std::optional<SteadySolveResult> try_multigrid_solve(const Mesh& mesh, const FemOperators& ops,
                                                     const PdeCoefficients& coefficients, const std::vector<int>& free,
                                                     const Field& u, int* probe_iterations,
                                                     const SurfaceMultigridParams& multigrid) {
  if (probe_iterations) *probe_iterations = 0;
  // The multigrid's probe decides: kept where it converges (well-shaped meshes, where it
  // is several times faster than a factorization), given up where its rate predicts more
  // than max_multigrid_iterations (real meshes with slivers, where neither it nor the
  // Laplacian factor beats the direct solve: docs/solvers-measurements.md).
  GlobalBilaplacianParams gp{.g1 = coefficients.g1, .g2 = coefficients.g2, .tolerance = 1e-10};
  gp.hand_on_to_factor = false;
  gp.multigrid = multigrid;
  try {
    GlobalBilaplacianResult g = solve_global_bilaplacian(mesh, ops, free, u, gp);
    if (probe_iterations) *probe_iterations = g.multigrid_iterations;
    if (!g.converged) return std::nullopt;
    SteadySolveResult r;
    r.values = std::move(g.values);
    r.iterations = g.iterations;
    r.relative_residual = g.relative_residual;
    r.solver = SteadySolver::Global;
    r.multigrid_probe_iterations = g.multigrid_iterations;
    return r;
  } catch (const SolverError&) {
    // The multigrid cannot serve this mesh (a coarse level that rounding makes
    // indefinite, as carotid-ica-4k's cotangent one): the direct solve's turn.
    return std::nullopt;
  }
}

SteadySolveResult solve_steady(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients,
                               const std::vector<int>& free, const Field& u, SteadySolver solver, int global_from,
                               const CgOptions& iterative) {
  int probe = 0;
  if (solver == SteadySolver::Auto) {
    if (auto_tries_multigrid(mesh, coefficients, free, global_from))
      if (std::optional<SteadySolveResult> g = try_multigrid_solve(mesh, ops, coefficients, free, u, &probe))
        return std::move(*g);
    solver = SteadySolver::Direct;
  }
  SteadySolveResult r;
  r.multigrid_probe_iterations = probe;
  r.solver = solver;
  if (solver == SteadySolver::Direct) {
    const SteadyDirectSolver direct(mesh, ops, coefficients, free);
    r.values = direct.solve(u);
    r.relative_residual = direct.last_relative_residual();
    return r;
  }
  if (solver == SteadySolver::Iterative) {
    // Jacobi-CG on the free set as the session's domain: every other vertex is held at
    // its value in u; the free rows of u are the starting guess.
    PdeSession session(
        mesh, ops, static_cast<int>(u.cols()),
        PdeCoefficients{
            .alpha = 0, .b1 = 0, .b2 = 0, .g0 = coefficients.g0, .g1 = coefficients.g1, .g2 = coefficients.g2},
        DomainOptions{.seed_rings = 0});
    session.cg_options = iterative;
    session.set_values(u);
    session.activate(free);
    const StepResult step = session.solve_steady();
    r.values = session.values();
    r.iterations = step.cg.iterations;
    r.relative_residual = step.cg.relative_residual;
    r.converged = step.cg.converged();
    r.message = step.cg.message;
    return r;
  }
  if (!(coefficients.g2 > 0) || coefficients.g0 != 0)
    throw InputError(
        fmt::format("the global solver needs a bi-Laplacian term (g2 > 0) and no g0 term (g2 = {}, g0 = {}); "
                    "use the direct solver",
                    coefficients.g2, coefficients.g0));
  const GlobalBilaplacianResult g = solve_global_bilaplacian(
      mesh, ops, free, u, GlobalBilaplacianParams{.g1 = coefficients.g1, .g2 = coefficients.g2, .tolerance = 1e-10});
  r.converged = g.converged;
  if (!g.converged)
    r.message = fmt::format("the global solver stopped after {} iterations at relative residual {:.2g}", g.iterations,
                            g.relative_residual);
  r.values = g.values;
  r.iterations = g.iterations;
  r.relative_residual = g.relative_residual;
  return r;
}

}  // namespace meshpde
