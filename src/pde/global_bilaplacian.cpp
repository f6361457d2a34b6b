#include "meshpde/pde/global_bilaplacian.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <functional>

#include "free_parts.h"
#include "meshpde/core/errors.h"
#include "meshpde/solvers/cg.h"
#include "meshpde/solvers/surface_multigrid.h"

namespace meshpde {

namespace {

using clock_type = std::chrono::steady_clock;

double seconds_since(clock_type::time_point t) {
  return std::chrono::duration<double>(clock_type::now() - t).count();
}

}  // namespace

struct GlobalBilaplacianSolver::Impl {
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;

  const Mesh& mesh;
  const FemOperators& ops;
  std::vector<int> free;
  GlobalBilaplacianParams p;
  int nv = 0, n = 0;
  std::vector<int> local;  // index in `free` of each vertex, -1 for held ones
  Eigen::VectorXd d;       // D on every vertex
  // Built by the first solve that needs them and kept: the multigrid hierarchy while
  // it serves, the factor of K_FF (with its mass and size) once it is used.
  std::unique_ptr<BilaplacianMultigrid> multigrid;
  std::unique_ptr<SparseCholesky> factor;
  Eigen::VectorXd mass_f;
  std::vector<int> all;  // every vertex: the rows of the factor path's whole-mesh applies
  double factor_nonzeros = 0, kff_nonzeros = 0;
  bool factor_only = false;  // LaplacianFactor asked for, or Auto after a hand-on
  int multigrid_builds = 0, factorizations = 0;

  Impl(const Mesh& m, const FemOperators& o, std::vector<int> f, const GlobalBilaplacianParams& params)
      : mesh(m), ops(o), free(std::move(f)), p(params) {
    nv = mesh.num_vertices();
    n = static_cast<int>(free.size());
    if (!(p.g2 > 0) || !(p.g1 >= 0)) throw InputError("the global bi-Laplacian solver needs g2 > 0 and g1 >= 0");
    if (p.probe_iterations < 1 || !(p.max_multigrid_iterations > 0))
      throw InputError(
          "the global bi-Laplacian solver's Auto rule needs probe_iterations >= 1 and max_multigrid_iterations > 0");
    local.assign(static_cast<std::size_t>(nv), -1);
    for (int k = 0; k < n; ++k) {
      const int v = free[static_cast<std::size_t>(k)];
      if (v < 0 || v >= nv || local[static_cast<std::size_t>(v)] >= 0)
        throw InputError(fmt::format("free vertex {} is invalid or repeated", v));
      local[static_cast<std::size_t>(v)] = k;
    }
    // A part of the free set that no held vertex touches makes either preconditioner
    // fail without saying where: name it first.
    detail::require_held_parts(
        mesh, free, [&](int v) { return local[static_cast<std::size_t>(v)]; }, [](int) { return false; });
    d.resize(nv);
    for (int i = 0; i < nv; ++i) d[i] = ops.D(i);
    factor_only = p.preconditioner == Preconditioner::LaplacianFactor;
  }

  // The Cholesky factor of K_FF (the free rows and columns of K), once.
  void build_factor() {
    if (factor) return;
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    std::vector<Eigen::Triplet<double>> tf;
    for (int k = 0; k < n; ++k) {
      const int i = free[static_cast<std::size_t>(k)];
      tf.emplace_back(k, k, ops.Kii[i]);
      for (int q = off[i]; q < off[i + 1]; ++q)
        if (local[static_cast<std::size_t>(nbr[q])] >= 0)
          tf.emplace_back(k, local[static_cast<std::size_t>(nbr[q])], ops.Kij[q]);
    }
    Eigen::SparseMatrix<double> KFF(n, n);
    KFF.setFromTriplets(tf.begin(), tf.end());
    auto f = std::make_unique<SparseCholesky>();
    f->factorize(KFF);
    factor_nonzeros = f->factor_nonzeros();
    kff_nonzeros = static_cast<double>(KFF.nonZeros());
    mass_f.resize(n);
    for (int k = 0; k < n; ++k) mass_f[k] = ops.mass[free[static_cast<std::size_t>(k)]];
    all.resize(static_cast<std::size_t>(nv));
    for (int i = 0; i < nv; ++i) all[static_cast<std::size_t>(i)] = i;
    factor = std::move(f);
    ++factorizations;
  }

