// The only translation unit that includes CHOLMOD.
#include "meshpde/solvers/direct.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#ifdef MESHPDE_HAVE_CHOLMOD
#include <cholmod.h>

#include <Eigen/CholmodSupport>
#endif

#include <dlfcn.h>

#include <algorithm>
#include <exception>
#include <limits>
#ifdef MESHPDE_HAVE_OPENMP
#include <omp.h>
#endif

#include "../core/two_threads.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "supernodal_sweeps.h"

namespace meshpde {

namespace {

// Measured on the 2-core development machine (docs/solvers.md), bi-Laplacian drag
// regions: below about 700 unknowns Eigen's simplicial factorization beats CHOLMOD's
// supernodal one (504: 0.79 against 0.88 ms; 1,140: 2.8 against 2.2 ms); below about
// 60,000 a second BLAS thread does not pay (128k: 1.75 s on one or two).
constexpr Eigen::Index kSimplicialBelow = 700;
constexpr Eigen::Index kOneBlasThreadBelow = 60000;

// OpenBLAS (Debian's libopenblas0-pthread provides libblas.so.3) exports this; other
// BLAS libraries do not, and then nothing is changed.
void set_blas_threads(int n) {
  using Fn = void (*)(int);
  static const Fn fn = reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (fn) fn(n);
}

[[maybe_unused]] int blas_threads_for(Eigen::Index n) {  // unused without CHOLMOD
  return n < kOneBlasThreadBelow ? 1 : max_threads();
}

// CHOLMOD 3 (SuiteSparse 5.x) runs parts of its supernodal factorization (the scatter
// of each supernode's update) in OpenMP regions whose thread count is fixed when
// CHOLMOD is compiled (CHOLMOD_OMP_NUM_THREADS, 4 in Debian's build), whatever the
// machine has. On two cores that is four threads forking and joining once per
// supernode: measured on the 10k-vertex drag region's K D K (126 Mflop), 48 ms with
// them and 13 ms without (docs/solvers.md). The parallel work that pays is the BLAS's
// (its own threads, blas_threads_for), so CHOLMOD's regions run on the calling thread:
// with no active parallel level allowed (OpenMpActiveLevels(0)), every OpenMP region is
// one thread. Restored on leaving, so meshpde's own loops are not affected.
class OpenMpActiveLevels {
 public:
#ifdef MESHPDE_HAVE_OPENMP
  explicit OpenMpActiveLevels(int levels) : saved_(omp_get_max_active_levels()) {
    omp_set_max_active_levels(levels);
  }
  ~OpenMpActiveLevels() {
    omp_set_max_active_levels(saved_);
  }

