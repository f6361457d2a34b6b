// The only translation unit that includes CHOLMOD.
#include "meshpde/solvers/direct.h"

#include <fmt/format.h>

#include <Eigen/SparseCholesky>
#ifdef MESHPDE_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include <dlfcn.h>

#include <algorithm>

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"

namespace meshpde {

namespace {

// Measured on the 2-core development machine (docs/solvers.md): below about 3,000
// unknowns Eigen's simplicial factorization beats CHOLMOD's supernodal one; below about
// 60,000 a single BLAS thread beats two (the supernodes are too small to share).
constexpr Eigen::Index kSimplicialBelow = 3000;
constexpr Eigen::Index kOneBlasThreadBelow = 60000;

// OpenBLAS (Debian's libopenblas0-pthread provides libblas.so.3) exports this; other
// BLAS libraries do not, and then nothing is changed.
void set_blas_threads(int n) {
  using Fn = void (*)(int);
  static const Fn fn = reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (fn) fn(n);
}

int blas_threads_for(Eigen::Index n) {
  return n < kOneBlasThreadBelow ? 1 : max_threads();
}

}  // namespace

struct SparseCholesky::Impl {
  Backend requested = Backend::Auto;
  Backend backend = Backend::Eigen;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> eigen;
#ifdef MESHPDE_HAVE_CHOLMOD
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> cholmod;
#endif
  Eigen::SparseMatrix<double> pattern;  // structure of the analyzed matrix (values unused)
  bool analyzed = false;
  bool factored = false;
};

bool SparseCholesky::cholmod_available() {
#ifdef MESHPDE_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
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
  if (A_in.rows() != A_in.cols())
    throw SolverError(fmt::format("direct solve: the matrix is {} x {}, not square", A_in.rows(), A_in.cols()));
  Eigen::SparseMatrix<double> A = A_in;
  A.makeCompressed();
  for (Eigen::Index k = 0; k < A.nonZeros(); ++k)
    if (!std::isfinite(A.valuePtr()[k])) throw SolverError("direct solve: the matrix has a NaN or infinite entry");
  Impl& d = *impl_;
  d.factored = false;
  if (d.requested == Backend::Auto)
    d.backend = cholmod_available() && A.rows() >= kSimplicialBelow ? Backend::Cholmod : Backend::Eigen;
  const bool new_pattern = !d.analyzed || !same_pattern(A, d.pattern);
  Eigen::ComputationInfo info = Eigen::Success;
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == Backend::Cholmod) {
    set_blas_threads(blas_threads_for(A.rows()));
    if (new_pattern) {
      d.cholmod.analyzePattern(A);
      ++analyses_;
    }
    d.cholmod.factorize(A);
    info = d.cholmod.info();
  }
#endif
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
  if (info != Eigen::Success)
    throw SolverError(
        fmt::format("direct solve ({}): the matrix is not positive definite (a part of the mesh "
                    "without constraints, or a negative coefficient?)",
                    backend_name()));
  d.factored = true;
}

double SparseCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
#ifdef MESHPDE_HAVE_CHOLMOD
  // CHOLMOD's common block records nnz(L) of the analysis in use.
  if (d.backend == Backend::Cholmod) return const_cast<Impl&>(d).cholmod.cholmod().lnz;
#endif
  return static_cast<double>(d.eigen.matrixL().nestedExpression().nonZeros());
}

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& B) const {
  const Impl& d = *impl_;
  if (!d.factored) throw SolverError("direct solve: solve() before a successful factorize()");
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == Backend::Cholmod) {
    // Triangular solves stream the factor once per column: memory-bound, and a second
    // BLAS thread makes them slower (164k-vertex Laplacian factor, three columns:
    // 43 ms on one thread, 48 ms on two), so they always run on one.
    set_blas_threads(1);
    return d.cholmod.solve(B);
  }
#endif
  return d.eigen.solve(B);
}

}  // namespace meshpde
