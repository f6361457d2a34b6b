// Time stepping and steady solves of
//
//     alpha u_tt - g1 lap(u) + g2 bilap(u) = f
//
// on the active domain of a mesh (Kim and Rossignac 2004 section 4):
//
//     alpha M u'' + C u' + Kt u = f,   Kt = g0 M + g1 K + g2 K D K,   C = b1 M + b2 Kt
//
// g0 (an elastic foundation, 0 by default) is our addition to Kim and Rossignac's PDE: with
// only K and K D K nothing holds a displacement in place (K 1 = 0), so a poke
// spreads without bound and a released surface settles at a rigid offset. g0 M u
// ties every vertex to its rest state, like tissue under a vessel wall, and makes a
// deformation decay over a length of about (g2 / g0)^(1/4) (or (g1 / g0)^(1/2)).
//
// advanced by backward Euler in velocity form, v = u', u^{n+1} = u^n + dt v^{n+1}:
//
//     At v^{n+1} = alpha M v^n - dt Kt u^n + dt f,   At = (alpha + b1 dt) M + (b2 + dt) dt Kt
//
// solved by Jacobi-PCG on the free vertices only, reading constrained and frozen
// values outside them, or, while the free set is one a StepFactor was built for
// (pde/step_factor.h), by that factor's two triangular sweeps. Kt is applied as g0 M u + g1 K u + g2 K (D (K u)); K D K
// is never assembled. Heat: b1 = 1, g1 = k. Wave: alpha = 1, g1 = c^2.
//
// Constraints are added, moved and removed between steps without rebuilding
// anything. The reaction force at a constrained vertex i is
//     f_i = (row_i(At) v - b_i) / dt       (time stepping)
//     f_i = row_i(Kt) u - f_i^ext           (steady solve)
// i.e. the force the constraint must apply to the surface to hold i in place; the
// feedback felt by a probe that holds the vertex is its negative. Units: field units
// times the units of Kt and M (for a displacement in mm with g in N/mm, newtons).
//
// The field u has m components per vertex (1: scalar, 3: displacement or vector);
// all components share every operator application.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/active_domain.h"
#include "meshpde/pde/coefficients.h"
#include "meshpde/pde/step_factor.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

/// How the active domain adjusts itself after each step (Kim and Rossignac 2004 section 4.2).
/// Growth is relative to the current activity, so it does not depend on units;
/// rest is absolute, in the field's units: set it to the precision you care about.
struct DomainOptions {
  bool self_adjusting = false;  ///< grow and shrink automatically after each step
  /// A border vertex pulls its frozen neighbours in when its rate |u'| exceeds this
  /// fraction of the largest rate in the domain and at the constraints (or its
  /// offset from rest exceeds this fraction of the largest offset), unless it is
  /// heading back towards rest (u' . (u - rest) < 0): relaxation never grows the domain.
  double grow_fraction = 1e-3;
  double rest_value = 1e-6;  ///< |u - u_rest| at or below this counts as at rest
  double rest_rate = 1e-4;   ///< |u'| at or below this counts as at rest (per second)
  int rest_steps = 5;        ///< consecutive steps at rest before a vertex leaves
  int seed_rings = 2;        ///< rings freed around a newly constrained vertex
  int max_free = 0;          ///< cap on |A| (0: no cap)
};

struct StepResult {
  CgResult cg;
  int free_vertices = 0;  ///< |A| during the solve
  int grown = 0;          ///< vertices that joined A after the step
  int shrunk = 0;         ///< vertices that left A after the step
  bool factored = false;  ///< solved with the step factor (cg.iterations is then 0)
};

/// What the self-adjusting rule would change after a step (PdeSession::propose_domain_change).
struct DomainChange {
  std::vector<int> grow;    ///< frozen vertices to free
  std::vector<int> shrink;  ///< free vertices at rest to freeze (back to their rest values)
  bool empty() const { return grow.empty() && shrink.empty(); }
};