 private:
  int saved_;
#else
  explicit OpenMpActiveLevels(int) {}  // user-provided: an unused-variable warning otherwise
#endif
};

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

#ifdef MESHPDE_HAVE_CHOLMOD
// Eigen's CHOLMOD wrapper with its factor in view, for the sweeps of
// supernodal_sweeps.h.
struct CholmodLLT : Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> {
  // A failure becomes a SolverError in words (factorize), not also a CHOLMOD warning
  // on stderr.
  CholmodLLT() { cholmod().print = 0; }
  // A view of the factor when it is supernodal LL^T with int indices (what Eigen's
  // supernodal wrapper asks CHOLMOD for), else an empty one.
  detail::SupernodalFactorView view() const {
    const cholmod_factor* L = m_cholmodFactor;
    detail::SupernodalFactorView v;
    if (!L || !L->is_super || !L->is_ll || L->xtype != CHOLMOD_REAL || L->itype != CHOLMOD_INT) return v;
    v.n = static_cast<Eigen::Index>(L->n);
    v.nsuper = static_cast<Eigen::Index>(L->nsuper);
    v.super = static_cast<const int*>(L->super);
    v.pi = static_cast<const int*>(L->pi);
    v.px = static_cast<const int*>(L->px);
    v.s = static_cast<const int*>(L->s);
    v.x = static_cast<const double*>(L->x);
    v.perm = static_cast<const int*>(L->Perm);
    return v;
  }
};
#endif

struct SparseCholesky::Impl {
  Backend requested = Backend::Auto;
  Backend backend = Backend::Eigen;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> eigen;
#ifdef MESHPDE_HAVE_CHOLMOD
  CholmodLLT cholmod;
  detail::SupernodalSweeps sweeps;  // over cholmod's factor, when it is supernodal
#endif
  Sweeps sweep_mode = Sweeps::WrittenOut;
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

void SparseCholesky::set_sweeps(Sweeps sweeps) {
  impl_->sweep_mode = sweeps;
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
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == Backend::Cholmod) {
    set_blas_threads(blas_threads_for(A.rows()));
    const OpenMpActiveLevels serial(0);
    if (new_pattern) {
      d.cholmod.analyzePattern(A);
      ++analyses_;
    }
    d.cholmod.factorize(A);
    info = d.cholmod.info();
    const detail::SupernodalFactorView view = d.cholmod.view();
    d.sweeps = info == Eigen::Success && view.x ? detail::SupernodalSweeps(view) : detail::SupernodalSweeps();
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
  if (info != Eigen::Success) throw not_positive_definite(backend_name());
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

double SparseCholesky::pivot_ratio() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  auto take = [&](double pivot) {
    lo = std::min(lo, pivot);
    hi = std::max(hi, pivot);
  };
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == Backend::Cholmod) {
    const detail::SupernodalFactorView L = d.cholmod.view();
    if (!L.x) return 0;
    for (Eigen::Index k = 0; k < L.nsuper; ++k) {
      const int rows = L.pi[k + 1] - L.pi[k], cols = L.super[k + 1] - L.super[k];
      for (int j = 0; j < cols; ++j) {
        const double l = L.x[L.px[k] + static_cast<std::ptrdiff_t>(j) * rows + j];
        take(l * l);
      }
    }
    return hi > 0 ? lo / hi : 0;
  }
#endif
  const auto D = d.eigen.vectorD();
  for (Eigen::Index i = 0; i < D.size(); ++i) take(D[i]);
  return hi > 0 ? lo / hi : 0;
}

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& B) const {
  const Impl& d = *impl_;
  if (!d.factored) throw SolverError("direct solve: solve() before a successful factorize()");
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == Backend::Cholmod) {
    if (B.rows() != d.cholmod.rows())
      throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", B.rows(), d.cholmod.rows()));
    // Written-out sweeps (supernodal_sweeps.h) for up to four columns: 1.5-2x faster
    // than cholmod_solve on the factors of surface meshes. From five columns on,
    // cholmod_solve's BLAS-3 calls are about as fast or faster (164k, eight columns,
    // cholmod_solve against a generic-width version of these loops: the Laplacian's
    // factor 69 against 66 ms, K D K's 111 against 157 ms).
    if (!d.sweeps.empty() && d.sweep_mode == Sweeps::WrittenOut && B.cols() >= 1 && B.cols() <= 4)
      return d.sweeps.solve(B);
    // Otherwise cholmod_solve, on one BLAS thread: a second made it slower (164k-vertex
    // Laplacian factor, three columns: 43 ms on one thread, 48 ms on two).
    set_blas_threads(1);
    const OpenMpActiveLevels serial(0);
    return d.cholmod.solve(B);
  }
#endif
  return d.eigen.solve(B);
}

#ifdef MESHPDE_HAVE_CHOLMOD
namespace {

// A CHOLMOD supernodal LL^T factor of a matrix in the order it is given (no
// fill-reducing permutation, no postordering), with the sweeps and the trailing block
// the leading-block and split factors need.
struct CholmodInOrder {
  cholmod_common common{};
  cholmod_factor* L = nullptr;

