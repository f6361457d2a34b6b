// Fairing and membranes (Kim and Rossignac 2004 section 5.2, Figs. 6-7): solve the Laplacian
// (order 1, membrane, g1) or bi-Laplacian (order 2, thin plate, g2) equation on the
// vertex coordinates with a selection held fixed.
//
// Static (default): one steady solve Kt x = 0 on the free vertices.
// Regularized (Kim and Rossignac's membrane regularization): `steps` backward Euler steps of
// (b1 M + dt Kt) x^{n+1} = b1 M x^n where K is re-assembled every step from the
// current geometry with each element stiffness weighted by its triangle's area
// (divided by the mean area, so the weights are unit-free): large stiff triangles
// pull small soft ones, evening out the triangulation. The mass term is divided by
// the mean area too, so dt and damping are unit-free.
//
// What it achieves, measured on the bunny half of Fig. 7 (tests/test_apps.cpp): the
// plain membrane crowds the free vertices (area ratio 2.9e8); 15 regularized steps
// spread them (area ratio about 1e2) and the result is still a membrane. But the
// area weighting equalizes areas, not shapes: its smallest angle falls from 7.6 to
// about 0.2 degrees (slivers). Weights (A / mean A)^p for p in [0.25, 1] and slower
// flows did not avoid that once the membrane had formed. Like the seed, which found
// the bi-Laplacian variant fragile, we find the regularization good for vertex
// distribution and bad for angles; an intrinsic Delaunay re-triangulation is the
// remedy where angles matter.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

struct FairParams {
  int order = 2;            ///< 1: membrane (Laplacian), 2: thin plate (bi-Laplacian)
  bool regularize = false;  ///< area-weighted stiffness, re-assembled every step
  double dt = 1.0;          ///< regularization time step (unit-free; seed: 1)
  int steps = 15;           ///< regularization steps
  /// b1 of the regularization steps, relative to the mean triangle area. 0 (default) is
  /// quasi-static: each step re-solves the area-weighted membrane at the current
  /// geometry, which is what Kim and Rossignac's b1 = 0.01 amounts to at its scale (b1 M is
  /// negligible next to dt K there).
  double damping = 0.0;
  /// The static solve's: Auto (default: for order 2 the multigrid on large, well-shaped
  /// meshes where it converges, else Direct: SteadySolver's rule), Direct, Global (order
  /// 2 only) or Iterative; pde/steady_direct.h. Regularized fairing steps by CG.
  SteadySolver solver = SteadySolver::Auto;
  CgOptions cg{.tolerance = 1e-10, .max_iterations = 100000};
  /// Operators of the static solve: Auto (default) takes intrinsic Delaunay on badly
  /// shaped meshes (operators/laplacian.h), where the cotangent K has weights of 1e9
  /// and more and a direct solve breaks down. The regularization re-assembles
  /// area-weighted cotangent operators every step, whatever this says.
  LaplacianKind laplacian = LaplacianKind::Auto;
};

/// Triangle shape statistics.
struct TriangleQuality {
  double min_angle_deg = 0;
  double area_ratio = 0;  ///< largest over smallest non-degenerate area
  /// Counts of A / mean(A) in the bins [0, .01), [.01, .1), [.1, .5), [.5, 1), [1, 2), [2, 10), [10, inf).
  std::vector<int> area_histogram;
  static const std::vector<double>& bin_edges();
};

/// Quality of the listed faces (all faces when `faces` is empty).
TriangleQuality triangle_quality(const Positions& V, const Triangles& F, const std::vector<int>& faces = {});

struct FairResult {
  Positions V;                    ///< faired positions
  TriangleQuality before, after;  ///< over the faces touching a free vertex
  long long cg_iterations = 0;
  double worst_residual = 0;  ///< largest relative residual over the solves
  SteadySolver solver =
      SteadySolver::Iterative;  ///< the solver that ran: Direct or Global (Auto resolved); Iterative for CG
  LaplacianKind laplacian = LaplacianKind::Cotan;  ///< the operators of the static solve
  std::string laplacian_reason;                    ///< why Auto chose them
  /// False when an iterative solve stopped short of its tolerance (Global or Iterative,
  /// or a regularization step's CG): V is then the last iterate (regularized: the
  /// surface before the step that failed), and `message` says where it stopped.
  bool converged = true;
  std::string message;
};

/// \throw InputError if nothing is fixed, a fixed index is out of range, or order is not 1 or 2;
///        SolverError if a solve breaks down (not for non-convergence: FairResult::converged).
FairResult fair(const Mesh& mesh, const std::vector<int>& fixed, const FairParams& params);

}  // namespace meshpde
