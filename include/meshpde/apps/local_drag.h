// Local drag: move one vertex by a displacement and let the surface around it
// follow smoothly (Kim and Rossignac 2004 section 5.3 displacement interpolation; the correction
// of Schoenmaker's thesis in its static form).
//
// The displacement field d (#V x 3) solves the steady problem
//     (g1 K + g2 K D K) d = f   on the region of influence,
// with d = 0 outside the region (the two frozen rings outside make the join C1 for
// g2 > 0), and each handle's point on its displacement: a vertex of size 0 held there
// (f = 0), or a handle with a size (or at a surface point) pulled there by a load f
// spread over it (pde/handle_load.h). Only region vertices are touched.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/handle_load.h"
#include "meshpde/pde/region_boundary.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

struct DragParams {
  int vertex = 0;                                          ///< handle vertex
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  ///< in mesh units (mm for vessels)
  double radius = 0;  ///< region of influence: surface distance from the handle (mesh units); 0: use rings
  int rings = 0;      ///< region of influence in rings of neighbours (used when radius == 0)
  double g1 = 0;      ///< membrane stiffness
  double g2 = 1;      ///< plate (bi-Laplacian) stiffness
  /// How a region given by radius ends (pde/region_boundary.h): Smooth (default; the
  /// corrections' foundation, a DragSession's solve) or Clamp (held at zero outside).
  RegionBoundary boundary = RegionBoundary::Smooth;
  /// The handle's size (DragSessionParams::handle_radius): < 0 (default) a quarter of the
  /// radius with the smooth boundary, 0 otherwise.
  double handle_radius = -1;
  /// Auto (default: with the clamp, the multigrid on large, well-shaped regions where it
  /// converges, else Direct: SteadySolver's rule; Direct with the smooth boundary),
  /// Direct, Global (g2 > 0) or Iterative (both with the clamp only), pde/steady_direct.h
  SteadySolver solver = SteadySolver::Auto;
  CgOptions cg{.tolerance = 1e-10, .max_iterations = 50000};  ///< for SteadySolver::Iterative
};

struct DragResult {
  Positions V;                                         ///< deformed positions
  Field displacement;                                  ///< #V x 3
  std::vector<int> region;                             ///< free vertices of the solve
  int moved_vertices = 0;                              ///< |d| > 1e-6 |displacement|
  double max_displacement = 0;                         ///< largest |d|
  Eigen::Vector3d reaction = Eigen::Vector3d::Zero();  ///< force holding the handle (DragSession::forces)
  CgResult cg;  ///< not converged(): an iterative solver stopped short (its last iterate is given)
  SteadySolver solver = SteadySolver::Iterative;  ///< the solver that ran (Auto resolved)
};

// The region is the vertices nearer than the radius on the surface
// (mesh/geodesic_distance.h, the rule of a correction's region), else the ring ball;
// when both radius and rings are given the radius is used. The field is held at zero
// outside it, and with the smooth boundary (the default for a radius) tied inside by
// the corrections' foundation, which takes it and its slope to zero at the radius, with
// a handle of a quarter of the radius by default: the answer is DragSession's with the
// same parameters, and correct_vessel's with the same vertex handle and handle size
// (apps/vessel_correction.h).

/// \throw InputError for a bad vertex or region, or the smooth boundary with solver
///        Global or Iterative; SolverError on a breakdown.
DragResult drag_vertex(const Mesh& mesh, const FemOperators& ops, const DragParams& params);

