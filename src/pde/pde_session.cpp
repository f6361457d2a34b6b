#include "meshpde/pde/pde_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "../operators/csr_row.h"
#include "meshpde/core/errors.h"

namespace meshpde {

namespace detail {

// The solve's local system: A then its ring in local numbering, with CSR rows
// restricted to A + ring (exact for CG directions, which vanish outside A). Built once
// per solve so the CG iterations run on contiguous memory.
struct PdeLocalSystem {
  std::vector<int> off, nbr;
  std::vector<double> w, kii, mass, inv_mass;
  std::vector<double> p, k, t, kt;  // local fields, (n + ring) x m
};

}  // namespace detail

struct PdeSession::Impl {
  Impl(const Mesh& mesh, const FemOperators& ops, int components, PdeCoefficients coefficients, DomainOptions domain);

  // What PdeSession's methods do (pde_session.h documents them).
  void set_coefficients(const PdeCoefficients& c);
  void set_values(const Field& u, bool as_rest);
  void set_velocities(const Field& v);
  void set_rest(const Field& rest);
  void activate(std::span<const int> vertices);
  void activate_all();
  void activate_rings(int v, int k);
  void deactivate_all();
  DomainChange propose_domain_change();
  void set_free_set(std::span<const int> free, std::span<const int> to_rest);
  void constrain(int v, std::span<const double> value);
  void release(int v);
  StepResult step(double dt, const Field* f, const CgOptions& cg);
  StepResult solve_steady(const Field* f, const CgOptions& cg);
  void set_step_factor(std::shared_ptr<const StepFactor> factor);
  bool step_factor_applies(double dt) const;

  enum class Mode { Step, Steady };
  // y(rows) = Kt w(rows), reading w on rows and two rings beyond; uses scratch t_, k_.
  void apply_Kt_free(const double* w, double* y);
  StepResult solve(Mode mode, double dt, const Field* f, const CgOptions& cg);
  void adjust_domain(StepResult& r);  // applies propose_domain_change(), counting into r
  double jacobi(int v, double cM, double cK);
  void free_vertex(int v);
  void build_local_system();
  void apply_local(const double* P, double* Y, double cM, double cK);

