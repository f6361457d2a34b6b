#include "meshpde/solvers/surface_multigrid.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/solvers/cg.h"
#include "meshpde/solvers/direct.h"

#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

namespace meshpde {
namespace {

using RowSparse = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

// Levels of at least this many rows run their products and vector updates on every
// thread. Lower than the 20k rows of one-off applies (core/parallel.h) because the
// cycle keeps the threads busy, so they wake fast: at 164k (levels of 162k, 40k, 10k,
// 2.5k rows) 5,000 took the solve from 26-28 to 23-24 ms an iteration against 20,000;
// 1,500 changed nothing more.
constexpr Eigen::Index kParallelRows = 5000;

// Y = S X for a compressed row-major S and row-major blocks, rows split over threads.
// Specialized for one and three columns (scalars, displacements).
template <int M>
void spmm_fixed(const RowSparse& S, const double* x, double* y, Eigen::Index m) {
  const Eigen::Index n = S.rows();
  const int* outer = S.outerIndexPtr();
  const int* inner = S.innerIndexPtr();
  const double* val = S.valuePtr();
  const Eigen::Index cols = M > 0 ? M : m;
  [[maybe_unused]] const bool parallel = n >= kParallelRows;
  [[maybe_unused]] const int threads = max_threads();
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel for schedule(static) if (parallel) num_threads(threads)
#endif
  for (Eigen::Index i = 0; i < n; ++i) {
    if constexpr (M > 0) {
      std::array<double, M> acc{};
      for (int k = outer[i]; k < outer[i + 1]; ++k) {
        const double v = val[k];
        const double* xr = x + static_cast<Eigen::Index>(inner[k]) * M;
        for (int c = 0; c < M; ++c) acc[c] += v * xr[c];
      }
      for (int c = 0; c < M; ++c) y[i * M + c] = acc[c];
    } else {
      double* yr = y + i * cols;
      for (Eigen::Index c = 0; c < cols; ++c) yr[c] = 0;
      for (int k = outer[i]; k < outer[i + 1]; ++k) {
        const double v = val[k];
        const double* xr = x + static_cast<Eigen::Index>(inner[k]) * cols;
        for (Eigen::Index c = 0; c < cols; ++c) yr[c] += v * xr[c];
      }
    }
  }
}

void spmm(const RowSparse& S, const Field& X, Field& Y) {
  Y.resize(S.rows(), X.cols());
  switch (X.cols()) {
    case 1:
      spmm_fixed<1>(S, X.data(), Y.data(), 1);
      break;
    case 3:
      spmm_fixed<3>(S, X.data(), Y.data(), 3);
      break;
    default:
      spmm_fixed<0>(S, X.data(), Y.data(), X.cols());
  }
}

// The cycle's and CG's vector updates run on every thread from kParallelRows rows on
// (for_row_ranges, core/parallel.h): serial, they were 14 % of a perf profile of the
// 164k solve (spin-waiting threads' samples included).
template <class F>
int for_row_ranges(Eigen::Index n, F&& f) {
  return meshpde::for_row_ranges(n, kParallelRows, std::forward<F>(f));
}

// A compressed row-major matrix from rows given as (column, value) lists.
RowSparse from_rows(Eigen::Index rows, Eigen::Index cols, const std::vector<int>& offsets,
                    const std::vector<int>& columns, const std::vector<double>& values) {
  return RowSparse(Eigen::Map<const RowSparse>(rows, cols, static_cast<Eigen::Index>(values.size()), offsets.data(),
                                               columns.data(), values.data()));
}

// The nodes of one level: a subset of the mesh's vertices, free or held, with a graph.
struct Nodes {
  std::vector<int> vertex;    // mesh vertex of each node
  std::vector<int> unknown;   // index among the level's free nodes, -1 for a held node
  std::vector<int> off, adj;  // graph (CSR), symmetric, no self loops
  int free_count = 0;
  int size() const { return static_cast<int>(vertex.size()); }
};

// Maximal independent set in node order, each other node assigned to its nearest
// adjacent seed, the seeds' graph from touching cells, and the prolongation of the
// free nodes from the free seeds (module comment). `position(v)` and `normal(v)` take
// mesh vertices.
template <class Position, class Normal>
std::pair<Nodes, RowSparse> coarsen(const Nodes& fine, Position&& position, Normal&& normal) {
  const int n = fine.size();
  std::vector<int> coarse_of(n, -1), owner(n, -1);
  std::vector<char> excluded(n, 0);
  Nodes coarse;
  for (int i = 0; i < n; ++i) {
    if (excluded[i]) continue;
    coarse_of[i] = coarse.size();
    owner[i] = i;
    coarse.vertex.push_back(fine.vertex[i]);
    coarse.unknown.push_back(fine.unknown[i] >= 0 ? coarse.free_count++ : -1);
    for (int q = fine.off[i]; q < fine.off[i + 1]; ++q) excluded[fine.adj[q]] = 1;
  }
  for (int i = 0; i < n; ++i) {
    if (owner[i] >= 0) continue;
    const Eigen::Vector3d x = position(fine.vertex[i]);
    double best = std::numeric_limits<double>::infinity();
    for (int q = fine.off[i]; q < fine.off[i + 1]; ++q) {
      const int j = fine.adj[q];
      if (coarse_of[j] < 0) continue;
      const double d = (position(fine.vertex[j]) - x).squaredNorm();
      if (d < best) best = d, owner[i] = j;
    }
  }
  // Cells: the fine nodes grouped by their coarse node (counting sort).
  const int nc = coarse.size();
  std::vector<int> cell_off(static_cast<std::size_t>(nc) + 1, 0), cell(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) ++cell_off[static_cast<std::size_t>(coarse_of[owner[i]]) + 1];
  for (int c = 0; c < nc; ++c) cell_off[c + 1] += cell_off[c];
  {
    std::vector<int> fill(cell_off.begin(), cell_off.end() - 1);
    for (int i = 0; i < n; ++i) cell[static_cast<std::size_t>(fill[coarse_of[owner[i]]]++)] = i;
  }
  // The seeds' graph: two seeds are neighbours when an edge joins their cells.
  coarse.off.assign(1, 0);
  coarse.adj.reserve(static_cast<std::size_t>(nc) * 8);
  {
    std::vector<int> mark(static_cast<std::size_t>(nc), -1);
    for (int c = 0; c < nc; ++c) {
      const std::size_t first = coarse.adj.size();
      for (int k = cell_off[c]; k < cell_off[c + 1]; ++k) {
        const int i = cell[static_cast<std::size_t>(k)];
        for (int q = fine.off[i]; q < fine.off[i + 1]; ++q) {
          const int o = coarse_of[owner[fine.adj[q]]];
          if (o != c && mark[static_cast<std::size_t>(o)] != c) {
            mark[static_cast<std::size_t>(o)] = c;
            coarse.adj.push_back(o);
          }
        }
      }
      std::sort(coarse.adj.begin() + static_cast<std::ptrdiff_t>(first), coarse.adj.end());
      coarse.off.push_back(static_cast<int>(coarse.adj.size()));
    }
  }

  // Prolongation rows of the free fine nodes (row = fine unknown, column = coarse
  // unknown; weights on held seeds are dropped: the correction is zero there). Each
  // coarse node's spokes (its coarse neighbours in its tangent plane, by angle) are
  // computed once for its whole cell.
  struct Spoke {
    double angle, x, y;
    int node;
  };
  struct Weight {
    int row, col;
    double w;
  };
  // Cells are independent: on large levels the threads take cells in turn, each with
  // its own weights (rows are sorted below, so the order they come in does not
  // matter) and scratch. A tangent plane is cached per node and only the cell's own
  // coarse node asks for it, so no two threads write the same entry.
  constexpr double two_pi = 2 * std::numbers::pi;
  [[maybe_unused]] const bool parallel = n >= kParallelRows;
  const int parts = parallel ? max_threads() : 1;
  std::vector<std::vector<Weight>> weights_of(static_cast<std::size_t>(parts));
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel if (parallel) num_threads(parts)
#endif
  {
#ifdef MESHPDE_HAVE_OPENMP
    std::vector<Weight>& weights = weights_of[static_cast<std::size_t>(omp_get_thread_num())];
#else
    std::vector<Weight>& weights = weights_of[0];
#endif
    weights.reserve(static_cast<std::size_t>(fine.free_count) * 3 / weights_of.size() + 16);
    std::vector<Spoke> spokes;
    Eigen::VectorXd fit_weights;
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp for schedule(dynamic, 512)
#endif
    for (int c = 0; c < nc; ++c) {
      const Eigen::Vector3d xc = position(coarse.vertex[static_cast<std::size_t>(c)]);
      Eigen::Vector3d t1 = Eigen::Vector3d::UnitX(), t2 = Eigen::Vector3d::UnitY();
      spokes.clear();
      const bool interpolate = cell_off[c + 1] - cell_off[c] > 1;
      if (interpolate) {
        const Eigen::Vector3d nrm = normal(coarse.vertex[static_cast<std::size_t>(c)]);
        t1 = (std::abs(nrm.x()) < 0.9 ? nrm.cross(Eigen::Vector3d::UnitX()) : nrm.cross(Eigen::Vector3d::UnitY()))
                 .normalized();
        t2 = nrm.cross(t1);
        for (int q = coarse.off[c]; q < coarse.off[c + 1]; ++q) {
          const Eigen::Vector3d e = position(coarse.vertex[static_cast<std::size_t>(coarse.adj[q])]) - xc;
          const double ex = e.dot(t1), ey = e.dot(t2);
          if (ex * ex + ey * ey > 0) spokes.push_back({std::atan2(ey, ex), ex, ey, coarse.adj[q]});
        }
        std::sort(spokes.begin(), spokes.end(), [](const Spoke& a, const Spoke& b) { return a.angle < b.angle; });
      }
      const int k = static_cast<int>(spokes.size());
      // Minimum weighted-norm weights w (c first, then the spokes) with sum w = 1 and
      // sum w q = p: w = Phi Q^T (Q Phi Q^T)^-1 (1, px, py), Q the 3 x (k+1) matrix of
      // (1, q), Phi = diag(1 / (1 + |q|^2 / h^2)) favouring near nodes.
      auto fan_fit = [&](double px, double py) {
        Eigen::MatrixXd Q(3, k + 1);
        Eigen::VectorXd phi(k + 1);
        double h2 = 0;
        for (const Spoke& sp : spokes) h2 += sp.x * sp.x + sp.y * sp.y;
        h2 /= k;
        Q.col(0) << 1, 0, 0;
        phi[0] = 1;
        for (int s2 = 0; s2 < k; ++s2) {
          const Spoke& sp = spokes[static_cast<std::size_t>(s2)];
          Q.col(s2 + 1) << 1, sp.x, sp.y;
          phi[s2 + 1] = 1 / (1 + (sp.x * sp.x + sp.y * sp.y) / h2);
        }
        const Eigen::Matrix3d G = Q * phi.asDiagonal() * Q.transpose();
        const Eigen::LDLT<Eigen::Matrix3d> ldlt(G);
        if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-10 * ldlt.vectorD().maxCoeff()))
          return false;  // the fan spans no plane (all spokes on a line)
        fit_weights = phi.asDiagonal() * (Q.transpose() * ldlt.solve(Eigen::Vector3d(1, px, py)));
        return true;
      };
      for (int e = cell_off[c]; e < cell_off[c + 1]; ++e) {
        const int i = cell[static_cast<std::size_t>(e)];
        const int u = fine.unknown[static_cast<std::size_t>(i)];
        if (u < 0) continue;
        auto add = [&](int node, double w) { weights.push_back({u, node, w}); };
        if (i == owner[i] || k == 0) {
          add(c, 1.0);
          continue;
        }
        const Eigen::Vector3d d = position(fine.vertex[static_cast<std::size_t>(i)]) - xc;
        const double px = d.dot(t1), py = d.dot(t2);
        const double pa = std::atan2(py, px);
        bool done = false;
        for (int s = 0; s < k && k >= 2; ++s) {
          const Spoke& a = spokes[static_cast<std::size_t>(s)];
          const Spoke& b = spokes[static_cast<std::size_t>((s + 1) % k)];
          double gap = b.angle - a.angle, off = pa - a.angle;
          if (gap <= 0) gap += two_pi;
          if (off < 0) off += two_pi;
          if (off > gap) continue;
          if (gap >= std::numbers::pi * (1 - 1e-9)) break;  // an open side: the fan's fit below
          const double det = a.x * b.y - a.y * b.x;
          double la = std::max((px * b.y - py * b.x) / det, 0.0), lb = std::max((a.x * py - a.y * px) / det, 0.0);
          const double lc = 1 - la - lb;
          if (lc < -1e-9) break;  // beyond the far edge: the fan's fit below
          add(c, std::max(lc, 0.0));
          add(a.node, la);
          add(b.node, lb);
          done = true;
          break;
        }
        if (!done && k >= 2 && fan_fit(px, py)) {
          // Outside every triangle of the fan (beyond a far edge, or on an open side):
          // the smallest weights, each damped by its spoke's length, over c and its whole
          // fan that reproduce constants and the tangent plane's linear functions exactly
          // (negative weights allowed), so linear precision holds here too.
          add(c, fit_weights[0]);
          for (int s2 = 0; s2 < k; ++s2)
            add(spokes[static_cast<std::size_t>(s2)].node, fit_weights[static_cast<std::size_t>(s2) + 1]);
          done = true;
        }
        if (!done) {
          // Along the spoke nearest in angle, clamped to the segment.
          const Spoke* best = &spokes[0];
          double best_off = two_pi;
          for (const Spoke& sp : spokes) {
            double off = std::abs(pa - sp.angle);
            if (off > std::numbers::pi) off = two_pi - off;
            if (off < best_off) best_off = off, best = &sp;
          }
          const double t =
              std::clamp((px * best->x + py * best->y) / (best->x * best->x + best->y * best->y), 0.0, 1.0);
          add(c, 1 - t);
          add(best->node, t);
        }
      }
    }
  }
  std::vector<Weight> weights;
  for (auto& part : weights_of) weights.insert(weights.end(), part.begin(), part.end());
  // Rows in order, held coarse nodes and zero weights dropped.
  std::vector<int> p_off(static_cast<std::size_t>(fine.free_count) + 1, 0), p_col;
  std::vector<double> p_val;
  for (const Weight& w : weights)
    if (coarse.unknown[static_cast<std::size_t>(w.col)] >= 0 && std::abs(w.w) > 1e-12)
      ++p_off[static_cast<std::size_t>(w.row) + 1];
  for (int u = 0; u < fine.free_count; ++u) p_off[u + 1] += p_off[u];
  p_col.resize(static_cast<std::size_t>(p_off.back()));
  p_val.resize(p_col.size());
  {
    std::vector<int> fill(p_off.begin(), p_off.end() - 1);
    for (const Weight& w : weights) {
      const int col = coarse.unknown[static_cast<std::size_t>(w.col)];
      if (col < 0 || !(std::abs(w.w) > 1e-12)) continue;
      const int at = fill[static_cast<std::size_t>(w.row)]++;
      p_col[static_cast<std::size_t>(at)] = col;
      p_val[static_cast<std::size_t>(at)] = w.w;
    }
  }
  // Columns in order within each row (a few entries, all distinct nodes).
  for (int u = 0; u < fine.free_count; ++u)
    for (int a2 = p_off[u] + 1; a2 < p_off[u + 1]; ++a2)
      for (int b2 = a2; b2 > p_off[u] && p_col[static_cast<std::size_t>(b2 - 1)] > p_col[static_cast<std::size_t>(b2)];
           --b2) {
        std::swap(p_col[static_cast<std::size_t>(b2 - 1)], p_col[static_cast<std::size_t>(b2)]);
        std::swap(p_val[static_cast<std::size_t>(b2 - 1)], p_val[static_cast<std::size_t>(b2)]);
      }
  RowSparse P = from_rows(fine.free_count, coarse.free_count, p_off, p_col, p_val);
  return {std::move(coarse), std::move(P)};
}

}  // namespace

