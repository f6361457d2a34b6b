// Vessel-wall correction (Schoenmaker, 3D Interactive Mesh Deformation): move handle vertices of a
// segmented vessel surface by displacements in mm and let the wall around them
// follow like tissue, within a region of influence, without self-intersections,
// optionally pulled onto the edges of the patient's image.
//
// Method Fem (ours). The displacement field d (#V x 3, mm) solves
//     (g1 K_w + g2 K_w D K_w) d = f_image + sum_l c_l w_l   on the region of influence,
// d = 0 outside the region (two frozen rings make the join C1 when g2 > 0), and each
// handle's point moving by the user's displacement: w_l is handle l's load (its point,
// or a smooth bump of the handle's size around it) and the c_l are what it takes to
// put every handle point on its displacement (see CorrectionHandle); a vertex handle of
// size 0 is simply held. K_w is the stiffness with the per-vertex tissue stiffness w
// averaged per triangle (a stiffer carina: w > 1 there). The operator is the intrinsic
// Delaunay one on badly shaped meshes (operators/intrinsic_delaunay.h), so
// marching-cubes slivers neither spoil the solve nor put spikes in d. Static by
// default; `dynamic` integrates
//     alpha M d'' + b1 M d' + (g1 K_w + g2 K_w D K_w) d = f
// from rest for `steps` backward-Euler steps, with the thesis's tissue parameters
// mapped as alpha = mass, b1 = 2 viscosity sqrt(alpha k) (viscosity 1 is critical
// damping of the region's slowest mode, k its stiffness), g = elasticity * (g1, g2);
// a step is a quarter of 1/omega, omega = sqrt(k / alpha), so `steps` counts time
// in the region's own units (the default 50 settles it to about exp(-7.5)).
// The region given in mm is the surface within that distance of the handles, ended by
// a foundation that takes the displacement and its slope to zero at the radius
// (RegionBoundary::Smooth): handles at points, distances on the surface and the
// boundary all belong to the surface, so independent triangulations of one wall give
// the same correction (docs/vessel-correction.md). The solve runs on a copy of the
// region and six rings around it: its cost follows the region, not the mesh.
//
// Method Springs (the thesis's, as a baseline, as we read it): rings of neighbours
// visited breadth first from the handle up to the level of influence, each vertex
// moved once towards the equilibrium of the thesis's eq. 12.1 (springs to its
// already-placed neighbours, overdamped), or with `dynamic` integrated with its inertia
// (its section 13.3); with an image, its direction cube (eq. 13.7) as a force inside
// the integration. Its region is counted in rings, so its result changes with the
// resolution, and nothing stops it from pushing the wall through itself. The details
// of our reading: docs/vessel-correction.md, "The thesis's method".
//
// Self-intersections. Triangles touching moved vertices are checked against the
// mesh with a BVH built once (mesh/self_intersections.h). When a Fem correction
// would create an intersection it continues in steps: from each surface reached
// (first the mesh itself) the largest step of the rest of the displacement (all of
// it, its half, its quarter ... down to 1 / `max_substeps` of the whole; from the mesh
// itself at most half) that creates none, with the operators rebuilt on the surface
// reached. When no step fits, the step is limited (bisection on the fraction applied)
// to the largest fraction that creates none, or the one-shot field is, whichever
// applies more. What was done is reported.
//
// Image guidance (soft correction). With an edge map E = |grad(G_sigma * I)|
// (image/volume.h, value per mm), each free vertex i of the region looks along its
// normal, up to `search_radius` mm either way, for an edge t_i (see below; or, with
// `cube_size`, takes the centre of the strongest voxel of the thesis's direction
// cube, eq. 13.7). The load f_i = lambda M_i (t_i - p_i - d_i) is a spring towards
// that edge in the same PDE (its lambda M_i part joins the matrix), with
// lambda = weight * (g2 (pi/L)^4 + g1 (pi/L)^2), L the region radius: weight 1
// pulls as hard as the region's slowest bending mode resists; the default 30
// lets edges win down to about L/2.3 (docs/vessel-correction.md has the measured
// choice). Along the normal the nearest ridge of
// E at least half as strong as the strongest in reach is taken, not the
// strongest: bright neighbours (spine, kidneys) must not capture the wall. A few
// fixed-point passes search again from the moved positions.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "meshpde/image/volume.h"
#include "meshpde/mesh/caps.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/units.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/handle_load.h"
#include "meshpde/pde/region_boundary.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

