// The direct solvers' front: backend choice, checks and errors, and the two backends'
// calls. CHOLMOD itself is behind cholmod_factors.h (cholmod_factors.cpp, or
// cholmod_missing.cpp in a build without it); Eigen's factors are used here directly.
#include "meshpde/solvers/direct.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>

#include "cholmod_factors.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "solver_threads.h"

namespace meshpde {

using detail::CholmodFactor;
using detail::CholmodInOrder;
using detail::kSimplicialBelow;

namespace {

// A compressed copy only when needed, and a check that A is square and every entry
// finite.
const Eigen::SparseMatrix<double>& checked(const Eigen::SparseMatrix<double>& A, Eigen::SparseMatrix<double>& copy) {
  if (A.rows() != A.cols())
    throw SolverError(fmt::format("direct solve: the matrix is {} x {}, not square", A.rows(), A.cols()));
  const Eigen::SparseMatrix<double>* out = &A;
  if (!A.isCompressed()) {
    copy = A;
    copy.makeCompressed();
    out = &copy;
  }
  for (Eigen::Index k = 0; k < out->nonZeros(); ++k)
    if (!std::isfinite(out->valuePtr()[k])) throw SolverError("direct solve: the matrix has a NaN or infinite entry");
  return *out;
}

SolverError not_positive_definite(const char* backend) {
  return SolverError(
      fmt::format("direct solve ({}): the matrix is not positive definite (a part of the mesh "
                  "without constraints, or a negative coefficient?)",
                  backend));
}

}  // namespace

struct SparseCholesky::Impl {
  Backend requested = Backend::Auto;
  Backend backend = Backend::Eigen;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> eigen;
  std::unique_ptr<CholmodFactor> cholmod;  // made on the first CHOLMOD factorization
  Sweeps sweep_mode = Sweeps::WrittenOut;
  Eigen::SparseMatrix<double> pattern;   // structure of the analyzed matrix (values unused)
  std::vector<int> order;                // the given fill-reducing order, or empty
  Eigen::Index parts[2] = {0, 0};        // its top level's parts, when split
  std::unique_ptr<SplitCholesky> split;  // the factor of A in that order, when split
  bool coarse_supernodes = true;         // for the given order
  bool analyzed = false;
  bool factored = false;
};

bool SparseCholesky::cholmod_available() {
  return detail::cholmod_built();
}

SparseCholesky::SparseCholesky(Backend backend) : impl_(std::make_unique<Impl>()) {
  if (backend == Backend::Cholmod && !cholmod_available())
    throw SolverError("CHOLMOD was requested but meshpde was built without it (install libsuitesparse-dev)");
  impl_->requested = backend;
  impl_->backend = backend == Backend::Auto ? (cholmod_available() ? Backend::Cholmod : Backend::Eigen) : backend;
}

SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

void SparseCholesky::set_sweeps(Sweeps sweeps) {
  impl_->sweep_mode = sweeps;
}

void SparseCholesky::set_order(std::vector<int> order, std::size_t part1, std::size_t part2, bool coarse_supernodes) {
  Impl& d = *impl_;
  if (order == d.order && static_cast<Eigen::Index>(part1) == d.parts[0] &&
      static_cast<Eigen::Index>(part2) == d.parts[1] && coarse_supernodes == d.coarse_supernodes)
    return;
  std::vector<char> seen(order.size(), 0);
  for (int k : order) {
    const bool in_range = k >= 0 && static_cast<std::size_t>(k) < order.size();
    if (!in_range || seen[static_cast<std::size_t>(k)])
      throw SolverError(fmt::format("direct solve: the given order is not a permutation of 0..{} (row {} {})",
                                    order.size() - 1, k, in_range ? "appears twice" : "is out of range"));
    seen[static_cast<std::size_t>(k)] = 1;
  }
  if ((part1 > 0) != (part2 > 0) || (part1 > 0 && part1 + part2 >= order.size()))
    throw SolverError(fmt::format("direct solve: parts of {} and {} rows leave no separator in an order of {}", part1,
                                  part2, order.size()));
  d.order = std::move(order);
  d.parts[0] = static_cast<Eigen::Index>(part1);
  d.parts[1] = static_cast<Eigen::Index>(part2);
  d.coarse_supernodes = coarse_supernodes;
  d.analyzed = false;  // the next factorize() analyzes afresh
}

const char* SparseCholesky::backend_name() const {
  return impl_->backend == Backend::Cholmod ? "cholmod-supernodal" : "eigen-simplicial-ldlt";
}

namespace {

bool same_pattern(const Eigen::SparseMatrix<double>& a, const Eigen::SparseMatrix<double>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  for (Eigen::Index k = 0; k <= a.outerSize(); ++k)
    if (a.outerIndexPtr()[k] != b.outerIndexPtr()[k]) return false;
  return std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

}  // namespace

void SparseCholesky::factorize(const Eigen::SparseMatrix<double>& A_in) {
  Eigen::SparseMatrix<double> copy;
  const Eigen::SparseMatrix<double>& A = checked(A_in, copy);
  Impl& d = *impl_;
  d.factored = false;
  if (d.requested == Backend::Auto)
    d.backend = cholmod_available() && A.rows() >= kSimplicialBelow ? Backend::Cholmod : Backend::Eigen;
  const bool new_pattern = !d.analyzed || !same_pattern(A, d.pattern);
  Eigen::ComputationInfo info = Eigen::Success;
  const bool split = d.backend == Backend::Cholmod && d.parts[0] > 0;
  if (split) {
    // A in the given order, factored as two parts on two threads and their separator
    // (SplitCholesky). Its analyses are made with each factorization.
    if (d.order.size() != static_cast<std::size_t>(A.rows()))
      throw SolverError(
          fmt::format("direct solve: the given order has {} rows, the matrix {}", d.order.size(), A.rows()));
    if (!d.split) d.split = std::make_unique<SplitCholesky>();
    ++analyses_;
    d.split->factorize(A, d.order, d.parts[0], d.parts[1]);
  }
  if (d.backend == Backend::Cholmod && !split) {
    // The CHOLMOD factor is made on first use (a build without CHOLMOD never gets
    // here: the backend is then Eigen's); a fresh one has no analysis yet.
    const bool fresh = !d.cholmod;
    if (fresh) d.cholmod = std::make_unique<CholmodFactor>();
    if (new_pattern || fresh) {
      if (!d.order.empty() && d.order.size() != static_cast<std::size_t>(A.rows()))
        throw SolverError(
            fmt::format("direct solve: the given order has {} rows, the matrix {}", d.order.size(), A.rows()));
      d.cholmod->analyze(A, d.order.empty() ? nullptr : &d.order, d.coarse_supernodes);
      ++analyses_;
    }
    if (!d.cholmod->factorize(A)) info = Eigen::NumericalIssue;
  }
  if (d.backend == Backend::Eigen) {
    if (new_pattern) {
      d.eigen.analyzePattern(A);
      ++analyses_;
    }
    d.eigen.factorize(A);
    info = d.eigen.info();
    // LDL^T succeeds on indefinite matrices: check the pivots.
    if (info == Eigen::Success && (d.eigen.vectorD().array() <= 0).any()) info = Eigen::NumericalIssue;
  }
  if (new_pattern) {
    d.pattern = A;
    d.analyzed = true;
  }
  ++factors_;
  if (info != Eigen::Success) throw not_positive_definite(backend_name());
  d.factored = true;
}

std::vector<int> SparseCholesky::order() const {
  const Impl& d = *impl_;
  if (!d.factored || d.backend != Backend::Cholmod) return {};
  if (d.parts[0] > 0) return d.order;
  return d.cholmod->order();
}

std::array<std::size_t, 2> SparseCholesky::split_parts() const {
  const Impl& d = *impl_;
  if (!d.factored || d.backend != Backend::Cholmod || d.parts[0] == 0) return {0, 0};
  return {static_cast<std::size_t>(d.parts[0]), static_cast<std::size_t>(d.parts[1])};
}

double SparseCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  if (d.backend == Backend::Cholmod && d.parts[0] > 0) return d.split->factor_nonzeros();
  if (d.backend == Backend::Cholmod) return d.cholmod->nonzeros();
  return static_cast<double>(d.eigen.matrixL().nestedExpression().nonZeros());
}

double SparseCholesky::pivot_ratio() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  if (d.backend == Backend::Cholmod && d.parts[0] > 0) return 0;  // not computed for a split factor
  if (d.backend == Backend::Cholmod) return d.cholmod->pivot_ratio();
  const auto D = d.eigen.vectorD();
  if (D.size() == 0) return 0;
  const double hi = D.maxCoeff();
  return hi > 0 ? D.minCoeff() / hi : 0;
}

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& B) const {
  const Impl& d = *impl_;
  if (!d.factored) throw SolverError("direct solve: solve() before a successful factorize()");
  if (B.rows() != d.pattern.rows())
    throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", B.rows(), d.pattern.rows()));
  if (d.backend == Backend::Cholmod && d.parts[0] > 0) {
    Eigen::MatrixXd ordered(B.rows(), B.cols());
    for (std::size_t k = 0; k < d.order.size(); ++k) ordered.row(static_cast<Eigen::Index>(k)) = B.row(d.order[k]);
    const Eigen::MatrixXd x = d.split->solve(ordered);
    Eigen::MatrixXd out(B.rows(), B.cols());
    for (std::size_t k = 0; k < d.order.size(); ++k) out.row(d.order[k]) = x.row(static_cast<Eigen::Index>(k));
    return out;
  }
  if (d.backend == Backend::Cholmod) return d.cholmod->solve(B, d.sweep_mode == Sweeps::WrittenOut);
  return d.eigen.solve(B);
}