struct BilaplacianMultigrid::Impl {
  struct Level {
    int n = 0;
    RowSparse A;               // assembled operator (below the finest; the finest for Gauss-Seidel)
    Eigen::VectorXd inv_diag;  // 1 / A_ii
    double lambda_max = 0;     // of D_A^-1 A, with a 10 % margin
    RowSparse P, Pt;           // to the next coarser level (n x n_next) and back
    mutable Field b, x, r, t, d, t2, e;
  };
  SurfaceMultigridParams params;
  double g1 = 0, g2 = 1;
  int nF = 0, nR = 0;
  RowSparse KRF, KFR;  // K restricted to (free and ring) x free, and its transpose
  Eigen::VectorXd dR;  // g2 D on the free vertices and their ring
  mutable Field kx, g1x;
  std::vector<Level> levels;
  SparseCholesky coarse;  // of the coarsest level

  // The finest operator assembled, A_0 = K_FR (g2 D) K_RF + g1 K_FF (two-ring stencil):
  // for Gauss-Seidel, which needs its rows, and as the coarsest level of a small problem.
  RowSparse assemble_finest() const {
    const RowSparse DK = dR.asDiagonal() * KRF;
    RowSparse A = KFR * DK;
    if (g1 > 0) A += RowSparse(g1 * RowSparse(KRF.topRows(nF)));
    A.makeCompressed();
    return A;
  }