enum class CorrectionMethod { Fem, Springs };
/// "fem" or "springs". \throw InputError otherwise.
CorrectionMethod parse_correction_method(const std::string& text);
const char* to_string(CorrectionMethod method);

// How a Fem correction's region of radius R ends (`--boundary`): RegionBoundary,
// pde/region_boundary.h. Smooth (the default) ends it by a foundation that takes the
// displacement and its slope to zero at R on the surface, so independent
// triangulations of one wall agree; Clamp (the rule before, for comparison) ends the
// free set at R - h by edge paths from the handles' vertices (mesh/regions.h's
// influence_region); Fade reaches 2 R by edge paths with a cubic foundation from 0.6 R.
// All three work static or dynamic, with or without image guidance; Smooth and Fade
// solve with the direct solver only.

/// A handle: a vertex or a point of the surface, moved by a prescribed displacement.
/// A Fem correction moves the handle's point by exactly `displacement`; with a handle
/// radius r > 0 (CorrectionParams::handle_radius) the force that does it is spread over
/// the surface within r of the point, so the drag makes a smooth bump instead of a cusp
/// (the load and where the point's motion is read: pde/handle_load.h;
/// CorrectionResult::handle_reading reports the reading). With a bump the mesh resolves,
/// the corners follow the point to the mesh's interpolation error (1-4 % of the drag with
/// a quarter-radius handle at 8 to 10 edges per radius, falling as the square of the edge).
struct CorrectionHandle {
  CorrectionHandle() = default;
  CorrectionHandle(int v, const Eigen::Vector3d& d) : vertex(v), displacement(d) {}
  /// At a surface point; `vertex` becomes the point's nearest corner.
  CorrectionHandle(const Mesh& mesh, const SurfacePoint& p, const Eigen::Vector3d& d);

  int vertex = 0;                                          ///< index into the mesh's vertices (when no point)
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  ///< mm (CorrectionParams::units: the mesh's unit)
  /// A point inside a triangle instead of the vertex (mesh/surface_distance.h); the
  /// springs method, which moves vertices, takes the point's nearest corner.
  std::optional<SurfacePoint> point;
  /// The point as the user gave it (the mesh's coordinates), before the nearest surface
  /// point (parse_point_handles sets it) or the nearest vertex (a vertex spelled
  /// "@X,Y,Z": the command line and Python set it) replaced it: a correction warns when
  /// it lies farther from its handle than the region reaches
  /// (CorrectionResult::handle_warning), and reports a point's distance.
  std::optional<Eigen::Vector3d> given;
};

/// Handles from moves written as the user writes them, one per vertex:
/// "DX,DY,DZ" (a displacement) or "normal:D" (D along the outward normal at the
/// vertex, mesh/topology.h's outward_vertex_normals: D > 0 pushes the wall out of a
/// closed vessel whatever its orientation). The one parser of moves for the CLI, the
/// editor and Python.
/// \throw InputError for a count mismatch, a vertex out of range, a malformed move
///        (the message quotes it) or a normal move at a vertex without area.
std::vector<CorrectionHandle> parse_handles(const Mesh& mesh, const std::vector<int>& vertices,
                                            const std::vector<std::string>& moves);

/// Handles at surface points: the point of the surface nearest to each of `points` (in
/// the mesh's coordinates), with its move as parse_handles reads it; "normal:D" is along
/// the outward normal at the point (the corners' outward normals interpolated). Each
/// handle keeps its point as given (CorrectionHandle::given).
/// \throw InputError as parse_handles, or for a point that is not finite.
std::vector<CorrectionHandle> parse_point_handles(const Mesh& mesh, const std::vector<Eigen::Vector3d>& points,
                                                  const std::vector<std::string>& moves);

