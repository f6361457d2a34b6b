// The bi-Laplacian's free block through the Laplacian's factor (mixed_bilaplacian.h).
#include "mixed_bilaplacian.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "meshpde/core/errors.h"
#include "meshpde/solvers/refinement.h"

namespace meshpde::detail {

namespace {
double positive_g2(double g2) {
  if (!(g2 > 0)) throw InputError(fmt::format("the mixed bi-Laplacian solve needs g2 > 0, not {}", g2));
  return g2;
}

constexpr double kRefineTolerance = 1e-13;
constexpr int kMaxRefinements = 3;
constexpr Eigen::Index kSweptColumns = 4;
}  // namespace

MixedBilaplacianSolver::MixedBilaplacianSolver(const Mesh& mesh, const FemOperators& ops, double g2,
                                               std::vector<int> free, const NestedDissection* order)
    : mesh_(mesh),
      ops_(ops),
      g2_(positive_g2(g2)),
      laplacian_(mesh, ops, PdeCoefficients{.g0 = 0, .g1 = 1, .g2 = 0}, std::move(free), SparseCholesky::Backend::Auto,
                 Eigen::VectorXd(), DirectOrdering::Cholmod, order) {
  const int nv = mesh.num_vertices(), n = num_free();
  for (int v = 0; v < nv; ++v)
    if (ops.mass[v] > 0 && laplacian_.free_index(v) < 0) held_.push_back(v);
  const auto c = static_cast<Eigen::Index>(held_.size());
  const std::vector<int>& F = free_vertices();
  mass_F_.resize(n);
  inverse_mass_F_.resize(n);
  for (int k = 0; k < n; ++k) {
    mass_F_[k] = ops.mass[F[static_cast<std::size_t>(k)]];
    inverse_mass_F_[k] = ops.D(F[static_cast<std::size_t>(k)]);
  }
  inverse_mass_C_.resize(c);
  std::vector<Eigen::Triplet<double>> entries;
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  for (Eigen::Index j = 0; j < c; ++j) {
    const int h = held_[static_cast<std::size_t>(j)];
    inverse_mass_C_[j] = ops.D(h);
    for (int s = off[h]; s < off[h + 1]; ++s)
      if (const int k = laplacian_.free_index(nbr[s]); k >= 0 && ops.Kij[s] != 0)
        entries.emplace_back(static_cast<int>(j), k, ops.Kij[s]);
  }
  K_CF_.resize(c, n);
  K_CF_.setFromTriplets(entries.begin(), entries.end());

  // N_F = K_FF^-1 (-K_FC): the Laplacian solver's coupling of a held vertex is -K_{F,h}.
  Eigen::MatrixXd B(n, c);
  for (Eigen::Index j = 0; j < c; ++j) B.col(j) = laplacian_.coupling(held_[static_cast<std::size_t>(j)]);
  N_.resize(n, c);
  for (Eigen::Index j = 0; j < c; j += kSweptColumns) {
    const Eigen::Index w = std::min<Eigen::Index>(kSweptColumns, c - j);
    N_.middleCols(j, w) = laplacian_.solve_rhs(B.middleCols(j, w));
  }
  Eigen::MatrixXd G = N_.transpose() * mass_F_.asDiagonal() * N_;
  for (Eigen::Index j = 0; j < c; ++j) G(j, j) += ops.mass[held_[static_cast<std::size_t>(j)]];
  G_.compute(G);
  if (G_.info() != Eigen::Success)
    throw SolverError("the mixed bi-Laplacian solve's held-vertex system did not factor");
}

Eigen::VectorXd MixedBilaplacianSolver::coupling(int v) const {
  Eigen::VectorXd b = Eigen::VectorXd::Zero(num_free());
  if (free_index(v) >= 0) throw InputError(fmt::format("vertex {} is free, not held", v));
  // -A_{F,v} = -g2 (K D K)_{F,v}, nonzero within two rings of v.
  for (const auto& [i, value] : steady_coupling(mesh_, ops_, {.g0 = 0, .g1 = 0, .g2 = g2_}, v))
    if (const int k = free_index(i); k >= 0) b[k] = value;
  return b;
}

Eigen::MatrixXd MixedBilaplacianSolver::solve(const Eigen::MatrixXd& B) const {
  if (B.rows() != num_free())
    throw InputError(fmt::format("right-hand side has {} rows for {} free vertices", B.rows(), num_free()));
  if (B.cols() > kSweptColumns) {
    // SparseCholesky sweeps up to four columns with its own loops and hands more to
    // cholmod_solve, about twice as slow a column on surface meshes.
    Eigen::MatrixXd X(B.rows(), B.cols());
    for (Eigen::Index j = 0; j < B.cols(); j += kSweptColumns) {
      const Eigen::Index w = std::min<Eigen::Index>(kSweptColumns, B.cols() - j);
      X.middleCols(j, w) = solve(B.middleCols(j, w));
    }
    return X;
  }
  // A_FF = g2 (K D K)_FF: solve (K D K)_FF X = B / g2.
  const Eigen::MatrixXd Y = laplacian_.factor().solve(B / g2_);
  Eigen::MatrixXd V = Y;
  if (N_.cols() > 0) {
    const Eigen::MatrixXd lambda = -G_.solve(N_.transpose() * (mass_F_.asDiagonal() * Y));
    V.noalias() += N_ * lambda;
  }
  return laplacian_.factor().solve(mass_F_.asDiagonal() * V);
}

Eigen::MatrixXd MixedBilaplacianSolver::multiply(const Eigen::MatrixXd& X) const {
  const Eigen::MatrixXd KX = laplacian_.matrix() * X;
  const Eigen::MatrixXd KCX = K_CF_ * X;
  return g2_ * (laplacian_.matrix() * (inverse_mass_F_.asDiagonal() * KX) +
                K_CF_.transpose() * (inverse_mass_C_.asDiagonal() * KCX));
}

Eigen::MatrixXd MixedBilaplacianSolver::solve_rhs(const Eigen::MatrixXd& B) const {
  if (B.rows() != num_free())
    throw InputError(fmt::format("right-hand side has {} rows for {} free vertices", B.rows(), num_free()));
  // |A|_inf given as 0: the backward error's test then asks for a relative residual of
  // 16 eps, so only the tolerance and a step that fails to lower the residual end it.
  RefinedSolve s = refined_solve(
      B, [&](const Eigen::MatrixXd& R) { return solve(R); },
      [&](const Eigen::MatrixXd& X) -> Eigen::MatrixXd { return multiply(X); }, 0.0, kRefineTolerance, kMaxRefinements);
  return std::move(s.x);
}

}  // namespace meshpde::detail