class PdeSession {
 public:
  /// The session keeps references to `mesh` and `ops`; both must outlive it.
  /// Values start at zero (or `initial`), velocities at zero, every vertex frozen.
  PdeSession(const Mesh& mesh, const FemOperators& ops, int components, PdeCoefficients coefficients = {},
             DomainOptions domain = {});

  PdeSession(PdeSession&&) noexcept;
  PdeSession& operator=(PdeSession&&) noexcept;
  ~PdeSession();

  int components() const;
  const PdeCoefficients& coefficients() const;
  void set_coefficients(const PdeCoefficients& c);
  const DomainOptions& domain_options() const;
  void set_domain_options(const DomainOptions& d);

  /// Current values u (#V x m) and velocities u' (#V x m).
  const Field& values() const;
  const Field& velocities() const;
  /// Replaces values (and sets velocities to zero). Also the rest state when `as_rest`.
  void set_values(const Field& u, bool as_rest = true);
  /// Replaces velocities u' (e.g. an initial impulse for the wave equation).
  void set_velocities(const Field& v);
  /// The state that self-adjusting shrink returns vertices to (default: initial values).
  void set_rest(const Field& rest);

  // --- domain -----------------------------------------------------------------
  const ActiveDomain& domain() const;
  /// Frees the listed vertices (zero-area vertices are skipped: they stay fixed).
  void activate(std::span<const int> vertices);
  void activate_all();
  /// Frees the k-ring neighbourhood of v (not constrained vertices).
  void activate_rings(int v, int k);
  /// Freezes every free vertex.
  void deactivate_all();
  /// What the self-adjusting rule (DomainOptions) would change after the last step,
  /// without changing the domain; advances the rest counters as a self-adjusting step
  /// does (which applies exactly this change, decided on the domain as it was). For a caller that applies the change
  /// later, with set_free_set (apps/haptics.h does, once a step factor for the new free set is ready).
  DomainChange propose_domain_change();
  /// Makes the free set exactly `free` (constrained vertices and vertices without area
  /// in it are skipped). Vertices that leave keep their values (their velocities become 0),
  /// except those listed in `to_rest`, which go back to their rest values.
  /// \throw InputError for a vertex that does not exist.
  void set_free_set(std::span<const int> free, std::span<const int> to_rest = {});

  // --- constraints --------------------------------------------------------------
  /// Prescribes u(v) = value (m entries) from the next step on; frees the seed rings
  /// around v. Moving a constraint is calling this again with a new value.
  void constrain(int v, std::span<const double> value);
  /// Releases v: it becomes free (and keeps its current value and velocity).
  void release(int v);
  std::span<const int> constrained_vertices() const;
  /// Reaction force at each constrained vertex, in constrained_vertices() order,
  /// from the last step or steady solve (#C x m).
  const Field& reaction_forces() const;

  // --- solves ---------------------------------------------------------------------
  /// One backward Euler step of size dt with optional forcing f (#V x m).
  StepResult step(double dt, const Field* f = nullptr);
  /// Steady solve Kt u = f on the free vertices (constrained and frozen held).
  StepResult solve_steady(const Field* f = nullptr);

  CgOptions cg_options;  ///< tolerance and cap of every solve

  /// Steps use `factor` instead of CG while the free set is exactly factor->vertices()
  /// (in any order) and dt and the coefficients are the factor's; other steps (and
  /// steady solves) use CG as before. nullptr: CG only. The factor must have been built
  /// on this session's mesh and operators (only its vertex numbers are checked).
  /// \throw InputError for a vertex the mesh does not have.
  void set_step_factor(std::shared_ptr<const StepFactor> factor);
  const std::shared_ptr<const StepFactor>& step_factor() const;
  /// Whether a step of size dt now would use the step factor.
  bool step_factor_applies(double dt) const;

 private:
  // The state (values, constraints, the domain) and the scratch of the solves, in the
  // implementation file.
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace meshpde
