// Steady problems (g0 M + g1 K + g2 K D K) u = f solved directly on a set of free
// vertices, every other vertex held at its given value. The matrix on the free set,
//     Kt_FF = g0 M_FF + g1 K_FF + g2 (K_SF)^T D_S K_SF,   S = F and its one-ring,
// is assembled from the stored K (K D K never appears whole) and factored once; solve()
// then costs two triangular sweeps per right-hand side, for any held values and any
// forcing. This is the path for interpolation, fairing and static drags, where
// Jacobi-CG's iteration count grows like h^-4 (see docs/solvers-measurements.md).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/surface_multigrid.h"

namespace meshpde {

/// Which solver steady problems use:
///  - Auto (the default): on a bi-Laplacian problem without g0, with at least
///    kAutoGlobalFromFreeVertices free vertices and no angle below
///    kAutoMultigridMinAngleDeg around them, the global solver with the surface
///    multigrid, kept where its own rate of convergence says it converges (well-shaped
///    meshes: about three times faster than a factorization) and given up for Direct
///    where it does not; Direct on everything else. The measured rule: docs/solvers-measurements.md,
///    "Auto: which steady solver, by size and by mesh";
///  - Direct: SteadyDirectSolver, a sparse Cholesky factor of Kt_FF;
///  - Iterative: Jacobi-CG (PdeSession::solve_steady), no factorization memory,
///    iteration counts that grow like h^-4;
///  - Global: CG preconditioned by the surface multigrid or the Laplacian factor, chosen
///    per mesh (pde/global_bilaplacian.h, Preconditioner::Auto), to a relative residual
///    of 1e-10: for large free sets, where a factor of Kt_FF costs about 2 KB a vertex
///    and this about 0.7-1 KB. Needs g2 > 0 and g0 = 0.
enum class SteadySolver { Auto, Direct, Iterative, Global };

/// "auto", "direct", "iterative", "global": the names the commands and the Python
/// module take. \throw InputError for any other name.
SteadySolver parse_steady_solver(const std::string& name);
const char* to_string(SteadySolver solver);

/// Auto's size rule: from this many free vertices on, Auto may try the multigrid on a
/// bi-Laplacian problem without g0 (measured: below it the direct solve takes
/// under 0.35 s on the 2-core development machine, little for a try to win back).
inline constexpr int kAutoGlobalFromFreeVertices = 50000;
/// Auto's shape rule: it tries the multigrid only where every triangle touching a free
/// vertex has all its angles at least this large (about the quality that Delaunay
/// refinement guarantees, 20.7 degrees). On every real mesh of the data folder the
/// multigrid's probe gave up (their smallest angles are 0.0002-5.4 degrees, a vessel
/// remeshed to a median angle of 55 degrees included), at a cost of 11-53 % of a
/// direct solve; the rule spares them that.
inline constexpr double kAutoMultigridMinAngleDeg = 20;

/// Whether Auto tries the multigrid: g2 > 0, g0 = 0, at least `global_from` free
/// vertices, and no angle below kAutoMultigridMinAngleDeg in the triangles touching
/// a free vertex.
bool auto_tries_multigrid(const Mesh& mesh, const PdeCoefficients& coefficients, const std::vector<int>& free,
                          int global_from = kAutoGlobalFromFreeVertices);

struct SteadySolveResult {
  Field values;                                ///< u with the free rows solved
  int iterations = 0;                          ///< CG iterations (0 for Direct)
  double relative_residual = 0;                ///< |b - Kt_FF x| / |b|, worst column
  SteadySolver solver = SteadySolver::Direct;  ///< the solver that ran (Direct or Global, never Auto)
  /// Auto on a large problem: the multigrid's iterations before it finished (Global) or
  /// was given up for the direct solve (Direct); 0 where Auto did not try it.
  int multigrid_probe_iterations = 0;
  /// False when an iterative solver (Global, Iterative) stopped short of its tolerance:
  /// `values` then hold its last iterate and `message` says where it stopped. A direct
  /// solve always converges (it throws SolverError when it cannot factor).
  bool converged = true;
  std::string message;  ///< set when not converged
  /// The same as a CG status (Converged or MaxIterations), as the applications report it.
  CgResult cg() const {
    return CgResult{.status = converged ? CgStatus::Converged : CgStatus::MaxIterations,
                    .iterations = iterations,
                    .relative_residual = relative_residual,
                    .message = message};
  }
};

/// Auto's try (needs g2 > 0, g0 = 0): the global solver with the surface multigrid to
/// a relative residual of 1e-10, stopped once its rate predicts more iterations than
/// GlobalBilaplacianParams::max_multigrid_iterations (hand_on_to_factor = false). The
/// answer (solver Global) where it converged; nothing where it was given up or could
/// not be built. `probe_iterations` (optional) gets its iterations either way;
/// `multigrid`: the hierarchy's parameters (the defaults are what Auto uses).
std::optional<SteadySolveResult> try_multigrid_solve(const Mesh& mesh, const FemOperators& ops,
                                                     const PdeCoefficients& coefficients, const std::vector<int>& free,
                                                     const Field& u, int* probe_iterations = nullptr,
                                                     const SurfaceMultigridParams& multigrid = {});

/// The steady problem Kt_FF u_F = -Kt_FH u_H with the held values of u (every vertex
/// not in `free`), by the solver asked for: Direct, Global (relative residual 1e-10),
/// Iterative (Jacobi-CG with `iterative`'s tolerance and cap, started from u's free
/// rows; the others ignore them), or as Auto decides (auto_tries_multigrid with
/// `global_from`, then try_multigrid_solve, else Direct). The one entry point of every
/// steady solve of the applications. Non-convergence of Global or Iterative is the
/// result's `converged`, not an exception.
/// \throw InputError for Global with g2 <= 0 or g0 != 0; SolverError as
///        SteadyDirectSolver, or for an operator that is not positive definite on the
///        free set.
SteadySolveResult solve_steady(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients,
                               const std::vector<int>& free, const Field& u, SteadySolver solver,
                               int global_from = kAutoGlobalFromFreeVertices, const CgOptions& iterative = {});

/// Kt_FF = g0 M_FF + g1 K_FF + g2 (K_SF)^T D_S K_SF (+ diag(extra_diagonal) on the free
/// rows when given, #V values), rows and columns in the order of `free`: the principal
/// submatrix of the whole-mesh Kt on those vertices. Cost follows the free set.
Eigen::SparseMatrix<double> assemble_steady_matrix(const Mesh& mesh, const FemOperators& ops,
                                                   const PdeCoefficients& coefficients, const std::vector<int>& free,
                                                   const Eigen::VectorXd& extra_diagonal = Eigen::VectorXd());

/// -Kt_{i,v} for every vertex i that Kt couples to v (v and its two rings), as
/// (i, value) pairs: the right-hand side a unit value held at v puts on row i.
/// \throw InputError for a bad vertex.
std::vector<std::pair<int, double>> steady_coupling(const Mesh& mesh, const FemOperators& ops,
                                                    const PdeCoefficients& coefficients, int v);

/// The fill-reducing ordering of SteadyDirectSolver's factor. Mesh:
/// mesh_nested_dissection of the free vertices (solvers/ordering.h), computed from the
/// mesh before the factor, one factor. MeshSplit: the same order, its two top-level
/// parts factored on two threads (SparseCholesky's split factor: a faster
/// factorization, slower solves). Cholmod: CHOLMOD's own choice (AMD, and METIS when
/// AMD's fill is high), the baseline `meshpde bench` compares with, and the factor
/// InterpolationSolver sweeps at every click. Auto (the default): MeshSplit for
/// operators with a bi-Laplacian part (g2 != 0) from kMeshOrderingFrom free vertices
/// when the build has METIS and the factor is CHOLMOD's, else Cholmod. CHOLMOD's
/// analysis of K D K (AMD, then METIS on its two-ring graph) costs about as much as
/// its factorization at 1M vertices, the mesh ordering a tenth of it; for K alone the
/// mesh order's one-layer separators leave 1.4x the fill of CHOLMOD's order on
/// armadillo-43k, and CHOLMOD's analysis is cheap (docs/solvers-measurements.md).
enum class DirectOrdering { Auto, Mesh, MeshSplit, Cholmod };
inline constexpr int kMeshOrderingFrom = 20000;

class SteadyDirectSolver {
 public:
  /// Assembles and factors Kt_FF (+ diag(extra_diagonal) on the free rows, when
  /// given: #V non-negative values, e.g. a per-vertex foundation or the inertia of
  /// an implicit time step). Keeps references to mesh and ops.
  /// `order` (optional): the elimination order of the free vertices (mesh vertex ids)
  /// instead of one computed here, e.g. reuse_ordering() of an earlier solver's
  /// vertex_order() for a free set that changed by a few vertices; where its parts
  /// split it (and the backend is CHOLMOD's, `ordering` Auto or MeshSplit) the two
  /// parts are factored on two threads; with `ordering` Cholmod, one factor with
  /// CHOLMOD's own supernodes (SparseCholesky::set_order). Ignored by the Eigen backend.
  /// \throw InputError for a bad vertex, or an order that is not one of the free set;
  ///        SolverError if a connected part of the free set touches no held vertex
  ///        (and g0 = 0): its values would be undetermined.
  SteadyDirectSolver(const Mesh& mesh, const FemOperators& ops, const PdeCoefficients& coefficients,
                     std::vector<int> free, SparseCholesky::Backend backend = SparseCholesky::Backend::Auto,
                     const Eigen::VectorXd& extra_diagonal = Eigen::VectorXd(),
                     DirectOrdering ordering = DirectOrdering::Auto, const NestedDissection* order = nullptr);

