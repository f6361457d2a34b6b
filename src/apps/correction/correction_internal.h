// What the files of the vessel-wall correction share (not installed). The public API is
// meshpde/apps/vessel_correction.h; the files here hold one topic each:
//   options.cpp             methods, boundaries, handles and moves as users write them
//   tissue.cpp              tissue properties, brushes, the operator's weights
//   params.cpp              the rules that resolve a request, and its validation
//   problem.cpp             the region of influence and the handles' terms
//   image_guidance.cpp      edge maps and where a vertex finds its edge
//   springs.cpp             the thesis's method (the baseline)
//   fem_solve.cpp           the finite-element solve, static and dynamic
//   intersection_guard.cpp  steps that keep the surface from intersecting itself
//   correct.cpp             correct_vessel, correction_region, CorrectionPreview
//   session.cpp             CorrectionSession (undo, redo, restore)
//   report.cpp              the JSON report
#pragma once

#include <Eigen/LU>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/pde/steady_direct.h"

namespace meshpde::correction {

// ---- The boundary's foundations --------------------------------------------------

// The fade's elastic foundation (RegionBoundary::Fade): zero within kFadeStart R, then
// kFadeStrength / R^4 (for the plate; / R^2 for the membrane) times the cube of the
// distance beyond, in units of (1 - kFadeStart) R; the free set reaches kFadeReach R.
// Chosen on jittered planes and their subdivisions (a prototype over these three
// numbers): the region's edge then changes the result about three times less from one
// resolution to the next than the clamp does.
inline constexpr double kFadeStart = 0.6, kFadeStrength = 1e3, kFadeReach = 2.0;

// Smooth's foundation: pde/region_boundary.h's SmoothFoundation.

// ---- Resolving a request (params.cpp) --------------------------------------------

bool fades(const CorrectionParams& p);   ///< the fem method with the fade and a radius
bool smooth(const CorrectionParams& p);  ///< the fem method with the smooth boundary and a radius
/// The handles' size (mm) after defaults: CorrectionParams::handle_radius, else a
/// fraction of the radius with the smooth boundary, 0 otherwise; 0 for the springs.
double handle_size(const CorrectionParams& p);
/// Whether a handle is held at its displacement (a vertex of size 0) rather than pulled
/// there by a load.
bool held_handle(const CorrectionHandle& h, double size);
/// Whether every handle is held: the cases the multigrid, global and iterative solvers take.
bool plain_handles(const CorrectionParams& p);
/// Throws InputError naming what is wrong with a request on this mesh.
void validate(const Mesh& mesh, const CorrectionParams& p);
/// The request as the solves read it: an elasticity field's largest value in the
/// scalar's place, and each point handle's vertex set to its nearest corner.
CorrectionParams normalized(const CorrectionParams& p, const Mesh& mesh);

// ---- Tissue (tissue.cpp) ---------------------------------------------------------

/// Vertex v's value of a tissue property: its field's entry, else the scalar.
double tissue_at(const Eigen::VectorXd& field, double scalar, int v);
/// The weights of the fem operator (#V, or empty when every weight is 1).
Eigen::VectorXd operator_weights(const CorrectionParams& p, int nv);

// ---- The problem (problem.cpp) ---------------------------------------------------

/// A handle that a load pulls to its displacement: its terms (pde/handle_load.h: the
/// load's weight at each vertex, where its displacement is read, the vertices it lies
/// on) and the displacement.
struct LoadedHandle : HandleLoad {
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
};

/// What a correction solves for, in the mesh's numbering.
struct FemProblem {
  std::vector<int> region;             ///< vertices that may move, the held handles first
  std::vector<double> distance;        ///< Smooth: each region vertex's surface distance from the handles
  std::vector<int> sources;            ///< one vertex per handle (Fade's distances start there)
  std::vector<CorrectionHandle> held;  ///< vertex handles of size 0, held at their displacement
  std::vector<LoadedHandle> loaded;    ///< the others
  /// Per handle of the request, in its order: where its displacement is read
  /// (CorrectionResult::handle_reading).
  std::vector<std::vector<std::pair<int, double>>> reading;
};

/// The region of influence and the handles' terms of a normalized, valid request.
FemProblem fem_problem(const Mesh& mesh, const CorrectionParams& p);

// ---- Image guidance (image_guidance.cpp) -----------------------------------------

/// The vertices pulled towards an edge (those inside the image that found one) and
/// where each is pulled, in the mesh's frame.
struct ImageTargets {
  std::vector<int> vertices;
  std::vector<Eigen::Vector3d> target;
};

/// The thesis's direction cube (eq. 13.7): the centre of the strongest voxel of the edge
/// map in the cube of g.cube_size voxels around q (q itself when none is in the image).
Eigen::Vector3d strongest_in_cube(const ImageGuidance& g, const Eigen::Vector3d& q);
/// Targets of the vertices `pulled` at positions Q: the nearest ridge of the edge map
/// along each vertex's normal within g.search_radius, or the direction cube's voxel.
ImageTargets find_targets(const ImageGuidance& g, const std::vector<int>& pulled, const Positions& Q,
                          const Eigen::MatrixX3d& normals);
/// The mean edge-map value at the given vertices (those inside the image) at positions Q.
double mean_edge_strength(const ImageGuidance& g, const std::vector<int>& vertices, const Positions& Q);

// ---- The solves (springs.cpp, fem_solve.cpp) -------------------------------------

/// The thesis's springs method over `region`: the displacement (#V x 3, mm).
Field springs(const Mesh& mesh, const CorrectionParams& p, const std::vector<int>& region);

/// The fem solve's operators and free set.
struct FemSetup {
  MeshOperators mo;
  std::vector<int> free;
  double length_scale = 1;  ///< region size in mm, for the dynamic and image scalings
};
FemSetup fem_setup(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem);
/// The boundary's foundation on the diagonal (#V values; zero for the clamp).
Eigen::VectorXd foundations(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const FemSetup& s);

/// The loaded handles' constraints on a factored system: each handle's response U_l to
/// its load (one solve each, held values zero) and S(k, l), handle k's point in response
/// l. A solve's d0 then becomes d0 + sum_l c_l U_l with S c = D - (handle points in d0):
/// the handle points land on their displacements, and the force that puts them there is
/// spread as their loads say (with a point load, the bordered system of a point
/// constraint). Throws InputError when two handles cannot be moved independently.
class HandleConstraints {
 public:
  HandleConstraints(const SteadyDirectSolver& solver, const std::vector<LoadedHandle>& handles, int nv);
  /// d (#V x 3) with the handle points moved by `fraction` of their displacements.
  void apply(Field& d, double fraction) const;
  /// d with handle k's point moved by targets[k].
  void apply(Field& d, const std::vector<Eigen::Vector3d>& targets) const;