  GlobalBilaplacianResult solve(const Field& u, bool warm_start) {
    const auto t0 = clock_type::now();
    const int m = static_cast<int>(u.cols());
    if (u.rows() != nv) throw InputError(fmt::format("values have {} rows for {} vertices", u.rows(), nv));
    // Right-hand side: -(Kt w)_F with w the held values (free entries zero).
    Field w = u;
    for (int v : free) w.row(v).setZero();
    const Field Kw = apply_stiffness(mesh, ops, w);
    Field DKw = Kw;
    for (int i = 0; i < nv; ++i) DKw.row(i) *= d[i];
    const Field KDKw = apply_stiffness(mesh, ops, DKw);
    Eigen::MatrixXd b(n, m);
    for (int k = 0; k < n; ++k) {
      const int v = free[static_cast<std::size_t>(k)];
      b.row(k) = -(p.g1 * Kw.row(v) + p.g2 * KDKw.row(v));
    }
    GlobalBilaplacianResult res;
    Eigen::MatrixXd x = Eigen::MatrixXd::Zero(n, m);
    if (warm_start)
      for (int k = 0; k < n; ++k) {
        const int v = free[static_cast<std::size_t>(k)];
        if (!u.row(v).allFinite())
          throw InputError(fmt::format("the starting value of free vertex {} is not finite", v));
        x.row(k) = u.row(v);
      }
    bool handed_on = false;  // Auto: the factor goes on from the multigrid's iterate
    auto finish = [&] {
      res.values = u;
      for (int k = 0; k < n; ++k) res.values.row(free[static_cast<std::size_t>(k)]) = x.row(k);
    };
    if (!factor_only) {
      const auto t_mg = clock_type::now();
      if (!multigrid) {
        multigrid = std::make_unique<BilaplacianMultigrid>(mesh, ops, free, p.g1, p.g2, p.multigrid);
        ++multigrid_builds;
      }
      const BilaplacianMultigrid& mg = *multigrid;
      res.level_unknowns = mg.level_unknowns();
      res.bytes_per_vertex = (mg.bytes(m) + 8.0 * 5 * m * n) / nv;
      res.setup_seconds = seconds_since(t0);
      const auto t1 = clock_type::now();
      // Auto: from the probe on, judge the multigrid after every iteration k by its rate
      // over the second half of its history, rho = (r_k / r_{k/2})^(1 / (k - k/2)): it
      // predicts k + ln(tolerance / r_k) / ln(rho) iterations in all. The first
      // iterations are left out of the rate because CG's residual can rise in them, and
      // the window follows a stall on a badly shaped mesh, where the rate is good at
      // first and then slows.
      Field xb = x;
      std::function<bool(int, double)> keep_going;
      // Relative residual at the start (1 from zero, less from a warm start) and after
      // each iteration, as the multigrid's solve reports them.
      std::vector<double> history;
      if (p.preconditioner == Preconditioner::Auto)
        keep_going = [&](int k, double r) {
          history.push_back(r);
          if (k < p.probe_iterations) return true;
          const double rho = std::pow(r / history[static_cast<std::size_t>(k / 2)], 1.0 / (k - k / 2));
          res.multigrid_predicted_iterations = rho < 1 ? k + std::log(p.tolerance / r) / std::log(rho) : HUGE_VAL;
          return res.multigrid_predicted_iterations <= p.max_multigrid_iterations;
        };
      const MultigridSolveResult r = mg.solve(Field(b), xb, p.tolerance, p.max_iterations, keep_going);
      x = xb;
      res.iterations = res.multigrid_iterations = r.iterations;
      res.relative_residual = r.relative_residual;
      res.converged = r.converged;
      res.solve_seconds = seconds_since(t1);
      res.multigrid_seconds = seconds_since(t_mg);
      handed_on = p.preconditioner == Preconditioner::Auto && !r.converged && r.iterations < p.max_iterations;
      if (!handed_on || !p.hand_on_to_factor) {
        res.used = Preconditioner::Multigrid;
        res.multigrid_given_up = handed_on;
        if (handed_on) multigrid.reset();  // judged too slow: not kept for the next solves
        finish();
        return res;
      }
      // The multigrid's hierarchy is released here, before the factor is built, and the
      // solves after this one start with the factor.
      multigrid.reset();
      factor_only = true;
    }
    res.used = Preconditioner::LaplacianFactor;
    const auto t_factor = clock_type::now();
    build_factor();
    const SparseCholesky& chol = *factor;
    res.factor_nonzeros = factor_nonzeros;
    res.bytes_per_vertex = std::max(
        res.bytes_per_vertex, (12.0 * factor_nonzeros + 12.0 * kff_nonzeros + 8.0 * 5 * m * n + 8.0 * 4 * m * nv) / nv);
    // (g1 K + g2 K D K)_FF x, matrix-free over the whole mesh (the free set is nearly all
    // of it here): scatter x into a field that is zero on held vertices, apply K (both
    // cores for large meshes), scale by D, apply K again, gather the free rows.
    Field full = Field::Zero(nv, m), kx(nv, m), dkx(nv, m), kdkx(nv, m);
    auto apply = [&](const Eigen::MatrixXd& xs) -> Eigen::MatrixXd {
      for (int k = 0; k < n; ++k) full.row(free[static_cast<std::size_t>(k)]) = xs.row(k);
      apply_stiffness_rows(mesh, ops, full.data(), kx.data(), m, all);
      dkx.noalias() = d.asDiagonal() * kx;
      apply_stiffness_rows(mesh, ops, dkx.data(), kdkx.data(), m, all);
      Eigen::MatrixXd y(n, m);
      for (int k = 0; k < n; ++k) {
        const int v = free[static_cast<std::size_t>(k)];
        y.row(k) = p.g2 * kdkx.row(v) + p.g1 * kx.row(v);
      }
      return y;
    };
    auto precondition = [&](const Eigen::MatrixXd& r) -> Eigen::MatrixXd {
      return chol.solve(mass_f.asDiagonal() * chol.solve(r)) / p.g2;
    };
    // The right-hand side's time is in the multigrid's set-up when Auto handed on.
    res.setup_seconds += seconds_since(handed_on ? t_factor : t0);
    const auto t1 = clock_type::now();
    // Block PCG: every component its own step lengths, one operator application for all;
    // from the multigrid's iterate when Auto handed the solve on, or the warm start.
    // The iterations the multigrid ran count against the cap.
    CgOptions options;
    options.tolerance = p.tolerance;
    options.max_iterations = std::max(0, p.max_iterations - res.iterations);
    CgWorkspace workspace;
    Field xf = x;
    const CgResult cg =
        block_pcg([&](const Field& P, Field& Q) { Q = apply(P); },
                  [&](const Field& R, Field& Z) { Z = precondition(R); }, Field(b), xf, options, workspace);
    if (cg.status == CgStatus::Breakdown) throw SolverError("global bi-Laplacian solve: " + cg.message);
    x = xf;
    res.iterations += cg.iterations;
    res.relative_residual = cg.relative_residual;
    res.converged = res.relative_residual <= p.tolerance;
    finish();
    res.solve_seconds += seconds_since(t1);
    return res;
  }
};

GlobalBilaplacianSolver::GlobalBilaplacianSolver(const Mesh& mesh, const FemOperators& ops, std::vector<int> free,
                                                 const GlobalBilaplacianParams& params)
    : impl_(std::make_unique<Impl>(mesh, ops, std::move(free), params)) {}

GlobalBilaplacianSolver::~GlobalBilaplacianSolver() = default;
GlobalBilaplacianSolver::GlobalBilaplacianSolver(GlobalBilaplacianSolver&&) noexcept = default;
GlobalBilaplacianSolver& GlobalBilaplacianSolver::operator=(GlobalBilaplacianSolver&&) noexcept = default;

GlobalBilaplacianResult GlobalBilaplacianSolver::solve(const Field& u, bool warm_start) {
  return impl_->solve(u, warm_start);
}

int GlobalBilaplacianSolver::multigrid_builds() const {
  return impl_->multigrid_builds;
}

int GlobalBilaplacianSolver::factorizations() const {
  return impl_->factorizations;
}

GlobalBilaplacianResult solve_global_bilaplacian(const Mesh& mesh, const FemOperators& ops,
                                                 const std::vector<int>& free, const Field& u,
                                                 const GlobalBilaplacianParams& params) {
  return GlobalBilaplacianSolver(mesh, ops, free, params).solve(u);
}

}  // namespace meshpde