  /// Returns u with the free rows solved; the other rows of u are the held values.
  /// `f` (optional) is the load, #V x m like u.
  Field solve(const Field& u, const Field* f = nullptr) const;
  /// The free rows only (num_free() x m, in the order of the free list): reads u only
  /// at held neighbours, so the cost follows the region, not the mesh.
  Eigen::MatrixXd solve_free(const Field& u, const Field* f = nullptr) const;
  const std::vector<int>& free_vertices() const { return free_; }
  /// Kt_FF^-1 B for right-hand sides given on the free rows (num_free() x m), with the
  /// same iterative refinement and residual reporting as solve_free().
  Eigen::MatrixXd solve_rhs(const Eigen::MatrixXd& B) const;
  /// -Kt_{F,v}: the right-hand side that a unit value held at vertex v (v not free)
  /// puts on the free rows. Nonzero only within two rings of v, so a handle's response
  /// solve_rhs(coupling(v)) costs one solve and no whole-mesh field.
  Eigen::VectorXd coupling(int v) const;
  /// Row of vertex v in the free list, or -1 when v is held.
  int free_index(int v) const { return local_index(v); }

  /// Relative residual |b - Kt_FF x| / |b| of the last solve (worst column), after
  /// iterative refinement; Kt_FF x is computed as the products g2 K^T (D (K x)), not
  /// with the assembled matrix.
  double last_relative_residual() const { return residual_; }
  /// Refinement steps (preconditioned CG steps) the last solve took: 0 when the first
  /// answer met refine_tolerance (solvers/refinement.h, pcg_refined_solve).
  int last_refinements() const { return refinements_; }