  void apply(std::size_t l, const Field& X, Field& Y) const {
    if (l > 0 || levels[0].A.rows() > 0) return spmm(levels[l].A, X, Y);
    spmm(KRF, X, kx);
    if (g1 > 0) g1x = g1 * kx.topRows(nF);
    const Eigen::Index m = kx.cols();
    for_row_ranges(nR, [&](Eigen::Index begin, Eigen::Index end, int) {
      double* K = kx.data();
      for (Eigen::Index i = begin; i < end; ++i)
        for (Eigen::Index c = 0; c < m; ++c) K[i * m + c] *= dR[i];
    });
    spmm(KFR, kx, Y);
    if (g1 > 0) Y += g1x;
  }

  // The largest eigenvalue of D_A^-1 A by eight Lanczos steps on D_A^-1/2 A D_A^-1/2
  // (its extreme Ritz value converges much faster than a power iteration, and from
  // below, hence the margin: Chebyshev smoothing amplifies modes above its interval).
  void estimate_lambda_max(std::size_t l) {
    Level& L = levels[l];
    const Eigen::Index n = L.n;
    const int steps = static_cast<int>(std::min<Eigen::Index>(8, n));
    // The vector work fused into two passes a step, in place: at 164k it was most of
    // the finest level's estimate (25 ms of it, against 8 applies of about 1.2 ms).
    const Eigen::VectorXd s = L.inv_diag.cwiseSqrt();
    Eigen::VectorXd v(n), v_prev = Eigen::VectorXd::Zero(n), w(n);
    Field x(n, 1), y;
    for (Eigen::Index i = 0; i < n; ++i) v[i] = std::sin(12.9898 * static_cast<double>(i) + 78.233) + 0.1;
    v /= v.norm();
    Eigen::VectorXd alpha(steps), beta(steps);
    int k = 0;
    for (; k < steps; ++k) {
      for (Eigen::Index i = 0; i < n; ++i) x(i, 0) = s[i] * v[i];
      apply(l, x, y);
      double a = 0;
      for (Eigen::Index i = 0; i < n; ++i) {
        w[i] = s[i] * y(i, 0);
        a += v[i] * w[i];
      }
      alpha[k] = a;
      const double b_prev = k > 0 ? beta[k - 1] : 0.0;
      double norm2 = 0;
      for (Eigen::Index i = 0; i < n; ++i) {
        w[i] -= a * v[i] + b_prev * v_prev[i];
        norm2 += w[i] * w[i];
      }
      beta[k] = std::sqrt(norm2);
      if (!(beta[k] > 1e-12 * std::abs(alpha[k]))) {
        ++k;
        break;
      }
      v_prev.swap(v);
      v.swap(w);
      v /= beta[k];
    }
    Eigen::MatrixXd T = Eigen::MatrixXd::Zero(k, k);
    for (int i = 0; i < k; ++i) {
      T(i, i) = alpha[i];
      if (i + 1 < k) T(i, i + 1) = T(i + 1, i) = beta[i];
    }
    L.lambda_max =
        1.1 * Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(T, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
  }

  // r = b - t, rows split over threads on large levels.
  static void difference(const Field& b, const Field& t, Field& r) {
    r.resize(b.rows(), b.cols());
    for_row_ranges(b.rows(), [&](Eigen::Index begin, Eigen::Index end, int) {
      r.middleRows(begin, end - begin) = b.middleRows(begin, end - begin) - t.middleRows(begin, end - begin);
    });
  }

  // Chebyshev smoothing of A x = b in D_A^-1 A on [lambda_max / range, lambda_max]
  // (Saad's three-term recurrence); from x = 0 when `zero_start`.
  void smooth(std::size_t l, const Field& b, Field& x, bool zero_start) const {
    const Level& L = levels[l];
    const double hi = L.lambda_max, lo = hi / params.smoothing_range;
    const double theta = (hi + lo) / 2, delta = (hi - lo) / 2, sigma = theta / delta;
    const int degree = l == 0 ? params.finest_smoothing_degree : params.smoothing_degree;
    const Eigen::Index n = b.rows(), m = b.cols();
    double rho = 1 / sigma;
    if (zero_start) {
      L.r = b;
      x.resize(n, m);
    } else {
      apply(l, x, L.t);
      difference(b, L.t, L.r);
    }
    L.d.resize(n, m);
    const double* dinv = L.inv_diag.data();
    double *D = L.d.data(), *X = x.data(), *R = L.r.data();
    const double inv_theta = 1 / theta;
    for_row_ranges(n, [&](Eigen::Index begin, Eigen::Index end, int) {
      for (Eigen::Index i = begin; i < end; ++i)
        for (Eigen::Index c = 0; c < m; ++c) {
          const Eigen::Index k = i * m + c;
          D[k] = dinv[i] * inv_theta * R[k];
          X[k] = zero_start ? D[k] : X[k] + D[k];
        }
    });
    for (int step = 2; step <= degree; ++step) {
      apply(l, L.d, L.t);
      const double rho_new = 1 / (2 * sigma - rho), a = rho_new * rho, g = 2 * rho_new / delta;
      const double* T = L.t.data();
      for_row_ranges(n, [&](Eigen::Index begin, Eigen::Index end, int) {
        for (Eigen::Index i = begin; i < end; ++i)
          for (Eigen::Index c = 0; c < m; ++c) {
            const Eigen::Index k = i * m + c;
            R[k] -= T[k];
            D[k] = a * D[k] + g * dinv[i] * R[k];
            X[k] += D[k];
          }
      });
      rho = rho_new;
    }
  }

  // Gauss-Seidel sweeps on A x = b in place, rows in order (forward) or reversed; from
  // x = 0 when `zero_start`.
  void gauss_seidel(std::size_t l, const Field& b, Field& x, bool forward, bool zero_start) const {
    const RowSparse& A = levels[l].A;
    const Eigen::Index n = b.rows(), m = b.cols();
    if (zero_start) x = Field::Zero(n, m);
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    const double* val = A.valuePtr();
    const double* dinv = levels[l].inv_diag.data();
    double* X = x.data();
    const double* B = b.data();
    std::vector<double> acc(static_cast<std::size_t>(m));
    for (int sweep = 0; sweep < params.smoothing_degree; ++sweep)
      for (Eigen::Index step = 0; step < n; ++step) {
        const Eigen::Index i = forward ? step : n - 1 - step;
        // acc: row i's residual with the current x_i; adding acc / A_ii to x_i zeroes it.
        for (Eigen::Index c = 0; c < m; ++c) acc[static_cast<std::size_t>(c)] = B[i * m + c];
        for (int k = outer[i]; k < outer[i + 1]; ++k) {
          const double v = val[k];
          const double* xr = X + static_cast<Eigen::Index>(inner[k]) * m;
          for (Eigen::Index c = 0; c < m; ++c) acc[static_cast<std::size_t>(c)] -= v * xr[c];
        }
        for (Eigen::Index c = 0; c < m; ++c) X[i * m + c] += dinv[i] * acc[static_cast<std::size_t>(c)];
      }
  }

  void pre_smooth(std::size_t l, const Field& b, Field& x) const {
    if (params.smoother == SurfaceMultigridParams::Smoother::GaussSeidel)
      gauss_seidel(l, b, x, true, true);
    else
      smooth(l, b, x, true);
  }
  void post_smooth(std::size_t l, const Field& b, Field& x) const {
    if (params.smoother == SurfaceMultigridParams::Smoother::GaussSeidel)
      gauss_seidel(l, b, x, false, false);
    else
      smooth(l, b, x, false);
  }

  void cycle(std::size_t l, const Field& b, Field& x) const {
    if (l + 1 == levels.size()) {
      const Eigen::MatrixXd rhs = b;
      x = coarse.solve(rhs);
      return;
    }
    const Level& L = levels[l];
    const Level& C = levels[l + 1];
    pre_smooth(l, b, x);
    apply(l, x, L.t);
    difference(b, L.t, L.r);
    spmm(L.Pt, L.r, C.b);
    cycle(l + 1, C.b, C.x);
    // W-cycle: more corrections of the coarse level (not of the coarsest, solved exactly).
    for (int k = 1; k < params.cycle_index && l + 2 < levels.size(); ++k) {
      apply(l + 1, C.x, C.t2);
      C.t2 = C.b - C.t2;
      cycle(l + 1, C.t2, C.e);
      C.x += C.e;
    }
    spmm(L.P, C.x, L.t);
    for_row_ranges(x.rows(), [&](Eigen::Index begin, Eigen::Index end, int) {
      x.middleRows(begin, end - begin) += L.t.middleRows(begin, end - begin);
    });
    post_smooth(l, b, x);
  }
};

BilaplacianMultigrid::BilaplacianMultigrid(const Mesh& mesh, const FemOperators& ops, std::span<const int> free,
                                           double g1, double g2, const SurfaceMultigridParams& params)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (!(g2 > 0) || !(g1 >= 0)) throw InputError("the bi-Laplacian multigrid needs g2 > 0 and g1 >= 0");
  if (params.smoothing_degree < 1 || !(params.smoothing_range > 1) || params.coarsest_unknowns < 0 ||
      params.max_levels < 1)
    throw InputError(
        "multigrid parameters: smoothing_degree >= 1, smoothing_range > 1, coarsest_unknowns >= 0, max_levels >= 1");
  m.params = params;
  if (m.params.coarsest_unknowns == 0) m.params.coarsest_unknowns = SurfaceMultigridParams::default_coarsest_unknowns();
  m.g1 = g1;
  m.g2 = g2;
  const int nv = mesh.num_vertices();
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  // Local numbering: the free vertices in the given order, then their one-ring.
  std::vector<int> local(static_cast<std::size_t>(nv), -1);
  Nodes nodes;
  m.nF = static_cast<int>(free.size());
  for (int k = 0; k < m.nF; ++k) {
    const int v = free[static_cast<std::size_t>(k)];
    if (v < 0 || v >= nv || local[static_cast<std::size_t>(v)] >= 0)
      throw InputError(fmt::format("free vertex {} is invalid or repeated", v));
    local[static_cast<std::size_t>(v)] = k;
    nodes.vertex.push_back(v);
  }
  for (int k = 0; k < m.nF; ++k)
    for (int q = off[nodes.vertex[static_cast<std::size_t>(k)]]; q < off[nodes.vertex[static_cast<std::size_t>(k)] + 1];
         ++q)
      if (local[static_cast<std::size_t>(nbr[q])] < 0) {
        local[static_cast<std::size_t>(nbr[q])] = nodes.size();
        nodes.vertex.push_back(nbr[q]);
      }
  m.nR = nodes.size();
  nodes.free_count = m.nF;
  nodes.unknown.resize(static_cast<std::size_t>(m.nR));
  for (int i = 0; i < m.nR; ++i) nodes.unknown[static_cast<std::size_t>(i)] = i < m.nF ? i : -1;
  // K on (free and ring) x free, and the level-0 graph (the mesh's edges among them).
  // With the free vertices in ascending order (the usual case) every row comes out
  // with its columns in order; otherwise rows are sorted.
  {
    const bool ascending = std::is_sorted(free.begin(), free.end());
    std::vector<int> k_off(static_cast<std::size_t>(m.nR) + 1, 0), k_col;
    std::vector<double> k_val;
    k_col.reserve(static_cast<std::size_t>(m.nR) * 7);
    k_val.reserve(static_cast<std::size_t>(m.nR) * 7);
    nodes.off.assign(1, 0);
    nodes.off.reserve(static_cast<std::size_t>(m.nR) + 1);
    nodes.adj.reserve(static_cast<std::size_t>(m.nR) * 6);
    std::vector<std::pair<int, double>> row;
    for (int i = 0; i < m.nR; ++i) {
      const int v = nodes.vertex[static_cast<std::size_t>(i)];
      const std::size_t first = k_col.size();
      bool diagonal = i >= m.nF;
      for (int q = off[v]; q < off[v + 1]; ++q) {
        const int j = local[static_cast<std::size_t>(nbr[q])];
        if (j < 0) continue;
        nodes.adj.push_back(j);
        if (j >= m.nF) continue;
        if (!diagonal && j > i) {
          k_col.push_back(i), k_val.push_back(ops.Kii[v]);
          diagonal = true;
        }
        k_col.push_back(j), k_val.push_back(ops.Kij[q]);
      }
      if (!diagonal) k_col.push_back(i), k_val.push_back(ops.Kii[v]);
      if (!ascending) {
        row.clear();
        for (std::size_t e = first; e < k_col.size(); ++e) row.emplace_back(k_col[e], k_val[e]);
        std::sort(row.begin(), row.end());
        for (std::size_t e = first; e < k_col.size(); ++e)
          k_col[e] = row[e - first].first, k_val[e] = row[e - first].second;
      }
      nodes.off.push_back(static_cast<int>(nodes.adj.size()));
      k_off[static_cast<std::size_t>(i) + 1] = static_cast<int>(k_col.size());
    }
    m.KRF = from_rows(m.nR, m.nF, k_off, k_col, k_val);
    m.KFR = m.KRF.transpose();
  }
  m.dR.resize(m.nR);
  for (int i = 0; i < m.nR; ++i) m.dR[i] = g2 * ops.D(nodes.vertex[static_cast<std::size_t>(i)]);