 private:
  const std::vector<LoadedHandle>& handles_;
  Field U_;
  Eigen::FullPivLU<Eigen::MatrixXd> lu_;
};

/// The fem displacement (#V x 3, mm) for the handles scaled by `fraction`, solved on a
/// copy of the region and its margin; fills r's solver, residual and accuracy fields.
Field fem_solve(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, double fraction,
                CorrectionResult& r);
/// A request and its problem in a region copy's numbering.
CorrectionParams localized(const RegionCopy& c, const CorrectionParams& p);
FemProblem localized(const RegionCopy& c, const FemProblem& problem);

// ---- Self-intersections (intersection_guard.cpp) ---------------------------------

using TrianglePairs = std::vector<std::pair<int, int>>;
/// The guard's steps for a one-shot field that creates the new intersections `found`:
/// the displacement split into steps that create none, or limited to the largest
/// fraction that creates none. new_pairs(V): the pairs intersecting at V that did not at
/// the start; among(V, pairs): those of `pairs` intersecting at V.
Field guarded_steps(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const Field& one_shot,
                    const TrianglePairs& found, const std::function<TrianglePairs(const Positions&)>& new_pairs,
                    const std::function<TrianglePairs(const Positions&, const TrianglePairs&)>& among,
                    CorrectionResult& r);

// ---- The correction (correct.cpp) ------------------------------------------------

/// correct_vessel, with intersections checked at the vertices `already_moved` too (a
/// session's earlier corrections) and with the caller's checker (or one of its own).
CorrectionResult correct_vessel_impl(const Mesh& mesh, const CorrectionParams& p,
                                     const SelfIntersectionChecker* checker, std::span<const int> already_moved);

}  // namespace meshpde::correction