  /// Refinement (CG preconditioned by the factor, residuals through the products) runs
  /// while the relative residual exceeds this, at most max_refinements steps.
  double refine_tolerance = 1e-14;
  int max_refinements = 5;
  const SparseCholesky& factor() const { return chol_; }
  /// The factor's elimination order as mesh vertex ids, with its top-level parts when
  /// the factor is split (else parts = {num_free(), 0}): what reuse_ordering() takes
  /// for the next free set. Empty order for the Eigen backend.
  NestedDissection vertex_order() const;
  /// The assembled Kt_FF (num_free() x num_free()).
  const Eigen::SparseMatrix<double>& matrix() const { return A_; }

  /// Conditioning of Kt_FF and what it means for accuracy. A small residual does not
  /// prove a small error: the relative error is bounded by about cond(S Kt_FF S) times
  /// the backward error of the solve (at least the unit roundoff u = 1.1e-16), with
  /// S = diag(Kt_FF)^-1/2 (the scaling that Cholesky's rounding errors do not see, van
  /// der Sluis). Its 1-norm is estimated with Hager and Higham's estimator (a handful of
  /// solves with the existing factor), computed on first call and kept. Measured on
  /// aorta-103k (20 mm region, 8.9 mm drag): intrinsic Delaunay operator 1.9e10 (bound
  /// 2e-6, observed disagreement of two solvers 2e-8), plain cotangent 1.7e14 (bound
  /// 2e-2, observed 2e-4). The bound is a worst case: errors are usually 10-100x smaller.
  struct Conditioning {
    double condition_1 = 0;     ///< estimate of cond_1(S Kt_FF S) (a lower bound, usually within 3x)
    double relative_error = 0;  ///< bound on |x - x_exact| / |x|: cond * max(u, backward error)
    bool sufficient = true;     ///< relative_error <= the requested accuracy
    std::string message;        ///< empty when sufficient, else a sentence for the user
  };
  /// \param accuracy the relative error the caller needs (default 1e-5: a tenth of a
  ///        micrometre on a 10 mm drag); the answer says whether this solve can promise it.
  Conditioning conditioning(double accuracy = 1e-5) const;
  int num_free() const { return static_cast<int>(free_.size()); }