/// Interactive drags of one or more handles over one region of influence, with the
/// region's factor computed once and reused.
///
/// The displacement is linear in the handles' displacements: d_F = B d_H, with B the
/// region's basis (one column per handle: the response to a unit move of that handle).
/// A held handle (a vertex of size 0 outside the free rows) enters through its coupling,
/// -Kt_FF^-1 Kt_Fh; a handle with a size, at a surface point, or added by add_handle()
/// is a constraint on the free rows (its reading c equals its displacement) met by its
/// load w times a multiplier: with G = Kt_FF^-1 W and S = C^T G, the multipliers are
/// S^-1 (D_c - C^T (held columns) D_h) (forces()). The constructor factors Kt once and
/// solves for all columns in one sweep; then
///   - a drag update (new handle displacements) is the product B d_H: region x handles
///     x 3 multiply-adds, no solve at all;
///   - adding a handle inside the region costs one solve with the same factor and the
///     small system S again, no refactorization;
///   - growing or shrinking the region by rings builds the new region's factor, except
///     for one ring factored in advance: with DragSessionParams::margin the set-up also
///     factors one ring outside the region, ordered last, and with inner_margin it
///     orders the region's own outermost ring last; growing (shrinking) by that ring
///     is then one multi-column solve with the same factor (a leading principal
///     submatrix's Cholesky factor is the leading block of the whole one). A ring given
///     up by shrink() can be grown back the same way. Other changes build a new factor
///     (with new margins).
/// The region is held at zero displacement outside (two frozen rings make the join C1
/// for g2 > 0), as drag_vertex() does, and by default ended inside by the smooth
/// boundary's foundation (DragSessionParams::boundary). The region is ordered by
/// nested dissection from its positions (solvers/ordering.h) and assembled once in
/// that order. Without margins (from 1,000 vertices, with CHOLMOD) the two halves of
/// the top level are factored at the same time (SplitCholesky, split_factor()); with
/// margins the factor is CHOLMOD's supernodal one in exactly the given order
/// (LeadingBlockCholesky; Eigen's simplicial one without CHOLMOD). Solves take all
/// handles' columns in one sweep, with iterative refinement to a relative residual of
/// 1e-12 or a backward-stable answer (solvers/refinement.h).
struct DragSessionParams {
  /// Region: the surface within this distance of the handles (mesh units; Smooth) or of
  /// the first handle (Clamp); 0: use rings. Default 0.
  double radius = 0;
  /// Each handle's size with the smooth boundary (mesh units; pde/handle_load.h): < 0
  /// (default) kHandleRadiusFraction of the radius, as correct_vessel's default; 0: a
  /// vertex handle is held at its displacement and a point handle is a point load. A
  /// vertex handle with a size still moves by exactly its displacement; the load makes
  /// the bump around it smooth. The clamp and regions by rings or lists take 0 only.
  double handle_radius = -1;
  int rings = 0;  ///< region in rings of neighbours of the first handle (when radius == 0); default 0
  double g1 = 0;  ///< membrane stiffness; default 0
  double g2 = 1;  ///< plate (bi-Laplacian) stiffness; default 1
  /// How a region given by radius ends (pde/region_boundary.h): Smooth (default) adds
  /// the corrections' foundation, so that the displacement and its slope reach zero at
  /// the radius on the surface and a drag equals correct_vessel with the same handles and
  /// handle size (the cotangent operators); Clamp holds the field at zero just
  /// outside the region, as sessions did before. Fade is not offered. A region given by
  /// rings or as a vertex list ends by the clamp. With Smooth the region is fixed by the
  /// radius: margins, grow() and shrink() ask for Clamp.
  RegionBoundary boundary = RegionBoundary::Smooth;
  /// Factor one ring outside the region at set-up, ordered last, so that grow(1) needs
  /// no new factor. Costs set-up time: the ring's rows fill in against the region's top
  /// separators, and the factor is one piece, not the two-thread split (10k-vertex
  /// region: set-up 33 ms instead of 20 ms, then growth 3.8 ms instead of 28 ms;
  /// docs/solvers-measurements.md).
  bool margin = false;
  /// Order the region's own outermost ring last, so that shrink(1) needs no new factor
  /// (10k-vertex region: set-up 35 ms, then shrinking 4.1 ms instead of 25 ms; both
  /// margins together: set-up 60 ms).
  bool inner_margin = false;
};

