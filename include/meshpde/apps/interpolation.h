// Scattered-data interpolation over a surface (Kim and Rossignac 2004 section 5.3, Figs. 8-11):
// values given at a few vertices spread smoothly by solving
//     (g1 K + g2 K D K) u = 0   on the other vertices, u = value at the constraints.
// g2 > 0 gives smooth bumps and reproduces linear fields exactly; g1 alone gives
// spikes at the constraints (Kim and Rossignac's Fig. 8). Any mix is allowed.
//
// Tangent vector fields, two ways:
//  - Componentwise (the seed): x, y, z interpolated separately, then each vertex's
//    vector projected onto its tangent plane. Where the surface turns, vectors that
//    point the "same way" along the surface disagree in 3D and partly cancel, so
//    magnitudes collapse.
//  - Connection: directions interpolated with the connection Laplacian
//    (operators/connection.h), which compares vectors after parallel transport, and
//    magnitudes interpolated as a scalar field; the result is direction times
//    magnitude, as in the vector heat method (Sharp et al. 2019), with constraints
//    held exactly. Needs an edge-manifold, consistently oriented mesh.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/topology.h"  // vertex_normals, used by tangent interpolation
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

enum class FieldKind { Scalar, Displacement, Tangent };
enum class TangentMethod { Componentwise, Connection };

struct InterpolationConstraint {
  int vertex = 0;
  Eigen::VectorXd value;  ///< 1 entry for scalars, 3 for displacements and tangent vectors
};

struct InterpolationParams {
  double g1 = 0;  ///< Laplacian (membrane) weight
  double g2 = 1;  ///< bi-Laplacian (thin plate) weight
  TangentMethod method = TangentMethod::Componentwise;
  /// Auto (default: the multigrid on large, well-shaped meshes where it converges, else
  /// Direct: SteadySolver's rule), Direct, Global (large meshes; g2 > 0) or Iterative
  /// (Jacobi-CG), pde/steady_direct.h. Connection-aware tangent directions are always
  /// solved directly.
  SteadySolver solver = SteadySolver::Auto;
  CgOptions cg{.tolerance = 1e-11, .max_iterations = 200000};  ///< for SteadySolver::Iterative
  /// Operators of the overloads without `ops`: Auto (default) takes intrinsic Delaunay
  /// on badly shaped meshes (operators/laplacian.h), where the cotangent K has weights
  /// of 1e9 and more and a direct solve breaks down. Tangent fields always use the
  /// cotangent operators, on the input triangles their normals and connection need.
  LaplacianKind laplacian = LaplacianKind::Auto;
};

struct InterpolationResult {
  Field values;  ///< #V x 1 or #V x 3
  /// Of the (last) solve: iterations (0 for direct) and relative residual; not
  /// converged() when an iterative solver stopped short (values: its last iterate).
  CgResult cg;
  SteadySolver solver = SteadySolver::Direct;      ///< the solver of the (scalar or magnitude) solve: Auto resolved
  LaplacianKind laplacian = LaplacianKind::Cotan;  ///< the operators used (overloads without `ops`)
  std::string laplacian_reason;                    ///< why Auto chose them
};

/// Interpolation with the caller's operators (params.laplacian is not used).
/// \throw InputError (bad vertex, duplicate vertex, wrong value size, g1 = g2 = 0, no
/// constraint), SolverError (breakdown).
InterpolationResult interpolate(const Mesh& mesh, const FemOperators& ops, FieldKind kind,
                                const std::vector<InterpolationConstraint>& constraints,
                                const InterpolationParams& params = {});

/// The same with the operators params.laplacian asks for (what the tool and the Python
/// module run). \throw InputError also for an intrinsic Laplacian asked for a tangent field.
InterpolationResult interpolate(const Mesh& mesh, FieldKind kind,
                                const std::vector<InterpolationConstraint>& constraints,
                                const InterpolationParams& params = {});