struct LeadingBlockCholesky::Impl {
  SparseCholesky::Backend requested = SparseCholesky::Backend::Auto;
  SparseCholesky::Backend backend = SparseCholesky::Backend::Eigen;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> eigen;
  bool factored = false;
  std::unique_ptr<CholmodInOrder> cholmod;  // made on the first CHOLMOD factorization
};

LeadingBlockCholesky::LeadingBlockCholesky(SparseCholesky::Backend backend) : impl_(std::make_unique<Impl>()) {
  if (backend == SparseCholesky::Backend::Cholmod && !SparseCholesky::cholmod_available())
    throw SolverError("CHOLMOD was requested but meshpde was built without it (install libsuitesparse-dev)");
  impl_->requested = backend;
  impl_->backend = backend == SparseCholesky::Backend::Eigen || !SparseCholesky::cholmod_available()
                       ? SparseCholesky::Backend::Eigen
                       : SparseCholesky::Backend::Cholmod;
}

LeadingBlockCholesky::~LeadingBlockCholesky() = default;
LeadingBlockCholesky::LeadingBlockCholesky(LeadingBlockCholesky&&) noexcept = default;
LeadingBlockCholesky& LeadingBlockCholesky::operator=(LeadingBlockCholesky&&) noexcept = default;

const char* LeadingBlockCholesky::backend_name() const {
  return impl_->backend == SparseCholesky::Backend::Cholmod ? "cholmod-supernodal" : "eigen-simplicial-llt";
}