/// The thesis's tissue parameters, each in [0, 1] and unit-free (defaults: the thesis's),
/// for the whole region or per vertex: a field (#V entries, each in [0, 1]) replaces its
/// scalar; a constant field gives exactly the scalar's result.
struct TissueParams {
  /// Inertia: alpha of the dynamic mode (Fem) or m of eq. 12.1 (springs). Heavier
  /// tissue settles more slowly. Default 0.1.
  double mass = 0.1;
  /// Scales the stiffness: (g1, g2) -> elasticity (g1, g2) in the dynamic mode; the
  /// spring constant c of the springs method. Default 0.9.
  double elasticity = 0.9;
  /// Damping: 1 is critical damping of the region's slowest mode (dynamic mode); for
  /// springs, how stretched each ring is left ("stable" threshold). Default 0.6.
  double viscosity = 0.6;
  /// Per-vertex mass: vertex i's inertia is mass_field[i] M_i. The time step follows the
  /// fastest tissue of the region (the smallest mass), so `steps` counts its time and a
  /// heavier band settles later. Empty (default): `mass` everywhere.
  Eigen::VectorXd mass_field;
  /// Per-vertex elasticity: it multiplies the stiffness field (relative to its largest
  /// value, which scales (g1, g2) as `elasticity` does in the dynamic mode), so a band of
  /// lower elasticity bends more, static or dynamic; springs: vertex j's spring constant.
  /// Empty (default): `elasticity` everywhere.
  Eigen::VectorXd elasticity_field;
  /// Per-vertex viscosity: vertex i's damping is 2 viscosity_i sqrt(alpha_i k_i) M_i, with
  /// k_i its elasticity times the region's slowest-mode stiffness; springs: vertex j's
  /// "stable" threshold. Empty (default): `viscosity` everywhere.
  Eigen::VectorXd viscosity_field;
};

/// A per-vertex property of the tissue that a brush paints.
enum class TissueProperty { Stiffness, Mass, Elasticity, Viscosity };
/// "stiffness", "mass", "elasticity" or "viscosity". \throw InputError otherwise.
TissueProperty parse_tissue_property(const std::string& text);
const char* to_string(TissueProperty property);

/// Gaussian scale (mm) of the edge map made from an image by edge_map(): the default of
/// `meshpde correct --image-sigma`, Python's image_sigma and the editor's images.
inline constexpr double kEdgeSigmaMm = 1.0;
/// The edge map E of an image for ImageGuidance::edges: the magnitude of its gradient
/// after a Gaussian of sigma_mm (gradient_magnitude(), image/volume.h), in the image's grid.
std::shared_ptr<const Volume> edge_map(const Volume& image, double sigma_mm = kEdgeSigmaMm);

struct ImageGuidance {
  std::shared_ptr<const Volume> edges;  ///< edge map E (edge_map() of the image); null: off
  Space space = Space::LPS;             ///< frame of the mesh coordinates
  double weight = 30.0;                 ///< pull strength, relative to the region's slowest mode (see above)
  double search_radius = 3.0;           ///< mm searched along the normal, each way, for an edge
  int passes = 4;                       ///< fixed-point passes (re-sampling E at the new positions)
  int cube_size = 0;  ///< thesis direction cube (odd, >= 3; springs need one); 0: the search along the normal
};

