// Heat and wave propagation on a surface (Kim and Rossignac 2004 section 5.1, Fig. 5).
//
//   heat:  u_t = k lap(u) + f           (b1 = 1, g1 = k)
//   wave:  u_tt + b u_t = c^2 lap(u) + f  (alpha = 1, b1 = b, g1 = c^2)
//
// advanced with PdeSession's backward Euler. Sources are vertices held at a value
// (Dirichlet) or point fluxes (a load f_i, in value x area per time). Backward Euler
// damps oscillations slightly: for a mode of angular frequency w the wave energy
// loses a factor 1 / (1 + w^2 dt^2) per step, so keep w dt small (the tests state the
// drift they allow).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

enum class Propagation { Heat, Wave };

struct PropagationParams {
  Propagation equation = Propagation::Heat;
  double dt = 1e-3;  ///< time step (s)
  int steps = 100;
  double diffusivity = 1.0;                     ///< heat: k (length^2 / s)
  double wave_speed = 1.0;                      ///< wave: c (length / s)
  double damping = 0.0;                         ///< wave: b, mass-proportional damping (1 / s)
  std::vector<std::pair<int, double>> fixed{};  ///< (vertex, value) held every step
  std::vector<std::pair<int, double>> flux{};   ///< (vertex, load) applied every step
  Eigen::VectorXd initial{};                    ///< initial values (#V), empty: zero
  Eigen::VectorXd initial_velocity{};           ///< wave: initial u_t (#V), empty: zero
  bool local = false;                           ///< solve on a self-adjusting domain instead of the whole mesh
  CgOptions cg{.tolerance = 1e-10, .max_iterations = 20000};
};

struct PropagationResult {
  Eigen::VectorXd values;    ///< u at the end
  Eigen::VectorXd velocity;  ///< u_t at the end
  long long cg_iterations = 0;
  int max_free_vertices = 0;
};

/// Runs the simulation; `on_step(step, u, u_t)` is called after each step (step = 1..steps).
/// \throw InputError on a bad vertex, size or parameter.
PropagationResult propagate(
    const Mesh& mesh, const FemOperators& ops, const PropagationParams& params,
    const std::function<void(int, const Eigen::VectorXd&, const Eigen::VectorXd&)>& on_step = {});

/// Wave energy 1/2 u_t' M u_t + 1/2 c^2 u' K u (kinetic + elastic).
double wave_energy(const Mesh& mesh, const FemOperators& ops, const Eigen::VectorXd& u, const Eigen::VectorXd& ut,
                   double wave_speed);

/// The same on plain (V, F), on the operators of `laplacian` (build_mesh_operators; Auto
/// as in the (V, F) form of every solve).
inline PropagationResult propagate(
    const Positions& V, const Triangles& F, const PropagationParams& params,
    const std::function<void(int, const Eigen::VectorXd&, const Eigen::VectorXd&)>& on_step = {},
    LaplacianKind laplacian = LaplacianKind::Auto) {
  const MeshOperators mo = build_mesh_operators(Mesh(V, F), laplacian);
  return propagate(mo.mesh, mo.ops, params, on_step);
}
inline double wave_energy(const Positions& V, const Triangles& F, const Eigen::VectorXd& u, const Eigen::VectorXd& ut,
                          double wave_speed, LaplacianKind laplacian = LaplacianKind::Auto) {
  const MeshOperators mo = build_mesh_operators(Mesh(V, F), laplacian);
  return wave_energy(mo.mesh, mo.ops, u, ut, wave_speed);
}

}  // namespace meshpde