  CholmodInOrder() {
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
  ~CholmodInOrder() {
    if (L) cholmod_free_factor(&L, &common);
    cholmod_finish(&common);
  }
  CholmodInOrder(const CholmodInOrder&) = delete;
  CholmodInOrder& operator=(const CholmodInOrder&) = delete;

  // Analyzes and factors A (compressed, symmetric; the lower triangle is read). Returns
  // false if A is not positive definite. The caller sets the BLAS and OpenMP threads.
  bool factorize(const Eigen::SparseMatrix<double>& A) {
    if (L) cholmod_free_factor(&L, &common);
    // A view of A's arrays (nothing copied); with stype -1 CHOLMOD reads the lower
    // triangle and ignores the upper one.
    cholmod_sparse view{};
    view.nrow = view.ncol = static_cast<std::size_t>(A.rows());
    view.nzmax = static_cast<std::size_t>(A.nonZeros());
    view.p = const_cast<int*>(A.outerIndexPtr());
    view.i = const_cast<int*>(A.innerIndexPtr());
    view.x = const_cast<double*>(A.valuePtr());
    view.stype = -1;
    view.itype = CHOLMOD_INT;
    view.xtype = CHOLMOD_REAL;
    view.dtype = CHOLMOD_DOUBLE;
    view.sorted = 1;
    view.packed = 1;
    L = cholmod_analyze(&view, &common);
    if (!L) throw SolverError(fmt::format("direct solve: CHOLMOD's analysis failed (status {})", common.status));
    // The order must be the given one: the leading-block solves rely on it.
    const auto* perm = static_cast<const int*>(L->Perm);
    for (std::size_t k = 0; k < L->n; ++k)
      if (perm[k] != static_cast<int>(k)) throw SolverError("direct solve: CHOLMOD reordered a matrix given in order");
    return cholmod_factorize(&view, L, &common) && common.status == CHOLMOD_OK && L->minor == L->n;
  }

  // Y = L^-1 Y (sys CHOLMOD_L) or L^-T Y (CHOLMOD_Lt), all columns in one sweep. With
  // cholmod_solve: tried here, the written-out sweeps of SparseCholesky were slower on
  // these factors of drag regions, whose supernodes are coarse (nrelax above): on the
  // bench's 10k region (655k sphere), growing by one ring 4.1-4.5 against 3.1-3.6 ms,
  // adding a handle 2.8-3.3 against 1.5-1.8 ms.
  void sweep(int sys, Eigen::MatrixXd& Y) {
    cholmod_dense b{};
    b.nrow = b.d = static_cast<std::size_t>(Y.rows());
    b.ncol = static_cast<std::size_t>(Y.cols());
    b.nzmax = b.nrow * b.ncol;
    b.x = Y.data();
    b.xtype = CHOLMOD_REAL;
    b.dtype = CHOLMOD_DOUBLE;
    cholmod_dense* x = cholmod_solve(sys, L, &b, &common);
    if (!x) throw SolverError("direct solve: a CHOLMOD triangular sweep failed");
    Y = Eigen::Map<Eigen::MatrixXd>(static_cast<double*>(x->x), Y.rows(), Y.cols());
    cholmod_free_dense(&x, &common);
  }

  // The trailing s x s block of L (lower triangular, dense), read from the supernodes.
  Eigen::MatrixXd trailing_block(Eigen::Index s) const {
    const auto n = static_cast<Eigen::Index>(L->n), first = n - s;
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(s, s);
    const auto* super = static_cast<const int*>(L->super);
    const auto* pi = static_cast<const int*>(L->pi);
    const auto* px = static_cast<const int*>(L->px);
    const auto* rows = static_cast<const int*>(L->s);
    const auto* x = static_cast<const double*>(L->x);
    for (std::size_t k = 0; k < L->nsuper; ++k) {
      if (super[k + 1] <= first) continue;
      const int nsrow = pi[k + 1] - pi[k];
      for (int j = std::max<int>(super[k], static_cast<int>(first)); j < super[k + 1]; ++j)
        for (int q = j - super[k]; q < nsrow; ++q) {  // rows j and below (the diagonal block's lower part)
          const int i = rows[pi[k] + q];
          C(i - first, j - first) = x[px[k] + static_cast<std::ptrdiff_t>(j - super[k]) * nsrow + q];
        }
    }
    return C;
  }
};

}  // namespace
#endif

struct LeadingBlockCholesky::Impl {
  SparseCholesky::Backend requested = SparseCholesky::Backend::Auto;
  SparseCholesky::Backend backend = SparseCholesky::Backend::Eigen;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> eigen;
  bool factored = false;
#ifdef MESHPDE_HAVE_CHOLMOD
  CholmodInOrder cholmod;
#endif
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
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    set_blas_threads(blas_threads_for(A.rows()));
    const OpenMpActiveLevels serial(0);
    ok = d.cholmod.factorize(A);
  }
#endif
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
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) return d.cholmod.common.lnz;
#endif
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
#ifdef MESHPDE_HAVE_CHOLMOD
  if (d.backend == SparseCholesky::Backend::Cholmod) {
    set_blas_threads(1);  // as SparseCholesky::solve(): a second BLAS thread slows the sweeps
    const OpenMpActiveLevels serial(0);
    d.cholmod.sweep(CHOLMOD_L, Y);
    Y.bottomRows(size_ - n).setZero();
    d.cholmod.sweep(CHOLMOD_Lt, Y);
    return Y.topRows(n);
  }