void LeadingBlockCholesky::factorize(const Eigen::SparseMatrix<double>& A_in) {
  Impl& d = *impl_;
  d.factored = false;
  size_ = 0;
  Eigen::SparseMatrix<double> copy;
  const Eigen::SparseMatrix<double>& A = checked(A_in, copy);
  if (d.requested == SparseCholesky::Backend::Auto)  // the size rule of SparseCholesky
    d.backend = SparseCholesky::cholmod_available() && A.rows() >= kSimplicialBelow ? SparseCholesky::Backend::Cholmod
                                                                                    : SparseCholesky::Backend::Eigen;
  bool ok = true;
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    if (!d.cholmod) d.cholmod = std::make_unique<CholmodInOrder>();
    detail::set_blas_threads(detail::blas_threads_for(A.rows()));
    const detail::OpenMpActiveLevels serial(0);
    ok = d.cholmod->factorize(A);
  }
  if (d.backend == SparseCholesky::Backend::Eigen) {
    d.eigen.compute(A);
    ok = d.eigen.info() == Eigen::Success;
  }
  if (!ok) throw not_positive_definite(backend_name());
  size_ = A.rows();
  d.factored = true;
}

double LeadingBlockCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  if (d.backend == SparseCholesky::Backend::Cholmod) return d.cholmod->nonzeros();
  return static_cast<double>(d.eigen.matrixL().nestedExpression().nonZeros());
}