/// One correction's request. Exactly one of radius and rings is > 0. Every length in
/// it (handle displacements, radius, image search radius) is in millimetres, whatever
/// the mesh's own unit (`units`).
struct CorrectionParams {
  std::vector<CorrectionHandle> handles;  ///< at least one; parse_handles() reads the CLI's form
  /// Unit of the mesh's coordinates (default mm). Another unit scales the mesh to mm for
  /// the solve (so that image guidance, radius and displacements in mm apply as they
  /// say); the result's V and displacement are in the mesh's unit again, its
  /// max_displacement in mm. mesh/units.h's units_warning() spots a wrong guess.
  LengthUnit units = LengthUnit::Millimetre;
  /// Region of influence: distance (mm) from the nearest handle, on the surface (Smooth)
  /// or along edges (Clamp, Fade); 0: use rings. Default 0.
  double radius = 0;
  int rings = 0;  ///< region of influence in rings of neighbours (the thesis's level of influence); default 0
  /// How a Fem region given by radius ends: Smooth (default), Clamp or Fade (see RegionBoundary).
  RegionBoundary boundary = RegionBoundary::Smooth;
  /// Size of each handle of a Fem correction (mm; see CorrectionHandle): < 0 (default)
  /// takes kHandleRadiusFraction of the radius with the smooth boundary, 0 with the clamp,
  /// the fade and rings; 0 is a single point, and a vertex handle of size 0 is held at its
  /// displacement exactly as before handles had a size.
  double handle_radius = -1;
  CorrectionMethod method = CorrectionMethod::Fem;  ///< Fem (ours, default) or Springs (the thesis's baseline)
  double g1 = 0;  ///< membrane (Laplacian) stiffness of Fem, unit-free weight; default 0
  double g2 = 1;  ///< plate (bi-Laplacian) stiffness of Fem, unit-free weight; default 1
  /// Operator of Fem: Auto (default) takes intrinsic Delaunay on badly shaped or
  /// non-manifold meshes, the cotangent one otherwise.
  LaplacianKind laplacian = LaplacianKind::Auto;
  /// Per-vertex tissue stiffness multiplier (#V entries, each > 0; averaged per
  /// triangle); empty (default): 1 everywhere.
  Eigen::VectorXd stiffness;
  bool dynamic = false;  ///< Fem: integrate the tissue dynamics instead of the static solve; default false
  int steps = 50;        ///< dynamic steps, each a quarter of the region's 1/omega (50: settled to about exp(-7.5))
  TissueParams tissue;   ///< mass, elasticity, viscosity of the dynamic mode and of Springs
  /// Vertices that never move (mesh/caps.h's cap_vertices: the flat caps of a model's open
  /// ends and their rims): they stay out of the region, held at zero displacement like its
  /// outside. A handle may not be one. Default none.
  std::vector<int> held;
  /// Split or limit a Fem correction that would make the surface intersect itself
  /// (default true); false applies it as solved (`--allow-intersections`).
  bool prevent_intersections = true;
  int max_substeps = 8;  ///< the guard's smallest step is 1 / max_substeps of the displacement; default 8
  ImageGuidance image;   ///< off unless image.edges is set
  /// How the Fem system is solved: Auto (default: for a static, unguided region with
  /// the clamp and vertex handles of size 0, the multigrid where SteadySolver's rule tries it and it converges, Direct
  /// otherwise), Direct (a sparse Cholesky factor of the region's matrix, with a
  /// condition estimate), Global (CG preconditioned by the surface multigrid or the
  /// Laplacian factor, pde/global_bilaplacian.h: for regions of hundreds of thousands of
  /// vertices; g2 > 0) or Iterative (Jacobi-CG, no factor: for comparison). Global and
  /// Iterative solve the static, unguided problem with the clamp and vertex handles of
  /// size 0 only.
  SteadySolver solver = SteadySolver::Auto;
  CgOptions cg{.tolerance = 1e-10, .max_iterations = 50000};  ///< for SteadySolver::Iterative
};

/// Paints `brush` into `params`' field of `property` (stiffness, or one of the tissue
/// fields). An empty field starts as its scalar everywhere (stiffness: 1), so painting
/// one band leaves the rest as the scalar option says.
/// \throw InputError for a bad brush, or a tissue value outside [0, 1].
void paint_tissue(const Mesh& mesh, CorrectionParams& params, TissueProperty property, const Brush& brush);
/// Paints a brush given as text, "[PROPERTY:]V:RADIUS:VALUE" (PROPERTY stiffness,
/// mass, elasticity or viscosity, default stiffness; V a vertex index or @X,Y,Z in the
/// mesh's coordinates; RADIUS in millimetres, like every length a user gives, so
/// `millimetres_per_unit` (units.h: millimetres_per) converts it to the mesh's units),
/// as `meshpde correct --brush` and Python's `brushes=` take it.
/// \throw InputError naming the brush for a malformed one, as paint_tissue.
void paint_tissue(const Mesh& mesh, CorrectionParams& params, const std::string& brush,
                  double millimetres_per_unit = 1.0);

/// A Fem correction solves on a copy of its region and this many rings around it
/// (mesh/regions.h's copy_region), so its cost follows the region, not the mesh. The
/// solve reads the region, its two frozen rings and, for the intrinsic operators, the
/// flips around them: with six rings the field equals the whole-mesh solve to rounding
/// for the cotangent operator; the intrinsic one differs by about 1e-5 of the drag,
/// because its mollification constant is set by the worst triangle of the mesh it is
/// built on (test AortaCorrection.TheRegionsCopyGivesTheWholeMeshAnswer).
inline constexpr int kCorrectionMarginRings = 6;