  // Finest level: diag(A)_i = g1 K_ii + g2 sum_j K_ij^2 D_j.
  m.levels.emplace_back();
  {
    Impl::Level& L0 = m.levels.back();
    L0.n = m.nF;
    L0.inv_diag.resize(m.nF);
    for (int i = 0; i < m.nF; ++i) {
      double a = 0;
      for (RowSparse::InnerIterator it(m.KFR, i); it; ++it) a += it.value() * it.value() * m.dR[it.col()];
      a += g1 * ops.Kii[nodes.vertex[static_cast<std::size_t>(i)]];
      L0.inv_diag[i] = a > 0 ? 1 / a : 0;
    }
    if (params.smoother == SurfaceMultigridParams::Smoother::GaussSeidel) L0.A = m.assemble_finest();
  }
  // Tangent planes: the least-squares plane of each vertex's one-ring (orientation
  // does not matter here, and it needs nothing beyond the ring), computed when needed.
  // Cached per node of the finest level (every coarse node is one), so memory follows
  // the free set, not the mesh.
  const Positions& X = mesh.positions();
  std::vector<Eigen::Vector3d> normals(static_cast<std::size_t>(m.nR));
  std::vector<char> has_normal(static_cast<std::size_t>(m.nR), 0);
  auto position = [&](int v) -> Eigen::Vector3d { return X.row(v).transpose(); };
  auto normal = [&](int v) -> Eigen::Vector3d {
    const auto at = static_cast<std::size_t>(local[static_cast<std::size_t>(v)]);
    if (!has_normal[at]) {
      Eigen::Vector3d mean = X.row(v).transpose();
      for (int q = off[v]; q < off[v + 1]; ++q) mean += X.row(nbr[q]).transpose();
      mean /= (off[v + 1] - off[v] + 1);
      Eigen::Matrix3d cov = (X.row(v).transpose() - mean) * (X.row(v).transpose() - mean).transpose();
      for (int q = off[v]; q < off[v + 1]; ++q) {
        const Eigen::Vector3d e = X.row(nbr[q]).transpose() - mean;
        cov += e * e.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
      es.computeDirect(cov);
      normals[at] = es.eigenvectors().col(0);
      has_normal[at] = 1;
    }
    return normals[at];
  };

  // Coarser levels until the coarsest is small enough for a direct solve.
  while (m.levels.back().n > m.params.coarsest_unknowns && static_cast<int>(m.levels.size()) < m.params.max_levels) {
    auto [coarse_nodes, P] = coarsen(nodes, position, normal);
    const int nc = coarse_nodes.free_count;
    if (nc == 0 || nc > 0.85 * m.levels.back().n) break;  // no longer coarsening
    const std::size_t l = m.levels.size() - 1;
    RowSparse Pt = P.transpose();
    RowSparse A;
    if (l == 0) {
      // A_1 = (K P)^T (g2 D) (K P) + g1 P^T K_FF P, the Galerkin product of the
      // finest operator without assembling it.
      RowSparse G = m.KRF * P;
      RowSparse g1_part;
      if (g1 > 0) g1_part = g1 * RowSparse(Pt * RowSparse(G.topRows(m.nF)));
      const RowSparse Gt = G.transpose();
      // (g2 D) G in place: one matrix of the finest level's size fewer to allocate.
      for (Eigen::Index i = 0; i < G.outerSize(); ++i)
        for (RowSparse::InnerIterator it(G, i); it; ++it) it.valueRef() *= m.dR[i];
      A = Gt * G;
      if (g1 > 0) A += g1_part;
    } else {
      A = Pt * (m.levels[l].A * P);
    }
    m.levels[l].P = std::move(P);
    m.levels[l].Pt = std::move(Pt);
    Impl::Level next;
    next.n = nc;
    next.A = std::move(A);
    next.A.makeCompressed();
    next.inv_diag = next.A.diagonal().cwiseInverse();
    m.levels.push_back(std::move(next));
    nodes = std::move(coarse_nodes);
  }
  if (m.nF == 0) return;  // nothing to solve: apply and precondition return empty blocks
  // The coarsest level by sparse Cholesky (the finest itself for a small problem).
  Eigen::SparseMatrix<double> Ac;
  if (m.levels.size() == 1) {
    Ac = m.levels[0].A.rows() > 0 ? m.levels[0].A : m.assemble_finest();
  } else {
    Ac = m.levels.back().A;
  }
  // A floating part makes the coarsest level singular; rounding may leave its zero
  // pivot tiny and positive instead of failing the factorization: relative test.
  std::string failure;
  try {
    m.coarse.factorize(Ac);
    if (!(m.coarse.pivot_ratio() > 1e-13))
      failure = fmt::format("smallest pivot {:.1e} of the largest", m.coarse.pivot_ratio());
  } catch (const SolverError& e) {
    failure = e.what();
  }
  if (!failure.empty())
    throw SolverError(fmt::format(
        "the bi-Laplacian on {} free vertices is not positive definite (its coarsest level of {} unknowns could not "
        "be factored: {}): is there a connected part of the free set with no held vertex?",
        m.nF, Ac.rows(), failure));
  if (params.smoother == SurfaceMultigridParams::Smoother::Chebyshev)
    for (std::size_t l = 0; l + 1 < m.levels.size(); ++l) m.estimate_lambda_max(l);
}

int SurfaceMultigridParams::default_coarsest_unknowns() {
  return SparseCholesky::cholmod_available() ? 12000 : 2000;
}

BilaplacianMultigrid::~BilaplacianMultigrid() = default;
BilaplacianMultigrid::BilaplacianMultigrid(BilaplacianMultigrid&&) noexcept = default;
BilaplacianMultigrid& BilaplacianMultigrid::operator=(BilaplacianMultigrid&&) noexcept = default;

int BilaplacianMultigrid::unknowns() const {
  return impl_->nF;
}

void BilaplacianMultigrid::apply(const Field& X, Field& Y) const {
  impl_->apply(0, X, Y);
}

void BilaplacianMultigrid::precondition(const Field& R, Field& Z) const {
  if (impl_->nF > 0)
    impl_->cycle(0, R, Z);
  else
    Z.resize(0, R.cols());
}

std::vector<int> BilaplacianMultigrid::level_unknowns() const {
  std::vector<int> n;
  for (const auto& L : impl_->levels) n.push_back(L.n);
  return n;
}

double BilaplacianMultigrid::bytes(int columns) const {
  const Impl& m = *impl_;
  auto sparse = [](const RowSparse& S) { return 12.0 * static_cast<double>(S.nonZeros()) + 4.0 * S.rows(); };
  double b = sparse(m.KRF) + sparse(m.KFR) + 8.0 * m.nR * (1 + 2 * columns);
  for (const auto& L : m.levels) b += sparse(L.A) + sparse(L.P) + sparse(L.Pt) + 8.0 * L.n * (1 + 5 * columns);
  b += 12.0 * m.coarse.factor_nonzeros();
  return b;
}

MultigridSolveResult BilaplacianMultigrid::solve(const Field& B, Field& X, double tolerance, int max_iterations,
                                                 const std::function<bool(int, double)>& keep_going) const {
  const Eigen::Index n = B.rows();
  if (n != impl_->nF) throw InputError(fmt::format("right-hand side has {} rows for {} unknowns", n, impl_->nF));
  CgOptions options;
  options.tolerance = tolerance;
  options.max_iterations = max_iterations;
  options.parallel_rows = kParallelRows;
  CgWorkspace w;
  const CgResult cg = block_pcg(
      [&](const Field& P, Field& Q) { apply(P, Q); }, [&](const Field& R, Field& Z) { precondition(R, Z); }, B, X,
      options, w, [&](int iterations, double residual) { return !keep_going || keep_going(iterations, residual); });
  if (cg.status == CgStatus::Breakdown) throw SolverError("bi-Laplacian multigrid: " + cg.message);
  MultigridSolveResult res;
  res.iterations = cg.iterations;
  res.relative_residual = cg.relative_residual;
  res.converged = cg.converged();
  return res;
}

}  // namespace meshpde
