// The only translation unit that includes CHOLMOD.
#include "meshpde/solvers/direct.h"

#include <fmt/format.h>

#include <Eigen/SparseCholesky>
#ifdef MESHPDE_HAVE_CHOLMOD
#include <cholmod.h>

#include <Eigen/CholmodSupport>
#endif

#include <dlfcn.h>

#include <algorithm>
#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

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

// CHOLMOD 3 (SuiteSparse 5.x) runs parts of its supernodal factorization (the scatter
// of each supernode's update) in OpenMP regions whose thread count is fixed when
// CHOLMOD is compiled (CHOLMOD_OMP_NUM_THREADS, 4 in Debian's build), whatever the
// machine has. On two cores that is four threads forking and joining once per
// supernode: measured on the 10k-vertex drag region's K D K (126 Mflop), 48 ms with
// them and 13 ms without (docs/solvers.md). The parallel work that pays is the BLAS's
// (its own threads, blas_threads_for), so CHOLMOD's regions run on the calling thread:
// with no active parallel level allowed, every OpenMP region is one thread. Restored
// on leaving, so meshpde's own loops are not affected.
class SerialOpenMpRegions {
 public:
#ifdef MESHPDE_HAVE_OPENMP
  SerialOpenMpRegions() : saved_(omp_get_max_active_levels()) {
    omp_set_max_active_levels(0);
  }
  ~SerialOpenMpRegions() {
    omp_set_max_active_levels(saved_);
  }

 private:
  int saved_;
#else
  SerialOpenMpRegions() {}  // user-provided: an unused-variable warning otherwise
#endif
};

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
    const SerialOpenMpRegions serial;
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
    const SerialOpenMpRegions serial;
    return d.cholmod.solve(B);
  }
#endif
  return d.eigen.solve(B);
}

struct LeadingBlockCholesky::Impl {
  SparseCholesky::Backend backend = SparseCholesky::Backend::Eigen;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> eigen;
  bool factored = false;
#ifdef MESHPDE_HAVE_CHOLMOD
  cholmod_common common{};
  cholmod_factor* L = nullptr;
  Impl() {
    cholmod_start(&common);
    common.print = 0;  // failures become SolverError in words, not lines on stderr
    // The given order, exactly: no fill-reducing method, no postordering (which could
    // move the rows meant to be last).
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_NATURAL;
    common.postorder = 0;
    common.supernodal = CHOLMOD_SUPERNODAL;
    // Coarser supernodes than CHOLMOD's default {4, 16, 48}: fewer, larger BLAS calls.
    // 10k-vertex drag region's K D K in nested dissection order: 15 ms instead of 17
    // (analysis and factorization; 8 and 16 were no better than 12).
    common.nrelax[0] = 12;
    common.nrelax[1] = 48;
    common.nrelax[2] = 144;
  }
  ~Impl() {
    if (L) cholmod_free_factor(&L, &common);
    cholmod_finish(&common);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
#endif
};

LeadingBlockCholesky::LeadingBlockCholesky(SparseCholesky::Backend backend) : impl_(std::make_unique<Impl>()) {
  if (backend == SparseCholesky::Backend::Cholmod && !SparseCholesky::cholmod_available())
    throw SolverError("CHOLMOD was requested but meshpde was built without it (install libsuitesparse-dev)");
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
  if (A_in.rows() != A_in.cols())
    throw SolverError(fmt::format("direct solve: the matrix is {} x {}, not square", A_in.rows(), A_in.cols()));
  Impl& d = *impl_;
  d.factored = false;
  size_ = 0;
  const Eigen::SparseMatrix<double>* A = &A_in;
  Eigen::SparseMatrix<double> compressed;
  if (!A_in.isCompressed()) {
    compressed = A_in;
    compressed.makeCompressed();
    A = &compressed;
  }
  for (Eigen::Index k = 0; k < A->nonZeros(); ++k)
    if (!std::isfinite(A->valuePtr()[k])) throw SolverError("direct solve: the matrix has a NaN or infinite entry");
  bool ok = true;
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    if (d.L) cholmod_free_factor(&d.L, &d.common);
    // A view of A's arrays (nothing copied); with stype -1 CHOLMOD reads the lower
    // triangle and ignores the upper one.
    cholmod_sparse view{};
    view.nrow = view.ncol = static_cast<std::size_t>(A->rows());
    view.nzmax = static_cast<std::size_t>(A->nonZeros());
    view.p = const_cast<int*>(A->outerIndexPtr());
    view.i = const_cast<int*>(A->innerIndexPtr());
    view.x = const_cast<double*>(A->valuePtr());
    view.stype = -1;
    view.itype = CHOLMOD_INT;
    view.xtype = CHOLMOD_REAL;
    view.dtype = CHOLMOD_DOUBLE;
    view.sorted = 1;
    view.packed = 1;
    set_blas_threads(blas_threads_for(A->rows()));
    const SerialOpenMpRegions serial;
    d.L = cholmod_analyze(&view, &d.common);
    if (!d.L) throw SolverError(fmt::format("direct solve: CHOLMOD's analysis failed (status {})", d.common.status));
    // The order must be the given one: the leading-block solves rely on it.
    const auto* perm = static_cast<const int*>(d.L->Perm);
    for (std::size_t k = 0; k < d.L->n; ++k)
      if (perm[k] != static_cast<int>(k)) throw SolverError("direct solve: CHOLMOD reordered a matrix given in order");
    ok = cholmod_factorize(&view, d.L, &d.common) && d.common.status == CHOLMOD_OK && d.L->minor == d.L->n;
  }
#endif
  if (d.backend == SparseCholesky::Backend::Eigen) {
    d.eigen.compute(*A);
    ok = d.eigen.info() == Eigen::Success;
  }
  if (!ok)
    throw SolverError(
        fmt::format("direct solve ({}): the matrix is not positive definite (a part of the mesh "
                    "without constraints, or a negative coefficient?)",
                    backend_name()));
  size_ = A->rows();
  d.factored = true;
}

double LeadingBlockCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) return d.common.lnz;
#endif
  return static_cast<double>(d.eigen.matrixL().nestedExpression().nonZeros());
}

Eigen::MatrixXd LeadingBlockCholesky::solve_leading(const Eigen::MatrixXd& B) const {
  const Impl& d = *impl_;
  if (!d.factored) throw SolverError("direct solve: solve_leading() before a successful factorize()");
  const Eigen::Index n = B.rows();
  if (n > size_) throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", n, size_));
  // L = [L_aa 0; L_ba L_bb]: forward with [B; 0] gives L_aa^-1 B on top; with the rest
  // zeroed, the backward sweep gives L_aa^-T on top and zeros below.
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(size_, B.cols());
  Y.topRows(n) = B;
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    set_blas_threads(1);  // as SparseCholesky::solve(): memory-bound sweeps
    const SerialOpenMpRegions serial;
    auto& common = const_cast<cholmod_common&>(d.common);  // CHOLMOD's workspace, not the factor
    cholmod_dense b{};
    b.nrow = b.d = static_cast<std::size_t>(size_);
    b.ncol = static_cast<std::size_t>(Y.cols());
    b.nzmax = b.nrow * b.ncol;
    b.x = Y.data();
    b.xtype = CHOLMOD_REAL;
    b.dtype = CHOLMOD_DOUBLE;
    cholmod_dense* y = cholmod_solve(CHOLMOD_L, d.L, &b, &common);
    if (!y) throw SolverError("direct solve: CHOLMOD's forward sweep failed");
    Eigen::Map<Eigen::MatrixXd> ym(static_cast<double*>(y->x), size_, Y.cols());
    ym.bottomRows(size_ - n).setZero();
    cholmod_dense* x = cholmod_solve(CHOLMOD_Lt, d.L, y, &common);
    cholmod_free_dense(&y, &common);
    if (!x) throw SolverError("direct solve: CHOLMOD's backward sweep failed");
    Eigen::MatrixXd out = Eigen::Map<Eigen::MatrixXd>(static_cast<double*>(x->x), size_, Y.cols()).topRows(n);
    cholmod_free_dense(&x, &common);
    return out;
  }
#endif
  d.eigen.matrixL().solveInPlace(Y);
  Y.bottomRows(size_ - n).setZero();
  d.eigen.matrixU().solveInPlace(Y);
  return Y.topRows(n);
}

}  // namespace meshpde
