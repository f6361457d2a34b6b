#include "meshpde/solvers/multigrid.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/solvers/direct.h"

namespace meshpde {

using RowMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

struct AlgebraicMultigrid::Level {
  RowMatrix A;               // this level's matrix
  Eigen::VectorXd inv_diag;  // D^-1
  double lambda_max = 2;     // upper estimate of the largest eigenvalue of D^-1 A
  RowMatrix P;               // prolongation to this level from the next coarser one
  RowMatrix R;               // restriction P^T
};

struct AlgebraicMultigrid::Coarse {
  SparseCholesky chol;
};

namespace {

// Largest eigenvalue of D^-1 A: a few power iterations (from a fixed, non-smooth start,
// so runs repeat exactly), 10 % added because power iteration approaches from below,
// capped by Gershgorin's bound, which is always above it.
double estimate_lambda_max(const RowMatrix& A, const Eigen::VectorXd& inv_diag) {
  const Eigen::Index n = A.rows();
  double gershgorin = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    double s = 0;
    for (RowMatrix::InnerIterator it(A, i); it; ++it) s += std::abs(it.value());
    gershgorin = std::max(gershgorin, s * inv_diag[i]);
  }
  Eigen::VectorXd x(n);
  for (Eigen::Index i = 0; i < n; ++i) x[i] = 1.0 + 0.5 * std::sin(1.7 * static_cast<double>(i));
  double lambda = 0;
  for (int it = 0; it < 12; ++it) {
    const Eigen::VectorXd y = inv_diag.cwiseProduct(A * x);
    lambda = y.norm() / x.norm();
    x = y / y.norm();
  }
  return std::min(1.1 * lambda, gershgorin);
}

// Aggregates of strongly connected unknowns (Vanek et al., three passes). Returns the
// aggregate of every unknown and the number of aggregates.
std::vector<int> aggregate(const RowMatrix& A, double theta, int& count) {
  const auto n = static_cast<int>(A.rows());
  const Eigen::VectorXd d = A.diagonal();
  auto strong = [&](int i, int j, double a) {
    return i != j && std::abs(a) >= theta * std::sqrt(std::abs(d[i] * d[j]));
  };
  std::vector<int> agg(static_cast<std::size_t>(n), -1);
  count = 0;
  // Pass 1: an unknown whose strong neighbours are all free becomes a root; it and
  // they form an aggregate.
  for (int i = 0; i < n; ++i) {
    if (agg[static_cast<std::size_t>(i)] >= 0) continue;
    bool free_neighbourhood = true;
    for (RowMatrix::InnerIterator it(A, i); it && free_neighbourhood; ++it)
      if (strong(i, static_cast<int>(it.col()), it.value()) && agg[static_cast<std::size_t>(it.col())] >= 0)
        free_neighbourhood = false;
    if (!free_neighbourhood) continue;
    agg[static_cast<std::size_t>(i)] = count;
    for (RowMatrix::InnerIterator it(A, i); it; ++it)
      if (strong(i, static_cast<int>(it.col()), it.value())) agg[static_cast<std::size_t>(it.col())] = count;
    ++count;
  }
  // Pass 2: the rest join the aggregate they are most strongly connected to.
  std::vector<int> joined = agg;
  for (int i = 0; i < n; ++i) {
    if (agg[static_cast<std::size_t>(i)] >= 0) continue;
    double best = 0;
    for (RowMatrix::InnerIterator it(A, i); it; ++it) {
      const int j = static_cast<int>(it.col());
      if (strong(i, j, it.value()) && agg[static_cast<std::size_t>(j)] >= 0 && std::abs(it.value()) > best) {
        best = std::abs(it.value());
        joined[static_cast<std::size_t>(i)] = agg[static_cast<std::size_t>(j)];
      }
    }
  }
  agg = std::move(joined);
  // Pass 3: unknowns with no aggregated strong neighbour (isolated, or only weakly
  // connected) form aggregates with their unaggregated strong neighbours.
  for (int i = 0; i < n; ++i) {
    if (agg[static_cast<std::size_t>(i)] >= 0) continue;
    agg[static_cast<std::size_t>(i)] = count;
    for (RowMatrix::InnerIterator it(A, i); it; ++it)
      if (strong(i, static_cast<int>(it.col()), it.value()) && agg[static_cast<std::size_t>(it.col())] < 0)
        agg[static_cast<std::size_t>(it.col())] = count;
    ++count;
  }
  return agg;
}

// Chebyshev smoothing of A x = b from x, with the polynomial in D^-1 A that is smallest
// on [lambda_max / ratio, lambda_max] (the oscillatory part the coarse levels cannot
// see): `degree` products with A.
void chebyshev(const RowMatrix& A, const Eigen::VectorXd& inv_diag, double lambda_max, double ratio, int degree,
               const Eigen::MatrixXd& b, Eigen::MatrixXd& x, bool zero_start) {
  const double upper = lambda_max, lower = lambda_max / ratio;
  const double theta = 0.5 * (upper + lower), delta = 0.5 * (upper - lower);
  const double sigma = theta / delta;
  double rho = 1 / sigma;
  Eigen::MatrixXd r = zero_start ? b : Eigen::MatrixXd(b - A * x);
  Eigen::MatrixXd dir = inv_diag.asDiagonal() * r / theta;
  for (int k = 1; k <= degree; ++k) {
    if (zero_start && k == 1)
      x = dir;
    else
      x += dir;
    if (k == degree) break;
    r.noalias() -= A * dir;
    const double rho_new = 1 / (2 * sigma - rho);
    dir = (rho_new * rho) * dir + (2 * rho_new / delta) * (inv_diag.asDiagonal() * r);
    rho = rho_new;
  }
}

}  // namespace