/// Interpolation that keeps its factor between solves, for values set and changed one
/// at a time (painting; the stateful tier beside interpolate()). The first solve()
/// factors what A_FF^-1 needs, A = g1 K + g2 K D K on the vertices free then:
///  - without g1 and with at most laplacian_factor_up_to (64) constraints, the
///    Laplacian's free block K_FF; A_FF^-1 is then two solves with it and a correction
///    of rank #constraints (the mixed form of the bi-Laplacian: a one-ring factor
///    instead of a two-ring one, so a faster first solve and a cheaper new vertex;
///    figures in docs/solvers.md, "Painting");
///  - else A_FF itself (SteadyDirectSolver). laplacian_factor() says which.
/// Later solves reuse that factor:
///  - constraints added or removed since the factorization: the factored system is
///    bordered by the changed vertices, a released constraint as an extra unknown and a
///    new one as a Lagrange multiplier holding its value, and the small dense Schur
///    complement S = H - G^T A_FF^-1 G of that border (k x k for k changed vertices)
///    is factored by LU. Once more than max_changes constraints differ from the
///    factored set, or S is close to singular, the next solve() factors afresh, in
///    the last factor's order where the free set changed by at most 5 % (no new
///    fill-reducing ordering: reused_orders()).
///  - what each solve needs from the factor is kept as columns of #free doubles, each
///    solved once (with refinement; a vertex added since the factorization, through the
///    Laplacian's factor, without: its residual lies in its own row) when needed: the
///    column A_FF^-1 G of each vertex that joins the border, and the response of each
///    originally constrained vertex whose value changes (at most 64; beyond, or for many
///    at once, their part of the right-hand side is solved afresh; with at most 16
///    values held at the factorization, theirs are solved with the first solve). A
///    solve on kept columns is dense arithmetic and whole-mesh products, with no solve
///    by the factor: a new value at a painted vertex costs milliseconds, a new vertex
///    one column.
/// Every answer is checked by its residual through the whole-mesh products and refined
/// (a solve with the factor on the residual, through the border) until it is at
/// rounding level, so it equals a fresh interpolate() with the Direct solver to rounding
/// (tests: 1e-10 relative). Memory: the factor and up to max_changes + 64 columns.
///
/// Fields: scalars, displacements and tangent vectors componentwise (3 columns,
/// projected onto the tangent planes); the connection method has no kept factor (use
/// interpolate()). Always the direct solver: params.solver must be Auto or Direct, and
/// params.cg is not used. Zero-area vertices are held at 0, as in interpolate().
class InterpolationSolver {
 public:
  /// With the operators params.laplacian asks for, built here and owned.
  /// \throw InputError for g1 < 0, g2 < 0, both 0, the connection method, or a solver
  ///        other than Auto or Direct.
  InterpolationSolver(const Mesh& mesh, FieldKind kind = FieldKind::Scalar, const InterpolationParams& params = {});
  /// With the caller's operators (params.laplacian is not used); mesh and ops are
  /// referenced and must outlive the solver.
  InterpolationSolver(const Mesh& mesh, const FemOperators& ops, FieldKind kind = FieldKind::Scalar,
                      const InterpolationParams& params = {});
  ~InterpolationSolver();
  InterpolationSolver(InterpolationSolver&&) noexcept;
  InterpolationSolver& operator=(InterpolationSolver&&) noexcept;

  /// Holds `vertex` at `value` (1 number for scalars, 3 otherwise): a new constraint, or
  /// a new value for one already held. \throw InputError for a vertex not in the mesh or
  /// without area, a value of the wrong size or not finite.
  void set_value(int vertex, const Eigen::VectorXd& value);
  /// Frees a constrained vertex. \throw InputError if it is not constrained.
  void remove(int vertex);
  /// Removes every constraint (the factor is kept for the next ones).
  void clear();
  bool constrained(int vertex) const;
  int num_constraints() const;
  /// The constraints in vertex order.
  std::vector<InterpolationConstraint> constraints() const;

  /// The field for the constraints as they are now (cg.iterations: the refinement
  /// steps; cg.relative_residual: |b - A_FF x| / |b| through the products).
  /// \throw InputError without constraints; SolverError where part of the mesh touches
  /// no constraint (its values would be undetermined) or the factorization fails.
  InterpolationResult solve();

  /// Whether the last factorization was of the Laplacian's free block (the mixed form:
  /// g1 = 0, at most laplacian_factor_up_to constraints at the fresh start) rather than
  /// of A_FF.
  bool laplacian_factor() const;
  /// Numeric factorizations so far (one per fresh start).
  int factorizations() const;
  /// Of those, the ones made in the last factor's order (reuse_ordering,
  /// solvers/ordering.h) instead of a new one: a fresh start whose free set differs from
  /// the last factor's by at most 5 % of its vertices.
  int reused_orders() const;
  /// Constraints that differ from the factored set (added or removed since), as of the
  /// last solve(): the size of the Schur complement.
  int changed_constraints() const;
  /// More changed constraints than this and the next solve() factors afresh (the Schur
  /// complement's cost grows with k^2 per solve and k^3 per change). Default 64.
  int max_changes = 64;
  /// A fresh start with at most this many constraints, for g1 = 0, factors the
  /// Laplacian's free block (laplacian_factor()), with more it factors A_FF: the mixed
  /// form keeps a column of #free doubles per constraint and pays a dense product with
  /// them at every solve. 0: always A_FF (the bench's baseline). Default 64.
  int laplacian_factor_up_to = 64;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Parses interpolation constraints, `values` numbers each (1 for scalars, 3 for
/// displacements and tangent vectors), from the text of a constraints file:
///   CSV:  one "vertex,value[,value,value]" a line; `#` starts a comment; a header line
///         is allowed;
///   JSON: {"constraints": [{"vertex": 12 or "@x,y,z", "value": 1 or [x, y, z]}]} or the
///         bare array.
/// A vertex is an index or @X,Y,Z (the nearest vertex). `name` (the file) is quoted in
/// errors with the line or the constraint's number.
/// \throw InputError for malformed text, a vertex not in the mesh, a wrong count of
///        values, a non-finite value, or no constraint at all.
std::vector<InterpolationConstraint> parse_constraints(const Mesh& mesh, const std::string& text, int values,
                                                       const std::string& name);

/// The same with each vertex spec resolved by `vertex` (which throws InputError for a
/// bad one): for a mesh no process holds whole (distributed/), where the caller knows
/// only the vertex count.
std::vector<InterpolationConstraint> parse_constraints(const std::function<int(const std::string&)>& vertex,
                                                       const std::string& text, int values, const std::string& name);

/// The same on plain (V, F) (on the operators of params.laplacian, Auto by default, as in
/// the (V, F) form of every solve).
inline InterpolationResult interpolate(const Positions& V, const Triangles& F, FieldKind kind,
                                       const std::vector<InterpolationConstraint>& constraints,
                                       const InterpolationParams& params = {}) {
  return interpolate(Mesh(V, F), kind, constraints, params);
}

}  // namespace meshpde