/// What a Fem correction of `params` solves on: its region of influence (mesh
/// numbering; the surface within the radius with the smooth boundary, mesh/regions.h's
/// influence_region clamped at the radius with the clamp), the region's copy and the
/// operators built on the copy (params.laplacian, params.stiffness). The editor's
/// vertex drag preview (a DragSession, clamp rule) solves on exactly these, so that the
/// preview when the mouse stops equals the correction applied on release. The mesh
/// must be in millimetres.
/// \throw InputError as correct_vessel for bad handles, region or stiffness, and for
///        params.units other than mm.
struct CorrectionRegion {
  std::vector<int> region;  ///< held vertex handles first
  RegionCopy copy;
  MeshOperators operators;  ///< on copy.mesh (operators.mesh: the copy, or its intrinsic operator mesh)
};
CorrectionRegion correction_region(const Mesh& mesh, const CorrectionParams& params);

struct CorrectionResult {
  Positions V;                               ///< corrected positions (the mesh's unit)
  Field displacement;                        ///< #V x 3, the mesh's unit (mm unless params.units says otherwise)
  std::vector<int> region;                   ///< vertices of the region of influence (handles included)
  double handle_radius = 0;                  ///< mm: the handles' size used (CorrectionParams::handle_radius resolved)
  int moved_vertices = 0;                    ///< |d| > 1e-6 of the largest handle displacement
  double max_displacement = 0;               ///< mm
  int new_self_intersections = 0;            ///< triangle pairs intersecting now that did not before
  double applied_fraction = 1;               ///< share of the requested displacement applied (< 1: limited)
  int substeps = 1;                          ///< steps the displacement was split into
  std::string intersection_action = "none";  ///< none | split into N steps | limited to F
  double relative_residual = 0;              ///< worst relative residual of the accepted solves
  SteadySolver solver = SteadySolver::Direct;  ///< the Fem solves' solver (Auto resolved; Direct for springs)
  double condition_estimate = 0;  ///< largest cond_1 of the scaled system (SteadyDirectSolver::conditioning)
  double error_bound = 0;         ///< largest estimated relative error of a solve
  std::string accuracy_warning;   ///< set when a solve cannot promise 1e-5 relative accuracy
  /// False when an iterative solve (solver Global or Iterative) stopped short of its
  /// tolerance: the displacement is its last iterate; `solver_message` says where.
  bool converged = true;
  std::string solver_message;
  /// Set when the region holds nothing but the handles (a radius below about one edge
  /// length): only the handles move, the wall around them does not follow.
  std::string region_warning;
  /// Set when a handle point (or a vertex spelled "@X,Y,Z") was given farther from the
  /// surface than the region reaches (the radius, or the rings times the mean edge
  /// length): its handle is the nearest surface point (vertex) all the same, but the
  /// coordinates were most likely meant for another frame or unit. When the point with x
  /// and y negated lies on the surface, the message says so (RAS against LPS: 3D Slicer
  /// writes LPS, vmtk and older Slicer RAS).
  std::string handle_warning;
  LaplacianKind laplacian = LaplacianKind::Cotan;
  std::string laplacian_reason;
  double image_mean_edge_before = 0;  ///< image guidance: mean E over the pulled vertices
  double image_mean_edge_after = 0;
  int pulled_vertices = 0;
  /// Image guidance: free vertices of the region outside the image (not pulled: they
  /// follow the drag unguided). Springs: region vertices outside it.
  int image_outside_vertices = 0;
  double time_ms = 0;
  /// Per handle (CorrectionParams::handles' order): the vertices and weights its
  /// displacement is read from, sum w d[vertex] = the handle's displacement. A vertex:
  /// (vertex, 1). A point handle with a size of at least half its triangle's edge: the
  /// quadratic reading around the point (mesh/surface_point_reading.h). A point
  /// otherwise: its triangle's corners and barycentric coordinates.
  std::vector<std::vector<std::pair<int, double>>> handle_reading;
};

/// How the caller found the caps a correction holds, for its report.
struct CorrectionCaps {
  std::string rule = "labels";  ///< the rule's name (CapRule: labels, auto, off)
  std::string label_array;      ///< the face-label array read (ModelFaceID, ...); empty: none
  std::vector<Cap> caps;        ///< the caps found (mesh/caps.h)
};

