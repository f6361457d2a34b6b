#include "meshpde/apps/heat_wave.h"

#include <fmt/format.h>

#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde {

PropagationResult propagate(const Mesh& mesh, const FemOperators& ops, const PropagationParams& p,
                            const std::function<void(int, const Eigen::VectorXd&, const Eigen::VectorXd&)>& on_step) {
  const int nv = mesh.num_vertices();
  if (!(p.dt > 0) || p.steps < 0)
    throw InputError(fmt::format("need dt > 0 and steps >= 0 (dt {}, steps {})", p.dt, p.steps));
  if (p.initial.size() != 0 && p.initial.size() != nv)
    throw InputError(fmt::format("initial values: {} for {} vertices", p.initial.size(), nv));
  if (p.initial_velocity.size() != 0 && p.initial_velocity.size() != nv)
    throw InputError(fmt::format("initial velocity: {} values for {} vertices", p.initial_velocity.size(), nv));
  auto check_vertex = [&](int v, const char* what) {
    if (v < 0 || v >= nv) throw InputError(fmt::format("{} vertex {} does not exist (the mesh has {})", what, v, nv));
  };
  PdeCoefficients c;
  if (p.equation == Propagation::Heat) {
    c = PdeCoefficients{.alpha = 0, .b1 = 1, .b2 = 0, .g0 = 0, .g1 = p.diffusivity, .g2 = 0};
  } else {
    c = PdeCoefficients{.alpha = 1, .b1 = p.damping, .b2 = 0, .g0 = 0, .g1 = p.wave_speed * p.wave_speed, .g2 = 0};
  }
  PdeSession s(mesh, ops, 1, c, DomainOptions{.self_adjusting = p.local});
  s.cg_options = p.cg;
  if (p.initial.size()) s.set_values(p.initial);
  if (p.initial_velocity.size()) s.set_velocities(p.initial_velocity);
  if (p.local) {
    // Start from the vertices that are not at rest, plus the sources.
    std::vector<int> start;
    for (int i = 0; i < nv; ++i)
      if ((p.initial.size() && p.initial[i] != 0) || (p.initial_velocity.size() && p.initial_velocity[i] != 0))
        start.push_back(i);
    s.activate(start);
    for (const auto& [v, rate] : p.flux) {
      check_vertex(v, "flux");
      s.activate_rings(v, 2);
    }
    s.set_rest(Field::Zero(nv, 1));
  } else {
    s.activate_all();
  }
  for (const auto& [v, value] : p.fixed) {
    check_vertex(v, "source");
    s.constrain(v, std::span<const double>(&value, 1));
  }
  Field f;
  if (!p.flux.empty()) {
    f = Field::Zero(nv, 1);
    for (const auto& [v, rate] : p.flux) {
      check_vertex(v, "flux");
      f(v, 0) += rate;
    }
  }
  PropagationResult r;
  for (int k = 1; k <= p.steps; ++k) {
    const StepResult sr = s.step(p.dt, f.size() ? &f : nullptr);
    if (!sr.cg.converged()) throw SolverError(fmt::format("step {}: {}", k, sr.cg.message));
    r.cg_iterations += sr.cg.iterations;
    r.max_free_vertices = std::max(r.max_free_vertices, sr.free_vertices);
    if (on_step) on_step(k, s.values().col(0), s.velocities().col(0));
  }
  r.values = s.values().col(0);
  r.velocity = s.velocities().col(0);
  return r;
}

double wave_energy(const Mesh& mesh, const FemOperators& ops, const Eigen::VectorXd& u, const Eigen::VectorXd& ut,
                   double wave_speed) {
  const Field Ku = apply_stiffness(mesh, ops, Field(u));
  return 0.5 * ut.dot(ops.mass.cwiseProduct(ut)) + 0.5 * wave_speed * wave_speed * u.dot(Ku.col(0));
}

}  // namespace meshpde
