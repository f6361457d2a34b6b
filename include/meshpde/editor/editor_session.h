// One interactive editing session on one mesh: what the browser editor's server
// (`meshpde serve`) runs for each connected page. Poke (a haptic probe at 1 kHz on
// its own thread), correct (vessel correction with undo and redo), paint (scalar
// values interpolated by g1/g2), heat and wave (sources, play and pause). The
// session only computes; the server turns requests into calls and the state into
// frames.
//
// Positions are in mesh units (mm for vessels). What a page shows is
// display_positions() (the corrected surface plus the probe's transient
// displacement) and field() (the painted, heat or wave values, or empty).
// Thread safety: one thread calls the methods; the poke's servo thread is internal.
#pragma once

#include <Eigen/Core>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "meshpde/apps/haptics.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/caps.h"
#include "meshpde/mesh/level_set.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde {

/// What a drag at a surface point would touch (EditorSession::region_rim): the curves on
/// the surface at the correction's region radius and at its handle's size, both measured
/// on the surface from the point (mesh/geodesic_distance.h), as the correction measures.
struct RegionRim {
  std::vector<LevelSetSegment> rim;     ///< where the surface distance is the radius
  std::vector<LevelSetSegment> handle;  ///< where it is the handle's radius
  int region_vertices = 0;              ///< vertices nearer than the radius
  double handle_radius = 0;             ///< mm: the default handle's size for this radius
};

class EditorSession {
 public:
  /// The mesh with its fields (kept for saving). \throw InputError for an unusable mesh.
  /// laplacian: the operator of poke, paint, heat, wave, the drag preview and correct
  /// (Auto: intrinsic Delaunay on badly shaped or non-manifold meshes; `serve --laplacian`).
  explicit EditorSession(MeshData data, std::shared_ptr<const Volume> edges = nullptr, Space space = Space::LPS,
                         LaplacianKind laplacian = LaplacianKind::Auto);
  LaplacianKind laplacian() const { return laplacian_; }
  ~EditorSession();
  EditorSession(const EditorSession&) = delete;
  EditorSession& operator=(const EditorSession&) = delete;

  const Mesh& mesh() const { return correction_.mesh(); }  ///< the corrected surface
  /// Corrected positions plus the probe's displacement while poking or relaxing.
  Positions display_positions() const;
  /// The field on show (#V values) and its name ("" when none).
  const Eigen::VectorXd& field() const { return field_; }
  const std::string& field_name() const { return field_name_; }
  double mean_edge_length() const { return mean_edge_; }

  // Poke: grab a vertex, move the probe (offset from the vertex's rest position),
  // let go (the surface relaxes; the servo keeps running until it has).
  /// influence: the poke's decay length in mesh units (HapticParams::influence;
  /// 0: three mean edge lengths). A larger one moves a wider region.
  void poke_begin(int vertex, double influence = 0);
  void poke_move(const Eigen::Vector3d& offset);
  void poke_end();
  /// Ends a poke and its relaxation at once, the surface back at rest (poke_end only
  /// lets go): every other tool's action does this first, so that the next tool starts
  /// on a still surface (the page's tissue brush calls it).
  void end_poke();
  bool poking() const;
  Eigen::Vector3d poke_force() const;
  int poke_contact() const;
  int poke_active_vertices() const;
  int poke_misses() const;
  double poke_p99_us() const;  ///< over the last second of steps

  // Drag preview: while the user drags a handle with the correct tool, the surface
  // follows live (a CorrectionPreview: the region's factor and its response to the
  // handle are built at drag_begin, every drag_move is a scaled copy of that response,
  // microseconds). The preview is the correction's default rule (the handle moves, the
  // region is measured on the surface and ends smoothly at `radius`, a handle of the
  // default size) on the very region, copy and operators that correct() uses, so when
  // the mouse stops it equals the correction applied on release with the same handle
  // to rounding, unless that one is image-guided, dynamic or has to avoid a
  // self-intersection.
  /// At a vertex. radius: the region of influence in mesh units; stiffness and tissue:
  /// the per-vertex stiffness (empty: 1) and tissue the release will use (its
  /// elasticity field weighs the static solve too). Returns the set-up time in ms.
  /// \throw InputError for a bad vertex or radius, or a region of more than 20,000
  ///        vertices (too large to factor while the user waits; releasing still corrects).
  double drag_begin(int vertex, double radius, const Eigen::VectorXd& stiffness = Eigen::VectorXd(),
                    const TissueParams& tissue = {});
  /// The same at a surface point (the point the user picked): that point moves.
  double drag_begin(const SurfacePoint& point, double radius, const Eigen::VectorXd& stiffness = Eigen::VectorXd(),
                    const TissueParams& tissue = {});
  void drag_move(const Eigen::Vector3d& offset);
  /// The rim of the region a drag at `point` with this radius would move, and of its
  /// handle (the page draws them under the cursor before a press). Costs one surface
  /// distance computation over the region (a few ms for 10k vertices).
  /// \throw InputError for a bad point or radius.
  RegionRim region_rim(const SurfacePoint& point, double radius) const;
  void drag_end();  ///< drops the preview (correct() drops it too)
  bool dragging() const { return preview_ != nullptr; }
  int drag_region_vertices() const;
  /// The vertices the running drag can move (empty without one): a page redraws only
  /// these and their neighbours while the drag is on.
  const std::vector<int>& drag_moving_vertices() const;

