// The only translation unit that includes CHOLMOD (built when CHOLMOD is found; else
// cholmod_missing.cpp).
#include "cholmod_factors.h"

#include <cholmod.h>
#include <fmt/format.h>

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <limits>

#include "meshpde/core/errors.h"
#include "solver_threads.h"
#include "supernodal_sweeps.h"

namespace meshpde::detail {

bool cholmod_built() {
  return true;
}

namespace {

// Eigen's CHOLMOD wrapper with its factor in view, for the sweeps of
// supernodal_sweeps.h.
struct CholmodLLT : Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> {
  // A failure becomes a SolverError in words (SparseCholesky::factorize), not also a
  // CHOLMOD warning on stderr.
  CholmodLLT() { cholmod().print = 0; }
  const cholmod_factor* factor() const { return m_cholmodFactor; }
  // A view of the factor when it is supernodal LL^T with int indices (what Eigen's
  // supernodal wrapper asks CHOLMOD for), else an empty one.
  SupernodalFactorView view() const {
    const cholmod_factor* L = m_cholmodFactor;
    SupernodalFactorView v;
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
  // Eigen's analyzePattern with the fill-reducing order given (order[k]: the row
  // eliminated k-th) instead of CHOLMOD's choice; CHOLMOD still postorders it. With
  // `coarse`, coarser supernodes than CHOLMOD's default {4, 16, 48}: fewer, larger
  // BLAS calls (the mesh ordering's factor of fertility-4k subdivided three times:
  // 4.8 s with the default, 3.9 s with these), and sweeps over more explicit zeros
  // (igea-134k's K D K in CHOLMOD's own order: one solve 38-43 ms with the default,
  // 44-55 ms with these).
  void analyze_in_order(const Eigen::SparseMatrix<double>& A, std::vector<int>& order, bool coarse) {
    cholmod_common& common = cholmod();
    if (m_cholmodFactor) {
      cholmod_free_factor(&m_cholmodFactor, &common);
      m_cholmodFactor = nullptr;
    }
    cholmod_sparse view = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
    cholmod_common saved = common;
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_GIVEN;
    if (coarse) {
      common.nrelax[0] = 16;
      common.nrelax[1] = 64;
      common.nrelax[2] = 192;
    }
    m_cholmodFactor = cholmod_analyze_p(&view, order.data(), nullptr, 0, &common);
    common.nmethods = saved.nmethods;
    common.method[0].ordering = saved.method[0].ordering;
    std::copy(std::begin(saved.nrelax), std::end(saved.nrelax), std::begin(common.nrelax));
    if (!m_cholmodFactor)
      throw SolverError(
          fmt::format("direct solve: CHOLMOD's analysis in the given order failed (status {})", common.status));
    m_isInitialized = true;
    m_info = Eigen::Success;
    m_analysisIsOk = true;
    m_factorizationIsOk = false;
  }
};

}  // namespace

struct CholmodFactor::Impl {
  mutable CholmodLLT llt;   // CHOLMOD's workspace and statistics change in const calls
  SupernodalSweeps sweeps;  // over llt's factor, when it is supernodal
};

CholmodFactor::CholmodFactor() : impl_(std::make_unique<Impl>()) {}
CholmodFactor::~CholmodFactor() = default;

void CholmodFactor::analyze(const Eigen::SparseMatrix<double>& A, const std::vector<int>* order,
                            bool coarse_supernodes) {
  set_blas_threads(blas_threads_for(A.rows()));
  const OpenMpActiveLevels serial(0);
  if (order) {
    std::vector<int> copy = *order;  // CHOLMOD takes a non-const pointer
    impl_->llt.analyze_in_order(A, copy, coarse_supernodes);
  } else {
    impl_->llt.analyzePattern(A);
  }
}

bool CholmodFactor::factorize(const Eigen::SparseMatrix<double>& A) {
  set_blas_threads(blas_threads_for(A.rows()));
  const OpenMpActiveLevels serial(0);
  Impl& d = *impl_;
  d.llt.factorize(A);
  const bool ok = d.llt.info() == Eigen::Success;
  const SupernodalFactorView view = d.llt.view();
  d.sweeps = ok && view.x ? SupernodalSweeps(view) : SupernodalSweeps();
  return ok;
}

Eigen::MatrixXd CholmodFactor::solve(const Eigen::MatrixXd& B, bool written_out) const {
  const Impl& d = *impl_;
  // Written-out sweeps (supernodal_sweeps.h) for up to four columns: 1.5-2x faster
  // than cholmod_solve on the factors of surface meshes. From five columns on,
  // cholmod_solve's BLAS-3 calls are about as fast or faster (164k, eight columns,
  // cholmod_solve against a generic-width version of these loops: the Laplacian's
  // factor 69 against 66 ms, K D K's 111 against 157 ms).
  if (!d.sweeps.empty() && written_out && B.cols() >= 1 && B.cols() <= 4) return d.sweeps.solve(B);
  // Otherwise cholmod_solve, on one BLAS thread: a second made it slower (164k-vertex
  // Laplacian factor, three columns: 43 ms on one thread, 48 ms on two).
  set_blas_threads(1);
  const OpenMpActiveLevels serial(0);
  return d.llt.solve(B);
}

double CholmodFactor::nonzeros() const {
  // CHOLMOD's common block records nnz(L) of the analysis in use.
  return impl_->llt.cholmod().lnz;
}

std::vector<int> CholmodFactor::order() const {
  const cholmod_factor* L = impl_->llt.factor();
  if (!L || !L->Perm) return {};
  const auto* perm = static_cast<const int*>(L->Perm);
  return std::vector<int>(perm, perm + L->n);
}

double CholmodFactor::pivot_ratio() const {
  const SupernodalFactorView L = impl_->llt.view();
  if (!L.x) return 0;
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (Eigen::Index k = 0; k < L.nsuper; ++k) {
    const int rows = L.pi[k + 1] - L.pi[k], cols = L.super[k + 1] - L.super[k];
    for (int j = 0; j < cols; ++j) {
      const double l = L.x[L.px[k] + static_cast<std::ptrdiff_t>(j) * rows + j];
      lo = std::min(lo, l * l);
      hi = std::max(hi, l * l);
    }
  }
  return hi > 0 ? lo / hi : 0;
}

struct CholmodInOrder::Impl {
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
};

CholmodInOrder::CholmodInOrder() : impl_(std::make_unique<Impl>()) {}
CholmodInOrder::~CholmodInOrder() = default;

bool CholmodInOrder::factorize(const Eigen::SparseMatrix<double>& A) {
  Impl& d = *impl_;
  if (d.L) cholmod_free_factor(&d.L, &d.common);
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
  d.L = cholmod_analyze(&view, &d.common);
  if (!d.L) throw SolverError(fmt::format("direct solve: CHOLMOD's analysis failed (status {})", d.common.status));
  // The order must be the given one: the leading-block solves rely on it.
  const auto* perm = static_cast<const int*>(d.L->Perm);
  for (std::size_t k = 0; k < d.L->n; ++k)
    if (perm[k] != static_cast<int>(k)) throw SolverError("direct solve: CHOLMOD reordered a matrix given in order");
  return cholmod_factorize(&view, d.L, &d.common) && d.common.status == CHOLMOD_OK && d.L->minor == d.L->n;
}

void CholmodInOrder::forward(Eigen::MatrixXd& Y) {
  impl_->sweep(CHOLMOD_L, Y);
}

void CholmodInOrder::backward(Eigen::MatrixXd& Y) {
  impl_->sweep(CHOLMOD_Lt, Y);
}

Eigen::MatrixXd CholmodInOrder::trailing_block(Eigen::Index s) const {
  const cholmod_factor* L = impl_->L;
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

double CholmodInOrder::nonzeros() const {
  return impl_->common.lnz;
}

#ifdef MESHPDE_HAVE_BLAS
// The BLAS that CHOLMOD links (Fortran interface; the trailing arguments are the hidden
// lengths of the character arguments).
extern "C" void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha,
                       const double* a, const int* lda, const double* beta, double* c, const int* ldc, std::size_t,
                       std::size_t);

Eigen::MatrixXd lower_gram(const Eigen::MatrixXd& C) {
  const int n = static_cast<int>(C.rows());
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(n, n);
  if (n == 0) return G;
  const double one = 1, zero = 0;
  dsyrk_("L", "N", &n, &n, &one, C.data(), &n, &zero, G.data(), &n, 1, 1);
  return G;
}
#else
Eigen::MatrixXd lower_gram(const Eigen::MatrixXd& C) {
  return C.triangularView<Eigen::Lower>() * C.transpose();
}
#endif

}  // namespace meshpde::detail