  const Mesh& mesh_;
  const FemOperators& ops_;
  int m_;
  PdeCoefficients coef_;
  DomainOptions dopt_;
  ActiveDomain domain_;
  Field u_, v_, rest_;
  // Constraints: list, target values (row-aligned), per-vertex slot.
  std::vector<int> cons_;
  Field cons_target_;
  std::vector<int> cons_pos_;
  Field reaction_;
  // Scratch, full size, kept zero outside the domain.
  Field k_full_, t_full_, kt_full_;  // scratch for the right-hand side (global numbering)
  Eigen::VectorXd kdk_diag_;         // lazily computed (NaN = not yet)
  std::vector<int> rest_count_;
  std::vector<int> ring_rows_;  // A followed by A+1, rebuilt per solve
  CgWorkspace ws_;
  detail::PdeLocalSystem local_;
  Field rhs_, sol_;  // per-solve right-hand side and iterate, kept to avoid allocations
  Eigen::VectorXd inv_diag_;
  std::vector<unsigned> visit_mark_;  // activate_rings' visit stamps, one per vertex
  unsigned visit_stamp_ = 0;
  std::vector<int> ring_seen_;  // activate_rings' breadth-first order
  std::vector<int> local_id_;   // vertex -> local index, -1 outside (kept -1 between solves)
  std::shared_ptr<const StepFactor> factor_;
  std::vector<int> factor_row_;  // vertex -> row of the step factor, -1 outside it
  Eigen::MatrixXd factor_rhs_;
};

PdeSession::Impl::Impl(const Mesh& mesh, const FemOperators& ops, int components, PdeCoefficients coefficients,
                       DomainOptions domain)
    : mesh_(mesh), ops_(ops), m_(components), coef_(coefficients), dopt_(domain), domain_(mesh) {
  if (components < 1) throw InputError(fmt::format("a field needs at least one component, got {}", components));
  if (ops.Kii.size() != mesh.num_vertices())
    throw InputError("operators were built for a different mesh (vertex count differs)");
  set_coefficients(coefficients);
  const int nv = mesh.num_vertices();
  u_ = Field::Zero(nv, m_);
  v_ = Field::Zero(nv, m_);
  rest_ = Field::Zero(nv, m_);
  k_full_ = Field::Zero(nv, m_);
  t_full_ = Field::Zero(nv, m_);
  kt_full_ = Field::Zero(nv, m_);
  cons_pos_.assign(nv, -1);
  cons_target_.resize(0, m_);
  reaction_.resize(0, m_);
  kdk_diag_ = Eigen::VectorXd::Constant(nv, std::numeric_limits<double>::quiet_NaN());
  local_id_.assign(nv, -1);
  factor_row_.assign(nv, -1);
  visit_mark_.assign(nv, 0u);
  rest_count_.assign(nv, 0);
}

void PdeSession::Impl::set_coefficients(const PdeCoefficients& c) {
  for (double x : {c.alpha, c.b1, c.b2, c.g0, c.g1, c.g2})
    if (!(x >= 0) || !std::isfinite(x))
      throw InputError(
          fmt::format("PDE coefficients must be finite and non-negative (alpha {}, b1 {}, b2 {}, g0 {}, g1 {}, g2 {})",
                      c.alpha, c.b1, c.b2, c.g0, c.g1, c.g2));
  coef_ = c;
}

void PdeSession::Impl::set_values(const Field& u, bool as_rest) {
  if (u.rows() != u_.rows() || u.cols() != m_)
    throw InputError(fmt::format("values must be {} x {}, got {} x {}", u_.rows(), m_, u.rows(), u.cols()));
  if (!u.allFinite()) throw InputError("values contain NaN or infinity");
  u_ = u;
  v_.setZero();
  if (as_rest) rest_ = u;
}

void PdeSession::Impl::set_velocities(const Field& v) {
  if (v.rows() != v_.rows() || v.cols() != m_)
    throw InputError(fmt::format("velocities must be {} x {}, got {} x {}", v_.rows(), m_, v.rows(), v.cols()));
  if (!v.allFinite()) throw InputError("velocities contain NaN or infinity");
  v_ = v;
}

void PdeSession::Impl::set_rest(const Field& rest) {
  if (rest.rows() != u_.rows() || rest.cols() != m_) throw InputError("rest state has the wrong shape");
  rest_ = rest;
}

void PdeSession::Impl::free_vertex(int v) {
  if (ops_.mass[v] <= 0 || domain_.state(v) == VertexState::Constrained) return;  // zero-area: held fixed
  if (domain_.make_free(v)) rest_count_[v] = 0;
}

void PdeSession::Impl::activate(std::span<const int> vertices) {
  for (int v : vertices) {
    if (v < 0 || v >= mesh_.num_vertices()) throw InputError(fmt::format("vertex {} does not exist", v));
    free_vertex(v);
  }
}

void PdeSession::Impl::activate_all() {
  for (int v = 0; v < mesh_.num_vertices(); ++v) free_vertex(v);
}

void PdeSession::Impl::deactivate_all() {
  const std::vector<int> a(domain_.free_vertices().begin(), domain_.free_vertices().end());
  for (int v : a) domain_.make_frozen(v);
}

void PdeSession::Impl::activate_rings(int v, int k) {
  // Breadth-first search over k rings with a visit stamp (no allocation once the
  // scratch vectors have grown); cost follows the neighbourhood, not the mesh.
  if (++visit_stamp_ == 0) {  // wrapped around: clear the marks once
    std::fill(visit_mark_.begin(), visit_mark_.end(), 0u);
    visit_stamp_ = 1;
  }
  ring_seen_.assign(1, v);
  visit_mark_[v] = visit_stamp_;
  std::size_t begin = 0;
  for (int r = 0; r < k; ++r) {
    const std::size_t end = ring_seen_.size();
    for (std::size_t q = begin; q < end; ++q)
      for (int b : mesh_.neighbors(ring_seen_[q]))
        if (visit_mark_[b] != visit_stamp_) {
          visit_mark_[b] = visit_stamp_;
          ring_seen_.push_back(b);
        }
    begin = end;
  }
  for (int w : ring_seen_)
    if (domain_.state(w) == VertexState::Frozen) free_vertex(w);
}

void PdeSession::Impl::constrain(int v, std::span<const double> value) {
  if (v < 0 || v >= mesh_.num_vertices()) throw InputError(fmt::format("vertex {} does not exist", v));
  if (static_cast<int>(value.size()) != m_)
    throw InputError(fmt::format("constraint at vertex {} has {} components, the field has {}", v, value.size(), m_));
  for (double x : value)
    if (!std::isfinite(x)) throw InputError(fmt::format("constraint at vertex {} is not finite", v));
  // A constraint that is unchanged and already reached needs no seeding (a haptic
  // probe held still re-sends its target every servo step).
  if (cons_pos_[v] >= 0) {
    bool same = true;
    for (int c = 0; c < m_; ++c) same &= cons_target_(cons_pos_[v], c) == value[c] && u_(v, c) == value[c];
    if (same) return;
  }
  if (cons_pos_[v] < 0) {
    domain_.make_constrained(v);
    cons_pos_[v] = static_cast<int>(cons_.size());
    cons_.push_back(v);
    cons_target_.conservativeResize(cons_.size(), m_);
    reaction_.conservativeResize(cons_.size(), m_);
    reaction_.row(cons_pos_[v]).setZero();
  }
  for (int c = 0; c < m_; ++c) cons_target_(cons_pos_[v], c) = value[c];
  activate_rings(v, dopt_.seed_rings);
}

void PdeSession::Impl::release(int v) {
  if (v < 0 || v >= mesh_.num_vertices() || cons_pos_[v] < 0) return;
  const int p = cons_pos_[v], last = static_cast<int>(cons_.size()) - 1;
  cons_[p] = cons_[last];
  cons_target_.row(p) = cons_target_.row(last);
  reaction_.row(p) = reaction_.row(last);
  cons_pos_[cons_[p]] = p;
  cons_.pop_back();
  cons_target_.conservativeResize(last, m_);
  reaction_.conservativeResize(last, m_);
  cons_pos_[v] = -1;
  domain_.make_frozen(v);
  free_vertex(v);
}

double PdeSession::Impl::jacobi(int v, double cM, double cK) {
  double kdk = 0;
  if (coef_.g2 != 0) {
    if (std::isnan(kdk_diag_[v])) kdk_diag_[v] = bilaplacian_diagonal(mesh_, ops_, v);
    kdk = kdk_diag_[v];
  }
  return cM * ops_.mass[v] + cK * (coef_.g0 * ops_.mass[v] + coef_.g1 * ops_.Kii[v] + coef_.g2 * kdk);
}

void PdeSession::Impl::apply_Kt_free(const double* w, double* y) {
  const auto A = domain_.free_vertices();
  const int n = static_cast<int>(A.size());
  double* K = k_full_.data();
  const double* mass = ops_.mass.data();
  const double g0 = coef_.g0, g1 = coef_.g1, g2 = coef_.g2;
  if (g2 != 0) {
    // K w on A and its ring, then D, then K again on A (Kim and Rossignac 2004, Fig. 4).
    double* T = t_full_.data();
    double* KT = kt_full_.data();
    apply_stiffness_rows(mesh_, ops_, w, K, m_, ring_rows_);
    for (int i : ring_rows_) {
      const double d = mass[i] > 0 ? 1.0 / mass[i] : 0.0;
      for (int c = 0; c < m_; ++c) T[m_ * i + c] = d * K[m_ * i + c];
    }
    apply_stiffness_rows(mesh_, ops_, T, KT, m_, A);
    for (int k = 0; k < n; ++k) {
      const int i = A[k];
      for (int c = 0; c < m_; ++c)
        y[m_ * k + c] = g0 * mass[i] * w[m_ * i + c] + g1 * K[m_ * i + c] + g2 * KT[m_ * i + c];
    }
  } else {
    apply_stiffness_rows(mesh_, ops_, w, K, m_, A);
    for (int k = 0; k < n; ++k) {
      const int i = A[k];
      for (int c = 0; c < m_; ++c) y[m_ * k + c] = g0 * mass[i] * w[m_ * i + c] + g1 * K[m_ * i + c];
    }
  }
}

void PdeSession::Impl::build_local_system() {
  detail::PdeLocalSystem& L = local_;
  const int nl = static_cast<int>(ring_rows_.size());
  for (int k = 0; k < nl; ++k) local_id_[ring_rows_[k]] = k;
  L.off.assign(1, 0);
  L.nbr.clear();
  L.w.clear();
  L.kii.resize(nl);
  L.mass.resize(nl);
  L.inv_mass.resize(nl);
  const auto off = mesh_.offsets();
  const auto nbr = mesh_.neighbors();
  for (int k = 0; k < nl; ++k) {
    const int i = ring_rows_[k];
    for (int s = off[i]; s < off[i + 1]; ++s) {
      const int j = local_id_[nbr[s]];
      if (j < 0) continue;
      L.nbr.push_back(j);
      L.w.push_back(ops_.Kij[s]);
    }
    L.off.push_back(static_cast<int>(L.nbr.size()));
    L.kii[k] = ops_.Kii[i];
    L.mass[k] = ops_.mass[i];
    L.inv_mass[k] = ops_.D(i);
  }
  for (int k = 0; k < nl; ++k) local_id_[ring_rows_[k]] = -1;
  const std::size_t size = static_cast<std::size_t>(nl) * m_;
  L.p.assign(size, 0.0);
  L.k.resize(size);
  L.t.resize(size);
  L.kt.resize(size);
}

namespace {

// y(rows 0..n) = K x over the local CSR, three components: the hot kernel of every
// localized step, cloned for AVX2+FMA with a run-time choice (GCC function
// multiversioning), so users' builds stay portable and capable CPUs go faster.
__attribute__((target_clones("arch=x86-64-v3", "default"))) void local_stiffness3(const int* off, const int* nbr,
                                                                                  const double* w, const double* kii,
                                                                                  const double* x, double* y, int n) {
  for (int i = 0; i < n; ++i) detail::csr_row<3>(i, off, nbr, w, kii, x, y);
}

template <int M>
void local_stiffness(const std::vector<int>& off, const std::vector<int>& nbr, const std::vector<double>& w,
                     const std::vector<double>& kii, const double* x, double* y, int n, int m_dyn) {
  if constexpr (M == 3) {
    local_stiffness3(off.data(), nbr.data(), w.data(), kii.data(), x, y, n);
  } else if constexpr (M == 1) {
    for (int i = 0; i < n; ++i) detail::csr_row<1>(i, off.data(), nbr.data(), w.data(), kii.data(), x, y);
  } else {
    for (int i = 0; i < n; ++i)  // any other component count (rare): one pass per component
      for (int c = 0; c < m_dyn; ++c) {
        double a = kii[i] * x[m_dyn * i + c];
        for (int s = off[i]; s < off[i + 1]; ++s) a += w[s] * x[m_dyn * nbr[s] + c];
        y[m_dyn * i + c] = a;
      }
  }
}

template <int M>
void apply_local_impl(const detail::PdeLocalSystem& L, const PdeCoefficients& co, int n, int m_dyn, const double* P,
                      double* Y, double cM, double cK, double* p, double* k, double* t, double* kt) {
  const int m = M > 0 ? M : m_dyn;
  const int nl = static_cast<int>(L.kii.size());
  std::copy_n(P, static_cast<std::size_t>(n) * m, p);  // ring entries stay zero
  if (co.g2 != 0) {
    local_stiffness<M>(L.off, L.nbr, L.w, L.kii, p, k, nl, m);
    for (int i = 0; i < nl; ++i)
      for (int c = 0; c < m; ++c) t[m * i + c] = L.inv_mass[i] * k[m * i + c];
    local_stiffness<M>(L.off, L.nbr, L.w, L.kii, t, kt, n, m);
    const double a1 = cK * co.g1, a2 = cK * co.g2;
    for (int i = 0; i < n; ++i) {
      const double a = (cM + cK * co.g0) * L.mass[i];
      for (int c = 0; c < m; ++c) Y[m * i + c] = a * P[m * i + c] + a1 * k[m * i + c] + a2 * kt[m * i + c];
    }
  } else {
    local_stiffness<M>(L.off, L.nbr, L.w, L.kii, p, k, n, m);
    const double a1 = cK * co.g1;
    for (int i = 0; i < n; ++i) {
      const double a = (cM + cK * co.g0) * L.mass[i];
      for (int c = 0; c < m; ++c) Y[m * i + c] = a * P[m * i + c] + a1 * k[m * i + c];
    }
  }
}

}  // namespace

void PdeSession::Impl::apply_local(const double* P, double* Y, double cM, double cK) {
  detail::PdeLocalSystem& L = local_;
  const int n = domain_.num_free();
  if (m_ == 1)
    apply_local_impl<1>(L, coef_, n, 1, P, Y, cM, cK, L.p.data(), L.k.data(), L.t.data(), L.kt.data());
  else if (m_ == 3)
    apply_local_impl<3>(L, coef_, n, 3, P, Y, cM, cK, L.p.data(), L.k.data(), L.t.data(), L.kt.data());
  else
    apply_local_impl<0>(L, coef_, n, m_, P, Y, cM, cK, L.p.data(), L.k.data(), L.t.data(), L.kt.data());
}

StepResult PdeSession::Impl::step(double dt, const Field* f, const CgOptions& cg) {
  if (!(dt > 0) || !std::isfinite(dt)) throw InputError(fmt::format("time step must be positive, got {}", dt));
  return solve(Mode::Step, dt, f, cg);
}

StepResult PdeSession::Impl::solve_steady(const Field* f, const CgOptions& cg) {
  return solve(Mode::Steady, 0.0, f, cg);
}

StepResult PdeSession::Impl::solve(Mode mode, double dt, const Field* f, const CgOptions& cg) {
  if (f && (f->rows() != u_.rows() || f->cols() != m_))
    throw InputError(fmt::format("forcing must be {} x {}, got {} x {}", u_.rows(), m_, f->rows(), f->cols()));
  const auto A = domain_.free_vertices();
  const int n = static_cast<int>(A.size());
  ring_rows_.assign(A.begin(), A.end());
  ring_rows_.insert(ring_rows_.end(), domain_.ring().begin(), domain_.ring().end());
  const int nc = static_cast<int>(cons_.size());
  const double cM = mode == Mode::Step ? coef_.alpha + coef_.b1 * dt : 0.0;
  const double cK = mode == Mode::Step ? (coef_.b2 + dt) * dt : 1.0;

  // Velocities the constraints impose, and the previous velocities at them.
  Field v_old_c(nc, m_);
  for (int k = 0; k < nc; ++k) {
    const int i = cons_[k];
    v_old_c.row(k) = v_.row(i);
    v_.row(i) = mode == Mode::Step ? Field((cons_target_.row(k) - u_.row(i)) / dt) : Field::Zero(1, m_);
  }

  // Right-hand side on A. Step: b = alpha M v^n - dt Kt z + dt f with z = u^n + (b2 + dt) v_C
  // on the constraints (this folds -At_FC v_C into one Kt application). Steady: we solve for
  // the correction delta of u_F, so b = f - Kt u with u_C at its target.
  Field saved(nc, m_);
  for (int k = 0; k < nc; ++k) {
    const int i = cons_[k];
    saved.row(k) = u_.row(i);
    if (mode == Mode::Step)
      u_.row(i) += (coef_.b2 + dt) * v_.row(i);
    else
      u_.row(i) = cons_target_.row(k);
  }
  Field& b = rhs_;
  Field& x = sol_;
  b.resize(n, m_);
  x.resize(n, m_);
  apply_Kt_free(u_.data(), b.data());
  for (int k = 0; k < nc; ++k) u_.row(cons_[k]) = saved.row(k);
  for (int k = 0; k < n; ++k) {
    const int i = A[k];
    if (mode == Mode::Step) {
      b.row(k) = coef_.alpha * ops_.mass[i] * v_.row(i) - dt * b.row(k);
      if (f) b.row(k) += dt * f->row(i);
      x.row(k) = v_.row(i);  // warm start from the previous velocity
    } else {
      b.row(k) = -b.row(k);
      if (f) b.row(k) += f->row(i);
      x.row(k).setZero();
    }
  }

  StepResult r;
  r.free_vertices = n;
  if (mode == Mode::Step && step_factor_applies(dt)) {
    // Two triangular sweeps in the factor's row order: no iteration, a fixed cost.
    factor_rhs_.resize(n, m_);
    for (int k = 0; k < n; ++k) factor_rhs_.row(factor_row_[A[k]]) = b.row(k);
    const Eigen::MatrixXd X = factor_->solve(factor_rhs_);
    if (!X.allFinite()) {
      for (int k = 0; k < nc; ++k) v_.row(cons_[k]) = v_old_c.row(k);
      throw SolverError("step: the factored solve gave a non-finite value");
    }
    for (int k = 0; k < n; ++k) x.row(k) = X.row(factor_row_[A[k]]);
    r.factored = true;
  } else {
    Eigen::VectorXd& inv_diag = inv_diag_;
    inv_diag.resize(n);
    for (int k = 0; k < n; ++k) {
      const double d = jacobi(A[k], cM, cK);
      inv_diag[k] = d > 0 ? 1.0 / d : 1.0;
    }
    build_local_system();
    auto apply = [&](const Field& P, Field& Y) { apply_local(P.data(), Y.data(), cM, cK); };
    r.cg = pcg(apply, inv_diag, b, x, cg, ws_);
  }

  if (r.cg.status == CgStatus::Breakdown) {
    for (int k = 0; k < nc; ++k) v_.row(cons_[k]) = v_old_c.row(k);
    throw SolverError(r.cg.message);
  }
  // Update the state.
  for (int k = 0; k < n; ++k) {
    const int i = A[k];
    if (mode == Mode::Step) {
      v_.row(i) = x.row(k);
      u_.row(i) += dt * x.row(k);
    } else {
      u_.row(i) += x.row(k);
    }
  }
  for (int k = 0; k < nc; ++k) u_.row(cons_[k]) = cons_target_.row(k);

  // Reaction forces: Kt applied at each constrained vertex to w = u + b2 v (Step) or u
  // (Steady), over its two rings.
  const double s = mode == Mode::Step ? coef_.b2 : 0.0;
  for (int k = 0; k < nc; ++k) {
    const int i = cons_[k];
    for (int c = 0; c < m_; ++c) {
      auto w = [&](int j) { return u_(j, c) + s * v_(j, c); };
      double kt = coef_.g0 * ops_.mass[i] * w(i) + coef_.g1 * stiffness_row(mesh_, ops_, i, w);
      if (coef_.g2 != 0) kt += coef_.g2 * bilaplacian_row(mesh_, ops_, i, w);
      double force = kt - (f ? (*f)(i, c) : 0.0);
      if (mode == Mode::Step)
        force += coef_.alpha * ops_.mass[i] * (v_(i, c) - v_old_c(k, c)) / dt + coef_.b1 * ops_.mass[i] * v_(i, c);
      reaction_(k, c) = force;
    }
  }
  if (mode == Mode::Step && dopt_.self_adjusting) adjust_domain(r);
  return r;
}

void PdeSession::Impl::set_step_factor(std::shared_ptr<const StepFactor> factor) {
  if (factor)
    for (int v : factor->vertices())
      if (v < 0 || v >= mesh_.num_vertices())
        throw InputError(fmt::format("step factor: vertex {} does not exist in this mesh", v));
  if (factor_)
    for (int v : factor_->vertices()) factor_row_[v] = -1;
  factor_ = std::move(factor);
  if (!factor_) return;
  for (std::size_t k = 0; k < factor_->vertices().size(); ++k)
    factor_row_[factor_->vertices()[k]] = static_cast<int>(k);
}

bool PdeSession::Impl::step_factor_applies(double dt) const {
  if (!factor_ || factor_->dt() != dt || !(factor_->coefficients() == coef_)) return false;
  const auto A = domain_.free_vertices();
  if (A.empty() || A.size() != factor_->vertices().size()) return false;
  for (int v : A)
    if (factor_row_[v] < 0) return false;
  return true;  // as many free vertices as factor rows, each one of them: the same set
}

void PdeSession::Impl::set_free_set(std::span<const int> free, std::span<const int> to_rest) {
  const int nv = mesh_.num_vertices();
  for (int v : free)
    if (v < 0 || v >= nv) throw InputError(fmt::format("vertex {} does not exist", v));
  for (int v : to_rest)
    if (v < 0 || v >= nv) throw InputError(fmt::format("vertex {} does not exist", v));
  if (++visit_stamp_ == 0) {
    std::fill(visit_mark_.begin(), visit_mark_.end(), 0u);
    visit_stamp_ = 1;
  }
  for (int v : free) visit_mark_[v] = visit_stamp_;
  const std::vector<int> current(domain_.free_vertices().begin(), domain_.free_vertices().end());
  for (int v : current)
    if (visit_mark_[v] != visit_stamp_) {
      domain_.make_frozen(v);
      v_.row(v).setZero();  // a frozen vertex does not move; freed again, it starts at rest
    }
  for (int v : free) free_vertex(v);
  for (int v : to_rest)
    if (domain_.state(v) == VertexState::Frozen) {
      u_.row(v) = rest_.row(v);
      v_.row(v).setZero();
    }
}

void PdeSession::Impl::adjust_domain(StepResult& r) {
  // Decided on the domain as it was after the step, then applied: the outcome does not
  // depend on the order of the free list, and a caller can apply the same proposal
  // later (propose_domain_change, set_free_set).
  const DomainChange change = propose_domain_change();
  for (int i : change.shrink) {
    u_.row(i) = rest_.row(i);
    v_.row(i).setZero();
    domain_.make_frozen(i);
  }
  for (int w : change.grow) free_vertex(w);
  r.grown = static_cast<int>(change.grow.size());
  r.shrunk = static_cast<int>(change.shrink.size());
}

DomainChange PdeSession::Impl::propose_domain_change() {
  DomainChange change;
  double v_ref = 0, u_ref = 0;
  auto rate = [&](int i) { return v_.row(i).norm(); };
  auto offset = [&](int i) { return (u_.row(i) - rest_.row(i)).norm(); };
  for (int i : domain_.free_vertices()) {
    v_ref = std::max(v_ref, rate(i));
    u_ref = std::max(u_ref, offset(i));
  }
  for (int i : cons_) {
    v_ref = std::max(v_ref, rate(i));
    u_ref = std::max(u_ref, offset(i));
  }
  const double grow_rate = std::max(dopt_.grow_fraction * v_ref, dopt_.rest_rate);
  const double grow_value = std::max(dopt_.grow_fraction * u_ref, dopt_.rest_value);
  if (++visit_stamp_ == 0) {  // marks the proposed growth: each vertex once
    std::fill(visit_mark_.begin(), visit_mark_.end(), 0u);
    visit_stamp_ = 1;
  }
  for (int i : domain_.free_vertices()) {
    // Growth follows a disturbance that spreads: a border vertex heading back towards
    // rest (v . (u - rest) < 0, as everywhere after a release) recruits nobody.
    const bool receding = v_.row(i).dot(u_.row(i) - rest_.row(i)) < 0;
    const bool moving = !receding && (rate(i) > grow_rate || offset(i) > grow_value);
    if (moving) {
      rest_count_[i] = 0;
      if (!domain_.on_border(i)) continue;
      for (int w : mesh_.neighbors(i)) {
        if (dopt_.max_free > 0 && domain_.num_free() + static_cast<int>(change.grow.size()) >= dopt_.max_free) break;
        if (domain_.state(w) == VertexState::Frozen && ops_.mass[w] > 0 && visit_mark_[w] != visit_stamp_) {
          visit_mark_[w] = visit_stamp_;
          change.grow.push_back(w);
        }
      }
    } else if (offset(i) <= dopt_.rest_value && rate(i) <= dopt_.rest_rate) {
      if (++rest_count_[i] >= dopt_.rest_steps) change.shrink.push_back(i);
    } else {
      rest_count_[i] = 0;
    }
  }
  return change;
}

// ---- PdeSession: the state lives in Impl --------------------------------------------

PdeSession::PdeSession(const Mesh& mesh, const FemOperators& ops, int components, PdeCoefficients coefficients,
                       DomainOptions domain)
    : impl_(std::make_unique<Impl>(mesh, ops, components, coefficients, domain)) {}
PdeSession::PdeSession(PdeSession&&) noexcept = default;
PdeSession& PdeSession::operator=(PdeSession&&) noexcept = default;
PdeSession::~PdeSession() = default;

int PdeSession::components() const {
  return impl_->m_;
}
const PdeCoefficients& PdeSession::coefficients() const {
  return impl_->coef_;
}
void PdeSession::set_coefficients(const PdeCoefficients& c) {
  impl_->set_coefficients(c);
}
const DomainOptions& PdeSession::domain_options() const {
  return impl_->dopt_;
}
void PdeSession::set_domain_options(const DomainOptions& d) {
  impl_->dopt_ = d;
}
const Field& PdeSession::values() const {
  return impl_->u_;
}
const Field& PdeSession::velocities() const {
  return impl_->v_;
}
void PdeSession::set_values(const Field& u, bool as_rest) {
  impl_->set_values(u, as_rest);
}
void PdeSession::set_velocities(const Field& v) {
  impl_->set_velocities(v);
}
void PdeSession::set_rest(const Field& rest) {
  impl_->set_rest(rest);
}
const ActiveDomain& PdeSession::domain() const {
  return impl_->domain_;
}
void PdeSession::activate(std::span<const int> vertices) {
  impl_->activate(vertices);
}
void PdeSession::activate_all() {
  impl_->activate_all();
}
void PdeSession::activate_rings(int v, int k) {
  impl_->activate_rings(v, k);
}
void PdeSession::deactivate_all() {
  impl_->deactivate_all();
}
DomainChange PdeSession::propose_domain_change() {
  return impl_->propose_domain_change();
}
void PdeSession::set_free_set(std::span<const int> free, std::span<const int> to_rest) {
  impl_->set_free_set(free, to_rest);
}
void PdeSession::constrain(int v, std::span<const double> value) {
  impl_->constrain(v, value);
}
void PdeSession::release(int v) {
  impl_->release(v);
}
std::span<const int> PdeSession::constrained_vertices() const {
  return impl_->cons_;
}
const Field& PdeSession::reaction_forces() const {
  return impl_->reaction_;
}
StepResult PdeSession::step(double dt, const Field* f) {
  return impl_->step(dt, f, cg_options);
}
StepResult PdeSession::solve_steady(const Field* f) {
  return impl_->solve_steady(f, cg_options);
}
void PdeSession::set_step_factor(std::shared_ptr<const StepFactor> factor) {
  impl_->set_step_factor(std::move(factor));
}
const std::shared_ptr<const StepFactor>& PdeSession::step_factor() const {
  return impl_->factor_;
}
bool PdeSession::step_factor_applies(double dt) const {
  return impl_->step_factor_applies(dt);
}

}  // namespace meshpde