  // Correct.
  /// Image guidance is filled in when a volume was given, and the caps the mesh's face
  /// labels mark (mesh/caps.h, CapRule::Labels) are held unless params.held is set.
  /// Afterwards, until the next action, the field on show is "moved (mm)" (each
  /// vertex's move); an image-guided one also keeps "image pull (mm)": how far the image
  /// moved each vertex beyond the same drag without it (one more solve, unguarded,
  /// scaled to the applied share of the drag).
  CorrectionResult correct(CorrectionParams params);
  /// Shows the last correction's "moved (mm)" or "image pull (mm)" (correct()).
  /// \throw InputError without a correction on show, or without its image pull.
  void show_correction_field(const std::string& name);
  /// The last correction's image pull (#V, mm; empty without image guidance).
  const Eigen::VectorXd& image_pull() const { return pull_; }
  /// The vertices of the mesh's labelled caps, which corrections and drags hold.
  const std::vector<int>& held_vertices() const { return held_; }
  bool can_undo() const { return correction_.can_undo(); }
  bool can_redo() const { return correction_.can_redo(); }
  void undo();
  void redo();
  /// The corrections' history (positions after each step, the first the original) and
  /// the step shown; restore_history() puts back a saved one (CorrectionSession::restore).
  const std::vector<Positions>& history() const { return correction_.history(); }
  std::size_t history_step() const { return correction_.current(); }
  void restore_history(std::vector<Positions> history, std::size_t current);
  int self_intersections() const { return correction_.new_self_intersections(); }
  bool has_image() const { return edges_ != nullptr; }
  /// Guides the corrections from now on by `edges` (an image's edge map, in the
  /// session's frame); null turns guidance off. Edits so far stay as they are.
  void set_image_edges(std::shared_ptr<const Volume> edges) { edges_ = std::move(edges); }

  // Paint: values at vertices, interpolated over the mesh.
  void paint(int vertex, double value, double g1, double g2);
  void clear_paint();
  const std::map<int, double>& painted() const { return painted_; }
  /// A tangent vector at a vertex (projected onto the tangent plane), interpolated
  /// over the mesh with the connection-aware method; shown as arrows, and its
  /// length as the field.
  void paint_vector(int vertex, const Eigen::Vector3d& vector, double g1, double g2);
  /// The painted vector field (#V x 3), empty when none.
  const Eigen::MatrixX3d& vectors() const { return vectors_; }

  // Heat and wave: sources (value 1 held at the vertex for heat, an impulse for
  // wave), then advance() steps the PDE while playing.
  void add_source(int vertex);
  void clear_sources();
  void play(const std::string& kind);  ///< "heat" or "wave"
  void pause();
  bool playing() const { return playing_; }
  /// Vertices in the heat or wave simulation's active domain.
  int simulation_active_vertices() const;
  /// Advances heat or wave by `steps` steps (the server calls it once a frame).
  void advance(int steps);

  /// The positions the session opened with (before any correction).
  const Positions& original_positions() const { return correction_.original(); }
  /// The mesh as it is now, with its original fields plus the painted or simulated
  /// field, for saving.
  MeshData snapshot() const;
  const std::string& last_solve_info() const { return info_; }
  /// Operator bundles built for this surface so far: one per state of the surface,
  /// shared by the probe, heat and wave and painting.
  int operator_builds() const { return geometry_.builds(); }
  double last_solve_ms() const { return last_ms_; }

 private:
  void check_vertex(int v) const;
  void clear_moved_field();  // ends a correction's colouring (the next action)
  double begin_preview(CorrectionHandle handle, double radius, const Eigen::VectorXd& stiffness,
                       const TissueParams& tissue);

  MeshData data_;
  CorrectionSession correction_;
  std::shared_ptr<const Volume> edges_;
  Space space_;
  LaplacianKind laplacian_ = LaplacianKind::Auto;
  double mean_edge_ = 1;
  std::vector<int> held_;  // the caps' vertices
  // The surface's operators (intrinsic Delaunay on badly shaped meshes), one cache for
  // the probe, heat and wave and painting; refreshed by every change of the surface.
  OperatorCache geometry_{laplacian_};
  // Poke state: the operators it was built on (kept alive while it runs).
  std::shared_ptr<const MeshOperators> poke_geometry_;
  std::unique_ptr<HapticSession> haptic_;
  double poke_influence_ = -1;
  // Drag preview state.
  std::unique_ptr<CorrectionPreview> preview_;
  Eigen::Vector3d drag_offset_ = Eigen::Vector3d::Zero();
  // Fields.
  Eigen::VectorXd field_;
  std::string field_name_;
  Eigen::VectorXd moved_, pull_;  // the last correction's two colourings (until the next action)
  std::map<int, double> painted_;
  // Paint's kept factor and what it was built for (the surface's operators, g1, g2).
  std::shared_ptr<const MeshOperators> paint_geometry_;
  std::unique_ptr<InterpolationSolver> paint_solver_;
  double paint_g1_ = -1, paint_g2_ = -1;
  std::map<int, Eigen::Vector3d> painted_vectors_;
  Eigen::MatrixX3d vectors_;
  std::vector<int> sources_;
  std::shared_ptr<const MeshOperators> pde_geometry_;
  std::unique_ptr<PdeSession> pde_;
  std::string pde_kind_;
  bool playing_ = false;
  std::string info_;
  double last_ms_ = 0;
};

}  // namespace meshpde