Eigen::MatrixXd LeadingBlockCholesky::solve_leading(const Eigen::MatrixXd& B) const {
  Impl& d = *impl_;  // CHOLMOD's workspace changes in a solve, the factor does not
  if (!d.factored) throw SolverError("direct solve: solve_leading() before a successful factorize()");
  const Eigen::Index n = B.rows();
  if (n > size_) throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", n, size_));
  // L = [L_aa 0; L_ba L_bb]: forward with [B; 0] gives L_aa^-1 B on top; with the rest
  // zeroed, the backward sweep gives L_aa^-T on top and zeros below.
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(size_, B.cols());
  Y.topRows(n) = B;
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    detail::set_blas_threads(1);  // as SparseCholesky::solve(): a second BLAS thread slows the sweeps
    const detail::OpenMpActiveLevels serial(0);
    d.cholmod->forward(Y);
    Y.bottomRows(size_ - n).setZero();
    d.cholmod->backward(Y);
    return Y.topRows(n);
  }
  d.eigen.matrixL().solveInPlace(Y);
  Y.bottomRows(size_ - n).setZero();
  d.eigen.matrixU().solveInPlace(Y);
  return Y.topRows(n);
}

struct SplitCholesky::Impl {
  std::unique_ptr<CholmodInOrder> part[2];  // made on the first factorization
  Eigen::Index n1 = 0, n2 = 0, s = 0;
  Eigen::MatrixXd C[2];               // trailing blocks of the parts' factors (lower)
  Eigen::LLT<Eigen::MatrixXd> schur;  // of C1 C1^T + C2 C2^T - ASS
  bool factored = false;
};

SplitCholesky::SplitCholesky() : impl_(std::make_unique<Impl>()) {}
SplitCholesky::~SplitCholesky() = default;
SplitCholesky::SplitCholesky(SplitCholesky&&) noexcept = default;
SplitCholesky& SplitCholesky::operator=(SplitCholesky&&) noexcept = default;