#endif
  d.eigen.matrixL().solveInPlace(Y);
  Y.bottomRows(size_ - n).setZero();
  d.eigen.matrixU().solveInPlace(Y);
  return Y.topRows(n);
}

namespace {

// Runs f0 and f1 at the same time, each on one core, with one BLAS thread each; CHOLMOD's
// own OpenMP regions inside them stay on their thread (nested regions are inactive at
// one active level). One thread under set_max_threads(1). Exceptions are rethrown after
// both have finished.
template <class F0, class F1>
void on_two_threads(F0&& f0, F1&& f1) {
  set_blas_threads(1);
  const OpenMpActiveLevels levels(max_threads() > 1 ? 1 : 0);
  detail::run_both(f0, f1);
}

}  // namespace

struct SplitCholesky::Impl {
#ifdef MESHPDE_HAVE_CHOLMOD
  CholmodInOrder part[2];
#endif
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

#ifdef MESHPDE_HAVE_BLAS
// The BLAS that CHOLMOD links (Fortran interface; the trailing arguments are the hidden
// lengths of the character arguments).
extern "C" void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha,
                       const double* a, const int* lda, const double* beta, double* c, const int* ldc, std::size_t,
                       std::size_t);
#endif

// The lower triangle of C C^T for a lower triangular C (its upper part zero); the
// strict upper triangle of the result is not meant to be read. With the BLAS, dsyrk:
// for the 225-row separator of the bench's 10k drag region 0.3 ms against 1.0 ms for
// Eigen's triangular product (compiled for any x86-64, where OpenBLAS picks its kernels
// for the machine it runs on).
[[maybe_unused]] Eigen::MatrixXd lower_gram(const Eigen::MatrixXd& C) {
#ifdef MESHPDE_HAVE_BLAS
  const int n = static_cast<int>(C.rows());
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(n, n);
  if (n == 0) return G;
  const double one = 1, zero = 0;
  dsyrk_("L", "N", &n, &n, &one, C.data(), &n, &zero, G.data(), &n, 1, 1);
  return G;
#else
  return C.triangularView<Eigen::Lower>() * C.transpose();
#endif
}

// The principal submatrix of A without the rows and columns [skip_begin, skip_end),
// compressed. With `check_coupling`, a nonzero between a column before skip_begin and a
// row in the skipped range throws.
[[maybe_unused]] Eigen::SparseMatrix<double> principal_without(const Eigen::SparseMatrix<double>& A,
                                                               Eigen::Index skip_begin, Eigen::Index skip_end,
                                                               bool check_coupling) {
  const Eigen::Index n = A.rows(), skipped = skip_end - skip_begin;
  Eigen::SparseMatrix<double> M(n - skipped, n - skipped);
  M.reserve(A.nonZeros());
  Eigen::Index column = 0;
  for (Eigen::Index j = 0; j < n; ++j) {
    if (j >= skip_begin && j < skip_end) continue;
    M.startVec(column++);
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) {
      const Eigen::Index i = it.row();
      if (i >= skip_begin && i < skip_end) {
        if (check_coupling && j < skip_begin && it.value() != 0)
          throw SolverError(fmt::format("split factor: rows {} and {} couple the two parts", j, i));
        continue;
      }
      M.insertBack(i < skip_begin ? i : i - skipped, column - 1) = it.value();
    }
  }
  M.finalize();
  return M;
}

}  // namespace