AlgebraicMultigrid::AlgebraicMultigrid(const Eigen::SparseMatrix<double>& A_in, const MultigridOptions& options)
    : coarse_(std::make_unique<Coarse>()), options_(options) {
  if (A_in.rows() != A_in.cols())
    throw SolverError(fmt::format("multigrid: the matrix is {} x {}, not square", A_in.rows(), A_in.cols()));
  RowMatrix A = A_in;
  A.makeCompressed();
  for (int depth = 0;; ++depth) {
    Level L;
    L.A = std::move(A);
    const Eigen::VectorXd d = L.A.diagonal();
    for (Eigen::Index i = 0; i < d.size(); ++i)
      if (!(d[i] > 0))
        throw SolverError(
            fmt::format("multigrid: diagonal entry {} of level {} is {} (not positive definite)", i, depth, d[i]));
    L.inv_diag = d.cwiseInverse();
    const Eigen::Index n = L.A.rows();
    if (n <= options.coarse_size || depth + 1 >= options.max_levels) {
      coarse_->chol.factorize(Eigen::SparseMatrix<double>(L.A));
      levels_.push_back(std::move(L));
      break;
    }
    L.lambda_max = estimate_lambda_max(L.A, L.inv_diag);
    int count = 0;
    const std::vector<int> agg = aggregate(L.A, options.strength_threshold, count);
    if (count >= n) {  // nothing aggregated (no strong connections): stop coarsening here
      coarse_->chol.factorize(Eigen::SparseMatrix<double>(L.A));
      levels_.push_back(std::move(L));
      break;
    }
    // Tentative prolongator: 1 / sqrt(aggregate size) on each aggregate (orthonormal
    // columns spanning the piecewise constants), smoothed: P = (I - w D^-1 A) T with
    // w = 4 / (3 lambda_max(D^-1 A)), the usual choice for smoothed aggregation.
    std::vector<int> size(static_cast<std::size_t>(count), 0);
    for (int a : agg) ++size[static_cast<std::size_t>(a)];
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) {
      const int a = agg[static_cast<std::size_t>(i)];
      t.emplace_back(static_cast<int>(i), a, 1.0 / std::sqrt(static_cast<double>(size[static_cast<std::size_t>(a)])));
    }
    RowMatrix T(n, count);
    T.setFromTriplets(t.begin(), t.end());
    const RowMatrix DA = ((4.0 / (3.0 * L.lambda_max)) * L.inv_diag).asDiagonal() * L.A;
    const RowMatrix DAT = DA * T;
    RowMatrix P = T - DAT;
    P.prune(0.0);
    RowMatrix R = P.transpose();
    RowMatrix AP = L.A * P;
    A = R * AP;
    A.prune(0.0);
    L.P = std::move(P);
    L.R = std::move(R);
    levels_.push_back(std::move(L));
  }
}

AlgebraicMultigrid::~AlgebraicMultigrid() = default;
AlgebraicMultigrid::AlgebraicMultigrid(AlgebraicMultigrid&&) noexcept = default;
AlgebraicMultigrid& AlgebraicMultigrid::operator=(AlgebraicMultigrid&&) noexcept = default;

Eigen::MatrixXd AlgebraicMultigrid::cycle(std::size_t l, const Eigen::MatrixXd& b) const {
  const Level& L = levels_[l];
  if (l + 1 == levels_.size()) return coarse_->chol.solve(b);
  Eigen::MatrixXd x;
  chebyshev(L.A, L.inv_diag, L.lambda_max, options_.smoother_ratio, options_.smoother_degree, b, x, true);
  const Eigen::MatrixXd r = b - L.A * x;
  x.noalias() += L.P * cycle(l + 1, L.R * r);
  chebyshev(L.A, L.inv_diag, L.lambda_max, options_.smoother_ratio, options_.smoother_degree, b, x, false);
  return x;
}

Eigen::MatrixXd AlgebraicMultigrid::apply(const Eigen::MatrixXd& R) const {
  if (R.rows() != levels_.front().A.rows())
    throw SolverError(fmt::format("multigrid: {} rows for a {}-unknown system", R.rows(), levels_.front().A.rows()));
  // Eigen splits the rows of row-major sparse products over its (OpenMP) threads.
  Eigen::setNbThreads(max_threads());
  return cycle(0, R);
}

int AlgebraicMultigrid::levels() const {
  return static_cast<int>(levels_.size());
}

std::vector<Eigen::Index> AlgebraicMultigrid::level_sizes() const {
  std::vector<Eigen::Index> s;
  for (const Level& L : levels_) s.push_back(L.A.rows());
  return s;
}

double AlgebraicMultigrid::operator_complexity() const {
  double total = 0;
  for (const Level& L : levels_) total += static_cast<double>(L.A.nonZeros());
  return total / static_cast<double>(levels_.front().A.nonZeros());
}

std::size_t AlgebraicMultigrid::bytes() const {
  std::size_t b = 0;
  auto matrix = [](const RowMatrix& M) {
    return static_cast<std::size_t>(M.nonZeros()) * (sizeof(double) + sizeof(int)) +
           static_cast<std::size_t>(M.outerSize() + 1) * sizeof(int);
  };
  for (const Level& L : levels_)
    b += matrix(L.A) + matrix(L.P) + matrix(L.R) + static_cast<std::size_t>(L.inv_diag.size()) * sizeof(double);
  return b;
}

}  // namespace meshpde