namespace {

// Part k's matrix of the split factor, lower triangle only, in the elimination order:
// the part's rows, then the separator's. A is read in its own numbering (its lower
// triangle), `position[i]` is row i's place in the order (parts [0, n1) and [n1, n1 +
// n2), the separator after them). Built without a permuted copy of all of A: the
// entries are counted into their columns, then each column's few rows sorted. Part 0
// also fills ASS, the separator's block (dense, both triangles), and throws if a nonzero
// couples the two parts.
Eigen::SparseMatrix<double> part_matrix(const Eigen::SparseMatrix<double>& A, const std::vector<int>& position,
                                        Eigen::Index n1, Eigen::Index n2, int k, Eigen::MatrixXd* ASS) {
  const Eigen::Index n = A.rows(), s = n - n1 - n2, size = (k == 0 ? n1 : n2) + s;
  // Local index in the part of an ordered row, -1 in the other part.
  auto local = [&](Eigen::Index p) -> Eigen::Index {
    if (p >= n1 + n2) return p - n1 - n2 + (k == 0 ? n1 : n2);
    if (k == 0) return p < n1 ? p : -1;
    return p >= n1 ? p - n1 : -1;
  };
  auto at = [&](Eigen::Index i) -> Eigen::Index {
    return position.empty() ? i : position[static_cast<std::size_t>(i)];
  };
  std::vector<int> start(static_cast<std::size_t>(size) + 1, 0);
  auto each_lower = [&](auto&& f) {  // f(row, column) in the part, row >= column
    for (Eigen::Index j = 0; j < n; ++j) {
      const Eigen::Index pj = at(j), lj = local(pj);
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) {
        const Eigen::Index i = it.row();
        if (i < j) continue;
        const Eigen::Index pi = at(i), li = local(pi);
        if (k == 0) {
          if ((li < 0) != (lj < 0) && std::min(pi, pj) < n1 && it.value() != 0)
            throw SolverError(fmt::format("split factor: rows {} and {} couple the two parts", j, i));
          if (ASS && pi >= n1 + n2 && pj >= n1 + n2)
            (*ASS)(pi - n1 - n2, pj - n1 - n2) = (*ASS)(pj - n1 - n2, pi - n1 - n2) = it.value();
        }
        if (li >= 0 && lj >= 0) f(std::max(li, lj), std::min(li, lj), it.value());
      }
    }
  };
  each_lower([&](Eigen::Index, Eigen::Index c, double) { ++start[static_cast<std::size_t>(c) + 1]; });
  for (Eigen::Index c = 0; c < size; ++c) start[static_cast<std::size_t>(c) + 1] += start[static_cast<std::size_t>(c)];
  Eigen::SparseMatrix<double> M(size, size);
  M.resizeNonZeros(start.back());
  std::copy(start.begin(), start.end(), M.outerIndexPtr());
  std::vector<int> next(start.begin(), start.end() - 1);
  int* rows = M.innerIndexPtr();
  double* values = M.valuePtr();
  if (ASS) ASS->setZero();
  each_lower([&](Eigen::Index r, Eigen::Index c, double v) {
    const int e = next[static_cast<std::size_t>(c)]++;
    rows[e] = static_cast<int>(r);
    values[e] = v;
  });
  for (Eigen::Index c = 0; c < size; ++c)  // a column holds a few rows: insertion sort
    for (int e = start[static_cast<std::size_t>(c)] + 1; e < start[static_cast<std::size_t>(c) + 1]; ++e)
      for (int q = e; q > start[static_cast<std::size_t>(c)] && rows[q - 1] > rows[q]; --q) {
        std::swap(rows[q - 1], rows[q]);
        std::swap(values[q - 1], values[q]);
      }
  return M;
}

}  // namespace

void SplitCholesky::factorize(const Eigen::SparseMatrix<double>& A, Eigen::Index part1, Eigen::Index part2) {
  factorize(A, {}, part1, part2);
}

