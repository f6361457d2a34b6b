#include "meshpde/pde/step_factor.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/pde/steady_direct.h"

namespace meshpde {

StepFactor::StepFactor(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients,
                       std::vector<int> free, double dt)
    : free_(std::move(free)), dt_(dt), c_(coefficients) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(dt > 0) || !std::isfinite(dt)) throw InputError(fmt::format("time step must be positive, got {}", dt));
  std::vector<int> sorted = free_;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    const int v = sorted[k];
    if (v < 0 || v >= mesh.num_vertices())
      throw InputError(fmt::format("step factor: vertex {} does not exist (the mesh has {})", v, mesh.num_vertices()));
    if (k > 0 && sorted[k - 1] == v) throw InputError(fmt::format("step factor: vertex {} is listed twice", v));
    if (!(ops.mass[v] > 0)) throw InputError(fmt::format("step factor: vertex {} has no area", v));
  }
  // At = cM M + cK Kt: steady_direct's assembly with every stiffness scaled by cK and
  // the foundation g0 raised by cM / cK (both multiplied through by cK).
  const double cM = c_.alpha + c_.b1 * dt, cK = (c_.b2 + dt) * dt;
  const PdeCoefficients scaled{.g0 = cK * c_.g0 + cM, .g1 = cK * c_.g1, .g2 = cK * c_.g2};
  if (!free_.empty()) chol_.factorize(assemble_steady_matrix(mesh, ops, scaled, free_));
  seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace meshpde
