#include "supernodal_sweeps.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <type_traits>
#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"

#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

namespace meshpde::detail {

namespace {

using Index = Eigen::Index;

// Factors with fewer nonzeros are swept on one thread: the second costs a fork and a
// join and the buffer, and the sweeps of a factor this small take well under 1 ms.
constexpr double kTwoThreadsFrom = 500000;

// Forward sweep y := L^-1 y over supernodes [k0, k1) for a row-major y with M columns.
// Updates of rows >= buffer_from go to `buffer` (rows counted from
// buffer_from) when it is given. Per supernode: the diagonal block's rows are
// contiguous in y and solved in place; the rows below it are summed into a dense
// scratch block column by column (contiguous in L) and scattered once. A supernode
// whose rows of y are all zero changes nothing and is skipped: for a right-hand side
// with few nonzeros (a unit load, a vertex's coupling) only the elimination tree's
// paths from them to the root are swept.
template <int M>
void forward(const SupernodalFactorView& L, Index k0, Index k1, double* y, Index buffer_from, double* buffer) {
  constexpr Index cols = M;
  std::vector<double> t;
  for (Index k = k0; k < k1; ++k) {
    const Index c0 = L.super[k], nc = L.super[k + 1] - c0, nr = L.pi[k + 1] - L.pi[k], below = nr - nc;
    const double* D = L.x + L.px[k];
    const int* rows = L.s + L.pi[k];
    double* yk = y + c0 * cols;
    if (std::all_of(yk, yk + nc * cols, [](double v) { return v == 0; })) continue;
    t.assign(static_cast<std::size_t>(below * cols), 0.0);
    for (Index j = 0; j < nc; ++j) {
      const double* col = D + j * nr;
      double* yj = yk + j * cols;
      const double d = 1 / col[j];
      for (Index c = 0; c < cols; ++c) yj[c] *= d;
      for (Index i = j + 1; i < nc; ++i)
        for (Index c = 0; c < cols; ++c) yk[i * cols + c] -= col[i] * yj[c];
      for (Index i = 0; i < below; ++i)
        for (Index c = 0; c < cols; ++c) t[static_cast<std::size_t>(i * cols + c)] += col[nc + i] * yj[c];
    }
    for (Index i = 0; i < below; ++i) {
      const Index row = rows[nc + i];
      double* target = buffer && row >= buffer_from ? buffer + (row - buffer_from) * cols : y + row * cols;
      for (Index c = 0; c < cols; ++c) target[c] -= t[static_cast<std::size_t>(i * cols + c)];
    }
  }
}

// Backward sweep y := L^-T y over supernodes [k0, k1), last first: the rows below the
// diagonal block gathered once into a dense scratch block.
template <int M>
void backward(const SupernodalFactorView& L, Index k0, Index k1, double* y) {
  constexpr Index cols = M;
  std::vector<double> g;
  std::array<double, M> acc;
  for (Index k = k1; k-- > k0;) {
    const Index c0 = L.super[k], nc = L.super[k + 1] - c0, nr = L.pi[k + 1] - L.pi[k], below = nr - nc;
    const double* D = L.x + L.px[k];
    const int* rows = L.s + L.pi[k];
    double* yk = y + c0 * cols;
    g.resize(static_cast<std::size_t>(below * cols));
    for (Index i = 0; i < below; ++i)
      for (Index c = 0; c < cols; ++c) g[static_cast<std::size_t>(i * cols + c)] = y[rows[nc + i] * cols + c];
    for (Index j = nc; j-- > 0;) {
      const double* col = D + j * nr;
      acc.fill(0.0);
      for (Index i = j + 1; i < nc; ++i)
        for (Index c = 0; c < cols; ++c) acc[static_cast<std::size_t>(c)] += col[i] * yk[i * cols + c];
      for (Index i = 0; i < below; ++i)
        for (Index c = 0; c < cols; ++c)
          acc[static_cast<std::size_t>(c)] += col[nc + i] * g[static_cast<std::size_t>(i * cols + c)];
      double* yj = yk + j * cols;
      const double d = 1 / col[j];
      for (Index c = 0; c < cols; ++c) yj[c] = (yj[c] - acc[static_cast<std::size_t>(c)]) * d;
    }
  }
}

template <int M>
void sweep_both(const SupernodalFactorView& L, Index g0, Index split, Index g1, bool two_threads, double* y) {
  const Index ns = L.nsuper;
  if (g0 == g1) {  // no split: one thread, no buffers
    forward<M>(L, 0, ns, y, 0, nullptr);
    backward<M>(L, 0, ns, y);
    return;
  }
  // Forward: the supernodes before the groups, then the groups (their updates of the
  // ancestors' rows, from `from` on, into one buffer each), the buffers added in
  // order, then the rest.
  forward<M>(L, 0, g0, y, 0, nullptr);
  const Index from = L.super[g1];
  const auto tail = static_cast<std::size_t>((L.n - from) * M);
  std::vector<double> buffer[2] = {std::vector<double>(tail, 0.0), std::vector<double>(tail, 0.0)};
  auto group_forward = [&](int t) {
    forward<M>(L, t == 0 ? g0 : split, t == 0 ? split : g1, y, from, buffer[t].data());
  };
  auto group_backward = [&](int t) { backward<M>(L, t == 0 ? g0 : split, t == 0 ? split : g1, y); };
  // The two groups on two threads (each on its own rows and buffer), or one after the
  // other: the same arithmetic either way.
  auto both = [&](auto&& f) {
#ifdef MESHPDE_HAVE_OPENMP
    if (two_threads) {
      std::exception_ptr error[2];
#pragma omp parallel for schedule(static, 1) num_threads(2)
      for (int t = 0; t < 2; ++t) {
        try {
          f(t);
        } catch (...) {  // an exception must not leave an OpenMP region
          error[t] = std::current_exception();
        }
      }
      for (const auto& e : error)
        if (e) std::rethrow_exception(e);
      return;
    }
#endif
    (void)two_threads;
    f(0);
    f(1);
  };
  both(group_forward);
  double* t = y + from * M;
  for (int g = 0; g < 2; ++g)
    for (std::size_t i = 0; i < tail; ++i) t[i] += buffer[g][i];
  forward<M>(L, g1, ns, y, 0, nullptr);
  // Backward: the rest first (the groups' ancestors), then the groups, then the
  // supernodes before them.
  backward<M>(L, g1, ns, y);
  both(group_backward);
  backward<M>(L, 0, g0, y);
}

}  // namespace

SupernodalSweeps::SupernodalSweeps(const SupernodalFactorView& L) : L_(L) {
  const Index ns = L.nsuper;
  // Parent of each supernode: the supernode of its first row below the diagonal block.
  std::vector<Index> column_owner(static_cast<std::size_t>(L.n));
  for (Index k = 0; k < ns; ++k)
    for (Index c = L.super[k]; c < L.super[k + 1]; ++c) column_owner[static_cast<std::size_t>(c)] = k;
  std::vector<Index> parent(static_cast<std::size_t>(ns), -1), first(static_cast<std::size_t>(ns));
  std::vector<double> work(static_cast<std::size_t>(ns), 0.0);
  std::vector<std::vector<Index>> children(static_cast<std::size_t>(ns) + 1);  // [ns]: the roots
  for (Index k = 0; k < ns; ++k) {
    const Index nc = L.super[k + 1] - L.super[k], nr = L.pi[k + 1] - L.pi[k];
    if (nr > nc) parent[static_cast<std::size_t>(k)] = column_owner[static_cast<std::size_t>(L.s[L.pi[k] + nc])];
    work[static_cast<std::size_t>(k)] += static_cast<double>(nr) * static_cast<double>(nc);
    work_ += static_cast<double>(nr) * static_cast<double>(nc);
    first[static_cast<std::size_t>(k)] = k;
  }
  for (Index k = 0; k < ns; ++k) {
    const Index p = parent[static_cast<std::size_t>(k)];
    if (p >= 0 && p <= k) return;  // not postordered (a parent before its child): no split
    children[static_cast<std::size_t>(p >= 0 ? p : ns)].push_back(k);
    if (p >= 0) {
      work[static_cast<std::size_t>(p)] += work[static_cast<std::size_t>(k)];
      first[static_cast<std::size_t>(p)] =
          std::min(first[static_cast<std::size_t>(p)], first[static_cast<std::size_t>(k)]);
    }
  }
  // Down the root chain to the first node with two or more children.
  Index node = ns;  // the virtual root above the roots
  while (children[static_cast<std::size_t>(node)].size() == 1) node = children[static_cast<std::size_t>(node)][0];
  const std::vector<Index>& kids = children[static_cast<std::size_t>(node)];
  if (kids.size() < 2) return;
  // The children's subtrees must tile [first(kids[0]), kids.back()] in order.
  for (std::size_t i = 1; i < kids.size(); ++i)
    if (first[static_cast<std::size_t>(kids[i])] != kids[i - 1] + 1) return;
  double total = 0;
  for (Index c : kids) total += work[static_cast<std::size_t>(c)];
  double prefix = 0, best = total;
  std::size_t cut = 1;
  for (std::size_t i = 0; i + 1 < kids.size(); ++i) {
    prefix += work[static_cast<std::size_t>(kids[i])];
    if (std::abs(total - 2 * prefix) < best) best = std::abs(total - 2 * prefix), cut = i + 1;
  }
  group_begin_ = first[static_cast<std::size_t>(kids[0])];
  split_ = kids[cut - 1] + 1;
  group_end_ = kids.back() + 1;
}

Eigen::MatrixXd SupernodalSweeps::solve(const Eigen::MatrixXd& B) const {
  const Index n = L_.n, m = B.cols();
  if (m < 1 || m > 4) throw SolverError(fmt::format("triangular sweeps: {} columns (one to four)", m));
  // Row-major and permuted: row i of y is row perm[i] of B.
  std::vector<double> y(static_cast<std::size_t>(n * m));
  for (Index i = 0; i < n; ++i)
    for (Index c = 0; c < m; ++c) y[static_cast<std::size_t>(i * m + c)] = B(L_.perm[i], c);
  const bool two_threads = work_ >= kTwoThreadsFrom && max_threads() > 1;
  auto run = [&](auto columns) {
    sweep_both<decltype(columns)::value>(L_, group_begin_, split_, group_end_, two_threads, y.data());
  };
  switch (m) {
    case 1:
      run(std::integral_constant<int, 1>{});
      break;
    case 2:
      run(std::integral_constant<int, 2>{});
      break;
    case 3:
      run(std::integral_constant<int, 3>{});
      break;
    default:
      run(std::integral_constant<int, 4>{});
  }
  Eigen::MatrixXd X(n, m);
  for (Index i = 0; i < n; ++i)
    for (Index c = 0; c < m; ++c) X(L_.perm[i], c) = y[static_cast<std::size_t>(i * m + c)];
  return X;
}

}  // namespace meshpde::detail