class DragSession {
 public:
  /// \throw InputError for bad handles or region; SolverError if the region's system
  ///        cannot be factored.
  DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles, const DragSessionParams& params);
  /// Handles at vertices and at surface points (the points' after the vertices'; for a
  /// point, handles() gives its triangle's nearest corner). Points need a region given
  /// by radius with the smooth boundary. \throw InputError also for a bad point.
  DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles,
              const std::vector<SurfacePoint>& points, const DragSessionParams& params);
  /// The same on a region given as a vertex list (handles in it are skipped; its
  /// vertices without area too), ended by the clamp; params.radius, params.rings and
  /// params.boundary are not used.
  DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles, const std::vector<int>& region,
              const DragSessionParams& params);
  ~DragSession();
  DragSession(DragSession&&) noexcept;
  DragSession& operator=(DragSession&&) = delete;

  /// Displacements of the free region vertices (rows in the order of region()) for the
  /// handles' displacements (#handles x 3, rows in the order of handles()).
  Eigen::MatrixXd displacements(const Eigen::MatrixXd& handle_displacements) const;
  /// Whole-mesh positions: rest positions plus the displacements of handles and region.
  Positions positions(const Eigen::MatrixXd& handle_displacements) const;
  /// The force on each handle that puts it on its displacement (#handles x 3, rows in
  /// the order of handles(); in the units of the system's rows, (g1 K + g2 K M^-1 K) d):
  /// a constrained handle's multiplier (its load sums to 1); a held vertex's row of the
  /// system applied to the field.
  Eigen::MatrixXd forces(const Eigen::MatrixXd& handle_displacements) const;

  /// Makes a free region vertex a handle of size 0 (appended to handles(), held at its
  /// displacement): one solve with the existing factor and the small system again.
  /// \throw InputError if the vertex is not a free region vertex or a handle already,
  ///        or cannot be moved apart from the other handles.
  void add_handle(int vertex);
  /// Grows the region by `rings` rings of neighbours (\throw InputError with the smooth
  /// boundary, whose region is fixed by its radius): by one ring that is already
  /// factored (the margin, or a ring given up by shrink()) one multi-column solve for
  /// all handles; otherwise a new factor.
  void grow(int rings = 1);
  /// Shrinks the region by its `rings` outermost rings (region vertices next to a held
  /// vertex that is not a handle; those vertices are then held at zero, handles in them
  /// stay handles). With a margin the first shrink by one ring is one multi-column
  /// solve with the same factor; otherwise a new factor. \throw InputError if no free
  /// vertex would be left, or with the smooth boundary.
  void shrink(int rings = 1);

  const std::vector<int>& handles() const { return handles_; }
  /// Per handle, where its displacement is read ((vertex, weight) pairs: the vertex, a
  /// point's corners or the quadratic around it; pde/handle_load.h).
  std::vector<std::vector<std::pair<int, double>>> readings() const;
  /// The handles' size in use (params.handle_radius resolved; 0 for a held vertex).
  double handle_radius() const { return handle_radius_; }
  /// Free vertices of the region: the vertices of handles with a size and of handles
  /// added by add_handle() included (a vertex handle's row of the basis is 1 for itself
  /// and 0 for every other handle).
  const std::vector<int>& region() const { return region_; }
  /// Row of vertex v in region(), or -1.
  int region_index(int v) const;
  const Eigen::MatrixXd& basis() const { return basis_; }  ///< region x handles
  int factorizations() const { return factorizations_; }   ///< factors built so far
  /// Whether the current factor is the two-thread split one (SplitCholesky: a region
  /// of at least 1,000 vertices without margins, CHOLMOD available).
  bool split_factor() const;
  int solves() const { return solves_; }                       ///< solves with a factor so far
  double last_relative_residual() const { return residual_; }  ///< of the last solve, after refinement
  /// The boundary in use: Smooth only for a region given by radius with params.boundary Smooth.
  RegionBoundary boundary() const { return smooth_ ? RegionBoundary::Smooth : RegionBoundary::Clamp; }

 private:
  struct Factor;
  struct Region;  // the region's vertices, the handles' loads and, for Smooth, its foundation
  static Region region_of(const Mesh& mesh, const FemOperators& ops, std::vector<int>& handles,
                          const std::vector<SurfacePoint>& points, const DragSessionParams& params);
  DragSession(const Mesh& mesh, const FemOperators& ops, std::vector<int> handles, const Region& region,
              const DragSessionParams& params);
  void build(std::vector<int> free);
  void activate();  // the region is the factor's current level: region_, handle flags, basis
  void compute_basis();
  // The basis and multipliers from held_columns_ and green_ (the small system S).
  void finish_basis();
  // Whether handle k is a constraint on the free rows (loaded, or a vertex among them).
  bool constrained(std::size_t k) const { return !loads_[k].load.empty() || handle_in_region_[k]; }
  // The handles' indices split: held (coupled through the right-hand side), then
  // constrained (the columns of green_, in this order).
  std::pair<std::vector<std::size_t>, std::vector<std::size_t>> held_and_constrained() const;
  // Vertices of `set` next to a vertex outside it that is neither a handle nor without area.
  std::vector<int> outer_ring(const std::vector<int>& set) const;
  // Up to `rings` rings of neighbours around `from`, leaving out `from` itself, handles
  // outside the region and vertices without area (nearest ring first).
  std::vector<int> rings_around(const std::vector<int>& from, int rings) const;
  Eigen::VectorXd coupling(int v) const;
  Eigen::MatrixXd solve(const Eigen::MatrixXd& b);

  const Mesh& mesh_;
  const FemOperators& ops_;
  DragSessionParams params_;
  std::vector<int> handles_;
  std::vector<bool> handle_in_region_;  // per handle: its vertex is a row of the region
  std::vector<HandleLoad> loads_;       // per handle: its load and reading; empty load: a vertex
  std::vector<bool> at_point_;          // per handle: a surface point (not a vertex)
  double handle_radius_ = 0;
  Eigen::MatrixXd held_columns_;                    // region x held handles: -A^-1 (coupling)
  Eigen::MatrixXd green_;                           // region x constrained handles: A^-1 (load)
  Eigen::MatrixXd multipliers_;                     // constrained handles x handles: their loads' factors
  std::unique_ptr<Factor> factor_;                  // of the region and its margin rings, those last
  std::vector<int> region_;                         // the factored vertices in use: the leading rows
  bool smooth_ = false;                             // the smooth boundary: foundation_ on the diagonal
  std::vector<std::pair<int, double>> foundation_;  // (vertex, kappa(s) M_i) for the region's vertices
  Eigen::MatrixXd basis_;
  int factorizations_ = 0, solves_ = 0;
  double residual_ = 0;
};

/// drag_vertex on plain (V, F), on the operators of `laplacian` (build_mesh_operators;
/// Auto, the default of the (V, F) form of every solve, takes intrinsic Delaunay on
/// badly shaped or non-manifold meshes and the cotangent ones otherwise).
inline DragResult drag_vertex(const Positions& V, const Triangles& F, const DragParams& params,
                              LaplacianKind laplacian = LaplacianKind::Auto) {
  const MeshOperators mo = build_mesh_operators(Mesh(V, F), laplacian);
  return drag_vertex(mo.mesh, mo.ops, params);
}

}  // namespace meshpde
