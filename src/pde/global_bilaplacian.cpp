#include "meshpde/pde/global_bilaplacian.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <functional>

#include "free_parts.h"
#include "meshpde/core/errors.h"
#include "meshpde/solvers/surface_multigrid.h"

namespace meshpde {

GlobalBilaplacianResult solve_global_bilaplacian(const Mesh& mesh, const FemOperators& ops,
                                                 const std::vector<int>& free, const Field& u,
                                                 const GlobalBilaplacianParams& p) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const int nv = mesh.num_vertices(), n = static_cast<int>(free.size()), m = static_cast<int>(u.cols());
  if (!(p.g2 > 0) || !(p.g1 >= 0)) throw InputError("the global bi-Laplacian solver needs g2 > 0 and g1 >= 0");
  if (p.probe_iterations < 1 || !(p.max_multigrid_iterations > 0))
    throw InputError(
        "the global bi-Laplacian solver's Auto rule needs probe_iterations >= 1 and max_multigrid_iterations > 0");
  if (u.rows() != nv) throw InputError(fmt::format("values have {} rows for {} vertices", u.rows(), nv));
  std::vector<int> local(nv, -1);
  for (int k = 0; k < n; ++k) {
    const int v = free[k];
    if (v < 0 || v >= nv || local[v] >= 0) throw InputError(fmt::format("free vertex {} is invalid or repeated", v));
    local[v] = k;
  }
  // A part of the free set that no held vertex touches makes either preconditioner
  // fail without saying where: name it first.
  detail::require_held_parts(
      mesh, free, [&](int v) { return local[v]; }, [](int) { return false; });
  Eigen::VectorXd d(nv);
  for (int i = 0; i < nv; ++i) d[i] = ops.D(i);
  // Right-hand side: -(Kt w)_F with w the held values (free entries zero).
  Field w = u;
  for (int v : free) w.row(v).setZero();
  const Field Kw = apply_stiffness(mesh, ops, w);
  Field DKw = Kw;
  for (int i = 0; i < nv; ++i) DKw.row(i) *= d[i];
  const Field KDKw = apply_stiffness(mesh, ops, DKw);
  Eigen::MatrixXd b(n, m);
  for (int k = 0; k < n; ++k) b.row(k) = -(p.g1 * Kw.row(free[k]) + p.g2 * KDKw.row(free[k]));
  GlobalBilaplacianResult res;
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(n, m);
  bool handed_on = false;  // Auto: the factor goes on from the multigrid's iterate
  auto finish = [&] {
    res.values = u;
    for (int k = 0; k < n; ++k) res.values.row(free[k]) = x.row(k);
  };
  if (p.preconditioner != Preconditioner::LaplacianFactor) {
    const auto t_mg = clock::now();
    const BilaplacianMultigrid mg(mesh, ops, free, p.g1, p.g2, p.multigrid);
    res.level_unknowns = mg.level_unknowns();
    res.bytes_per_vertex = (mg.bytes(m) + 8.0 * 5 * m * n) / nv;
    res.setup_seconds = std::chrono::duration<double>(clock::now() - t0).count();
    const auto t1 = clock::now();
    // Auto: from the probe on, judge the multigrid after every iteration k by its rate
    // over the second half of its history, rho = (r_k / r_{k/2})^(1 / (k - k/2)): it
    // predicts k + ln(tolerance / r_k) / ln(rho) iterations in all. The first
    // iterations are left out of the rate because CG's residual can rise in them, and
    // the window follows a stall on a badly shaped mesh, where the rate is good at
    // first and then slows.
    std::function<bool(int, double)> keep_going;
    std::vector<double> history{1.0};  // relative residual after each iteration, from x = 0
    if (p.preconditioner == Preconditioner::Auto)
      keep_going = [&](int k, double r) {
        history.push_back(r);
        if (k < p.probe_iterations) return true;
        const double rho = std::pow(r / history[static_cast<std::size_t>(k / 2)], 1.0 / (k - k / 2));
        res.multigrid_predicted_iterations = rho < 1 ? k + std::log(p.tolerance / r) / std::log(rho) : HUGE_VAL;
        return res.multigrid_predicted_iterations <= p.max_multigrid_iterations;
      };
    Block xb = Block::Zero(n, m);
    const MultigridSolveResult r = mg.solve(Block(b), xb, p.tolerance, p.max_iterations, keep_going);
    x = xb;
    res.iterations = res.multigrid_iterations = r.iterations;
    res.relative_residual = r.relative_residual;
    res.converged = r.converged;
    res.solve_seconds = std::chrono::duration<double>(clock::now() - t1).count();
    res.multigrid_seconds = std::chrono::duration<double>(clock::now() - t_mg).count();
    handed_on = p.preconditioner == Preconditioner::Auto && !r.converged && r.iterations < p.max_iterations;
    if (!handed_on) {
      res.used = Preconditioner::Multigrid;
      finish();
      return res;
    }
    // The multigrid's hierarchy is released here, before the factor is built.
  }
  res.used = Preconditioner::LaplacianFactor;
  const auto t_factor = clock::now();
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  // K_FF: the free rows and columns of K, for the preconditioner.
  std::vector<Eigen::Triplet<double>> tf;
  for (int k = 0; k < n; ++k) {
    const int i = free[k];
    tf.emplace_back(k, k, ops.Kii[i]);
    for (int q = off[i]; q < off[i + 1]; ++q)
      if (local[nbr[q]] >= 0) tf.emplace_back(k, local[nbr[q]], ops.Kij[q]);
  }
  Eigen::SparseMatrix<double> KFF(n, n);
  KFF.setFromTriplets(tf.begin(), tf.end());
  SparseCholesky chol;
  chol.factorize(KFF);
  res.factor_nonzeros = chol.factor_nonzeros();
  res.bytes_per_vertex = std::max(
      res.bytes_per_vertex,
      (12.0 * res.factor_nonzeros + 12.0 * static_cast<double>(KFF.nonZeros()) + 8.0 * 5 * m * n + 8.0 * 4 * m * nv) /
          nv);
  Eigen::VectorXd mass_f(n);
  for (int k = 0; k < n; ++k) mass_f[k] = ops.mass[free[k]];
  // (g1 K + g2 K D K)_FF x, matrix-free over the whole mesh (the free set is nearly all
  // of it here): scatter x into a field that is zero on held vertices, apply K (both
  // cores for large meshes), scale by D, apply K again, gather the free rows.
  Field full = Field::Zero(nv, m), kx(nv, m), dkx(nv, m), kdkx(nv, m);
  const std::vector<int> all = [&] {
    std::vector<int> a(static_cast<std::size_t>(nv));
    for (int i = 0; i < nv; ++i) a[static_cast<std::size_t>(i)] = i;
    return a;
  }();
  auto apply = [&](const Eigen::MatrixXd& xs) -> Eigen::MatrixXd {
    for (int k = 0; k < n; ++k) full.row(free[k]) = xs.row(k);
    apply_stiffness_rows(mesh, ops, full.data(), kx.data(), m, all);
    dkx.noalias() = d.asDiagonal() * kx;
    apply_stiffness_rows(mesh, ops, dkx.data(), kdkx.data(), m, all);
    Eigen::MatrixXd y(n, m);
    for (int k = 0; k < n; ++k) y.row(k) = p.g2 * kdkx.row(free[k]) + p.g1 * kx.row(free[k]);
    return y;
  };
  auto precondition = [&](const Eigen::MatrixXd& r) -> Eigen::MatrixXd {
    return chol.solve(mass_f.asDiagonal() * chol.solve(r)) / p.g2;
  };
  // The right-hand side's time is in the multigrid's set-up when Auto handed on.
  res.setup_seconds += std::chrono::duration<double>(clock::now() - (handed_on ? t_factor : t0)).count();
  const auto t1 = clock::now();
  // Block PCG: every component its own step lengths, one operator application for all;
  // from the multigrid's iterate when Auto handed the solve on.
  Eigen::MatrixXd r = handed_on ? Eigen::MatrixXd(b - apply(x)) : b;
  Eigen::MatrixXd z = precondition(r), pdir = z;
  Eigen::VectorXd bn = b.colwise().norm().transpose(), rz = (r.cwiseProduct(z)).colwise().sum().transpose();
  auto worst = [&] {
    double rel = 0;
    for (int c = 0; c < m; ++c) rel = std::max(rel, bn[c] > 0 ? r.col(c).norm() / bn[c] : 0.0);
    return rel;
  };
  res.relative_residual = worst();
  while (res.relative_residual > p.tolerance && res.iterations < p.max_iterations) {
    const Eigen::MatrixXd q = apply(pdir);
    for (int c = 0; c < m; ++c) {
      const double pq = pdir.col(c).dot(q.col(c));
      if (!(pq > 0)) continue;  // this component has converged (or is zero)
      const double alpha = rz[c] / pq;
      x.col(c) += alpha * pdir.col(c);
      r.col(c) -= alpha * q.col(c);
    }
    z = precondition(r);
    for (int c = 0; c < m; ++c) {
      const double rz_new = r.col(c).dot(z.col(c));
      pdir.col(c) = z.col(c) + (rz[c] > 0 ? rz_new / rz[c] : 0.0) * pdir.col(c);
      rz[c] = rz_new;
    }
    ++res.iterations;
    res.relative_residual = worst();
    if (!std::isfinite(res.relative_residual)) throw SolverError("global bi-Laplacian solve: the residual became NaN");
  }
  res.converged = res.relative_residual <= p.tolerance;
  finish();
  res.solve_seconds += std::chrono::duration<double>(clock::now() - t1).count();
  return res;
}

}  // namespace meshpde