/// A correction's report as one JSON object: the keys of `meshpde correct --json`
/// (moved_vertices, max_displacement, region_vertices, new_self_intersections, time_ms,
/// method, boundary, dynamic, laplacian, laplacian_reason, relative_residual,
/// condition_estimate, error_bound, accuracy_warning, region_warning and handle_warning
/// (null when none), applied_fraction, substeps, intersection_action, handles,
/// handle_radius, handle_points (each handle's vertex and displacement, reading
/// ("vertex", "corners" or "quadratic": CorrectionResult::handle_reading), and for a
/// point its triangle, barycentric coordinates, position and corners_displacement, the
/// barycentric combination of its corners' displacements: the drawn mesh's motion
/// there; for a point made from coordinates (parse_point_handles) also `given`, the
/// point as given, and `distance_to_surface`, mm), solver,
/// units, caps {rule, label_array, held_vertices, caps}, and image {pulled_vertices,
/// mean_edge_before, mean_edge_after, space} when guided). Python's CorrectionResult.to_dict() is the
/// same object. V and F: the surface the handles were given on (before the correction).
std::string correction_report_json(const Positions& V, const Triangles& F, const CorrectionParams& params,
                                   const CorrectionResult& result, const CorrectionCaps& caps = {});

/// One correction of `mesh` (the input is not modified).
/// \throw InputError for bad handles, region or stiffness; SolverError on a breakdown.
CorrectionResult correct_vessel(const Mesh& mesh, const CorrectionParams& params,
                                const SelfIntersectionChecker* checker = nullptr);

/// The live preview of a static correction without image guidance, for one handle
/// being dragged (the editor): the region's factor and the handle's response are built
/// once, and each drag D is then a product (microseconds), equal to correct_vessel with
/// that handle displacement to rounding (the same region, copy, operators, foundation
/// and handle constraint), as long as the release creates no self-intersection. The
/// mesh must be in millimetres.
/// \throw InputError for params with other than one handle, the springs method, the
///        dynamic mode or an image, a region of more than `max_region_vertices` (> 0;
///        checked before anything is factored), or as correct_vessel.
class CorrectionPreview {
 public:
  CorrectionPreview(const Mesh& mesh, const CorrectionParams& params, int max_region_vertices = 0);
  ~CorrectionPreview();
  CorrectionPreview(const CorrectionPreview&) = delete;
  CorrectionPreview& operator=(const CorrectionPreview&) = delete;
  int region_vertices() const;
  /// The mesh's vertices a drag can move (the region's copy, in the mesh's numbering):
  /// add_displacement changes no other row.
  const std::vector<int>& moving_vertices() const;
  /// Adds the displacement of the handle dragged by D (mm) to V (the mesh's #V x 3).
  void add_displacement(Positions& V, const Eigen::Vector3d& D) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A correction session on one mesh: corrections apply on top of each other, with
/// undo and redo (the history holds the positions after each step).
class CorrectionSession {
 public:
  explicit CorrectionSession(Mesh mesh);
  const Mesh& mesh() const { return mesh_; }  ///< at the current positions
  const Positions& original() const { return history_.front(); }
  /// Applies a correction to the current positions; clears the redo history.
  CorrectionResult apply(const CorrectionParams& params);
  bool can_undo() const { return current_ > 0; }
  bool can_redo() const { return current_ + 1 < history_.size(); }
  void undo();  ///< \throw InputError when there is nothing to undo
  void redo();  ///< \throw InputError when there is nothing to redo
  /// The positions after each step, the first the original, and the step shown now.
  const std::vector<Positions>& history() const { return history_; }
  std::size_t current() const { return current_; }
  /// Replaces the history by `history` (a saved session reopened), at step `current`.
  /// \throw InputError (the session unchanged) unless history[0] is the mesh's original
  ///        positions, every step holds finite positions of every vertex and current is a step.
  void restore(std::vector<Positions> history, std::size_t current);
  /// Triangle pairs intersecting at the current positions that did not in the
  /// original (cost follows the vertices moved so far).
  int new_self_intersections() const;

 private:
  Mesh mesh_;
  std::vector<Positions> history_;
  std::size_t current_ = 0;
  SelfIntersectionChecker original_checker_;
  std::vector<int> touched_;  // vertices ever moved
};

}  // namespace meshpde