void SplitCholesky::factorize(const Eigen::SparseMatrix<double>& A_in, Eigen::Index part1, Eigen::Index part2) {
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
  d.n1 = part1;
  d.n2 = part2;
  d.s = n - part1 - part2;
#ifdef MESHPDE_HAVE_CHOLMOD
  bool ok[2] = {false, false};
  Eigen::MatrixXd gram[2];
  auto factor_part = [&](int k) {
    // M1 skips part 2's rows; M2 skips part 1's.
    const Eigen::SparseMatrix<double> M =
        k == 0 ? principal_without(A, part1, part1 + part2, true) : principal_without(A, 0, part1, false);
    ok[k] = d.part[k].factorize(M);
    if (!ok[k]) return;
    d.C[k] = d.part[k].trailing_block(d.s);
    // C_k C_k^T on this part's thread (only its lower triangle is read below).
    gram[k] = lower_gram(d.C[k]);
  };
  on_two_threads([&] { factor_part(0); }, [&] { factor_part(1); });
  if (!ok[0] || !ok[1]) throw not_positive_definite("cholmod-supernodal, split");
  const Eigen::MatrixXd schur = gram[0] + gram[1] - Eigen::MatrixXd(A.bottomRightCorner(d.s, d.s));
  d.schur.compute(schur);
  if (d.schur.info() != Eigen::Success) throw not_positive_definite("cholmod-supernodal, split");
#endif
  size_ = n;
  d.factored = true;
}

double SplitCholesky::factor_nonzeros() const {
  const Impl& d = *impl_;
  if (!d.factored) return 0;
  double count = static_cast<double>(d.s * (d.s + 1) / 2);
#ifdef MESHPDE_HAVE_CHOLMOD
  for (const CholmodInOrder& p : d.part) count += p.common.lnz;
#endif
  return count;
}

Eigen::MatrixXd SplitCholesky::solve(const Eigen::MatrixXd& B) const {
  Impl& d = *impl_;  // CHOLMOD's workspace changes in a solve, the factors do not
  if (!d.factored) throw SolverError("direct solve: solve() before a successful factorize()");
  if (B.rows() != size_) throw SolverError(fmt::format("direct solve: {} rows for a factor of {}", B.rows(), size_));
  const Eigen::Index m = B.cols();
  Eigen::MatrixXd out(size_, m);
#ifdef MESHPDE_HAVE_CHOLMOD
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
  on_two_threads([&] { d.part[0].sweep(CHOLMOD_L, Y[0]); }, [&] { d.part[1].sweep(CHOLMOD_L, Y[1]); });
  Eigen::MatrixXd t = B.bottomRows(d.s);
  for (int k = 0; k < 2; ++k) t += d.C[k].triangularView<Eigen::Lower>() * Y[k].bottomRows(d.s);
  const Eigen::MatrixXd xs = d.schur.solve(t);
  for (int k = 0; k < 2; ++k) Y[k].bottomRows(d.s) = d.C[k].triangularView<Eigen::Lower>().transpose() * xs;
  on_two_threads([&] { d.part[0].sweep(CHOLMOD_Lt, Y[0]); }, [&] { d.part[1].sweep(CHOLMOD_Lt, Y[1]); });
  for (int k = 0; k < 2; ++k) out.middleRows(begin[k], rows[k]) = Y[k].topRows(rows[k]);
  out.bottomRows(d.s) = xs;
#endif
  return out;
}

}  // namespace meshpde
