// The coefficients of meshpde's PDE (Kim and Rossignac 2004 section 4):
//
//     alpha M u'' + C u' + Kt u = f,   Kt = g0 M + g1 K + g2 K D K,   C = b1 M + b2 Kt
//
// i.e. alpha u_tt - g1 lap(u) + g2 bilap(u) = f with Rayleigh damping and an elastic
// foundation g0 (our addition: it ties every vertex to its rest state, so a
// deformation decays over about (g2 / g0)^(1/4)). Shared by the time stepper
// (pde/pde_session.h) and the steady solvers (pde/steady_direct.h). Units: with K
// dimensionless and M in length^2, g1 has the units of a force per field unit, g2
// those times length^2, g0 those per length^2.
#pragma once

namespace meshpde {

struct PdeCoefficients {
  double alpha = 0;  ///< inertia (mass density); default 0: first order in time (heat-like)
  double b1 = 1;     ///< mass-proportional (Rayleigh) damping; default 1
  double b2 = 0;     ///< stiffness-proportional (Rayleigh) damping; default 0
  double g0 = 0;     ///< elastic foundation (zero-order stiffness); default 0
  double g1 = 1;     ///< Laplacian (membrane) stiffness; default 1
  double g2 = 0;     ///< bi-Laplacian (plate) stiffness; default 0

  bool operator==(const PdeCoefficients&) const = default;
};

}  // namespace meshpde