void SplitCholesky::factorize(const Eigen::SparseMatrix<double>& A_in, const std::vector<int>& order,
                              Eigen::Index part1, Eigen::Index part2) {
  Impl& d = *impl_;
  d.factored = false;
  size_ = 0;
  if (!available()) throw SolverError("the split factor needs CHOLMOD, and meshpde was built without it");
  Eigen::SparseMatrix<double> copy;
  const Eigen::SparseMatrix<double>& A = checked(A_in, copy);
  const Eigen::Index n = A.rows();
  if (part1 < 1 || part2 < 1 || part1 + part2 >= n)
    throw SolverError(
        fmt::format("split factor: parts of {} and {} rows leave no separator in {} rows", part1, part2, n));
  if (!order.empty() && order.size() != static_cast<std::size_t>(n))
    throw SolverError(fmt::format("split factor: an order of {} rows for a matrix of {}", order.size(), n));
  std::vector<int> position;
  if (!order.empty()) {
    position.assign(order.size(), -1);
    for (std::size_t k = 0; k < order.size(); ++k) {
      const int i = order[k];
      if (i < 0 || i >= n || position[static_cast<std::size_t>(i)] >= 0)
        throw SolverError(fmt::format("split factor: the order is not a permutation of 0..{} (row {})", n - 1, i));
      position[static_cast<std::size_t>(i)] = static_cast<int>(k);
    }
  }
  d.n1 = part1;
  d.n2 = part2;
  d.s = n - part1 - part2;
  for (auto& part : d.part)
    if (!part) part = std::make_unique<CholmodInOrder>();
  bool ok[2] = {false, false};
  Eigen::MatrixXd gram[2];
  Eigen::MatrixXd ASS(d.s, d.s);
  std::exception_ptr error[2];
  auto factor_part = [&](int k) {
    try {
      // Freed once factored: only L is kept.
      const Eigen::SparseMatrix<double> M = part_matrix(A, position, part1, part2, k, k == 0 ? &ASS : nullptr);
      ok[k] = d.part[k]->factorize(M);
    } catch (...) {
      error[k] = std::current_exception();
      return;
    }
    if (!ok[k]) return;
    d.C[k] = d.part[k]->trailing_block(d.s);
    // C_k C_k^T on this part's thread (only its lower triangle is read below).
    gram[k] = detail::lower_gram(d.C[k]);
  };
  detail::on_two_threads([&] { factor_part(0); }, [&] { factor_part(1); });
  for (const auto& e : error)
    if (e) std::rethrow_exception(e);
  if (!ok[0] || !ok[1]) throw not_positive_definite("cholmod-supernodal, split");
  gram[0] += gram[1];
  gram[1] = Eigen::MatrixXd();
  gram[0] -= ASS;
  ASS = Eigen::MatrixXd();
  d.schur.compute(gram[0]);
  if (d.schur.info() != Eigen::Success) throw not_positive_definite("cholmod-supernodal, split");
  size_ = n;
  d.factored = true;
}

double SplitCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  double count = static_cast<double>(d.s * (d.s + 1) / 2);
  for (const auto& part : d.part) count += part->nonzeros();
  return count;
}

Eigen::MatrixXd SplitCholesky::solve(const Eigen::MatrixXd& B) const {
  Impl& d = *impl_;  // CHOLMOD's workspace changes in a solve, the factors do not
  if (!d.factored) throw SolverError("direct solve: solve() before a successful factorize()");
  if (B.rows() != size_) throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", B.rows(), size_));
  const Eigen::Index m = B.cols();
  Eigen::MatrixXd out(size_, m);
  // Part k's factor is [L_kk 0; L_Sk C_k]. Forward with [B_k; 0] gives y_k = L_kk^-1 B_k
  // on top and w_k = -C_k^-1 L_Sk y_k below, so the separator's right-hand side after
  // both parts is B_S + C_1 w_1 + C_2 w_2. Backward with [y_k; C_k^T x_S] gives
  // x_k = L_kk^-T (y_k - L_Sk^T x_S) on top.
  Eigen::MatrixXd Y[2];
  const Eigen::Index begin[2] = {0, d.n1}, rows[2] = {d.n1, d.n2};
  for (int k = 0; k < 2; ++k) {
    Y[k] = Eigen::MatrixXd::Zero(rows[k] + d.s, m);
    Y[k].topRows(rows[k]) = B.middleRows(begin[k], rows[k]);
  }
  detail::on_two_threads([&] { d.part[0]->forward(Y[0]); }, [&] { d.part[1]->forward(Y[1]); });
  Eigen::MatrixXd t = B.bottomRows(d.s);
  for (int k = 0; k < 2; ++k) t += d.C[k].triangularView<Eigen::Lower>() * Y[k].bottomRows(d.s);
  const Eigen::MatrixXd xs = d.schur.solve(t);
  for (int k = 0; k < 2; ++k) Y[k].bottomRows(d.s) = d.C[k].triangularView<Eigen::Lower>().transpose() * xs;
  detail::on_two_threads([&] { d.part[0]->backward(Y[0]); }, [&] { d.part[1]->backward(Y[1]); });
  for (int k = 0; k < 2; ++k) out.middleRows(begin[k], rows[k]) = Y[k].topRows(rows[k]);
  out.bottomRows(d.s) = xs;
  return out;
}

}  // namespace meshpde