 private:
  const Mesh& mesh_;
  const FemOperators& ops_;
  PdeCoefficients c_;
  std::vector<int> free_;
  std::unordered_map<int, int> local_;  // vertex -> index in free_ (sized to the region, not the mesh)
  int local_index(int v) const {
    const auto it = local_.find(v);
    return it == local_.end() ? -1 : it->second;
  }
  Eigen::SparseMatrix<double> A_;
  SparseCholesky chol_;
  // Kt_FF as the products it is made of, for the residuals of the iterative
  // refinement: g0 M_FF + extra + g1 K_FF + g2 (K_SF)^T D_S K_SF, with K_SF (S = F, then
  // its one ring) kept (about 8 entries a row). The assembled K D K carries rounding of
  // the size eps |K|^T D |K| in its entries, which on meshes with slivers (D = 1/mass
  // large) is far above the products' rounding of K D K x for a smooth x; measured
  // against the residual of the assembled matrix, refinement cannot remove it
  // (docs/solvers-measurements.md, "Accuracy").
  Eigen::SparseMatrix<double, Eigen::RowMajor> K_SF_;
  Eigen::VectorXd g2_D_S_;  // g2 D on S
  // K_SC: row s of K on the held vertices, as (vertex, value) in [held_start_[s],
  // held_start_[s + 1]): the held values' share of the right-hand side.
  std::vector<int> held_start_;
  std::vector<std::pair<int, double>> held_entries_;
  Eigen::VectorXd diagonal_;  // g0 M_FF (+ the extra diagonal) on F
  Eigen::MatrixXd multiply(const Eigen::MatrixXd& X) const;
  mutable double residual_ = 0;
  mutable int refinements_ = 0;
  double a_norm_inf_ = 0;               // ||Kt_FF||_inf, for the backward error
  mutable double backward_error_ = 0;   // normwise backward error of the last solve
  mutable double inverse_norm_1_ = -1;  // estimate of ||A^-1||_1, computed on demand
};

/// The same on plain (V, F), on the operators of `laplacian` (build_mesh_operators; Auto
/// as in the (V, F) form of every solve).
inline SteadySolveResult solve_steady(const Positions& V, const Triangles& F, const PdeCoefficients& coefficients,
                                      const std::vector<int>& free, const Field& u, SteadySolver solver,
                                      LaplacianKind laplacian = LaplacianKind::Auto) {
  const MeshOperators mo = build_mesh_operators(Mesh(V, F), laplacian);
  return solve_steady(mo.mesh, mo.ops, coefficients, free, u, solver);
}

}  // namespace meshpde
