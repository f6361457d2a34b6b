#include "meshpde/editor/editor_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include "meshpde/apps/interpolation.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"

namespace meshpde {

namespace {

Mesh checked_mesh(const MeshData& d) {
  if (d.V.rows() == 0 || d.F.rows() == 0) throw InputError("the mesh has no triangles");
  return Mesh(d.V, d.F);
}

}  // namespace

EditorSession::EditorSession(MeshData data, std::shared_ptr<const Volume> edges, Space space, LaplacianKind laplacian)
    : data_(std::move(data)),
      correction_(checked_mesh(data_)),
      edges_(std::move(edges)),
      space_(space),
      laplacian_(laplacian) {
  mean_edge_ = std::max(meshpde::mean_edge_length(correction_.mesh()), 1e-12);
  held_ = cap_vertices(find_caps(correction_.mesh(), face_labels(data_), CapRule::Labels));
}

EditorSession::~EditorSession() {
  end_poke();
}

namespace {
// A live preview factors the region on the server's one thread: keep it to regions
// whose set-up takes a fraction of a second (about 0.3 s at 20k vertices here).
constexpr int kPreviewLimit = 20000;
// The field a correction leaves on the wall until the next action: how far each
// vertex moved (mm). Shown, never saved (a save can add the displacement itself).
constexpr const char* kMovedField = "moved (mm)";
// After an image-guided correction: how far the image moved each vertex beyond what the
// drag alone would have (mm), the other colouring of the same correction.
constexpr const char* kPullField = "image pull (mm)";
}  // namespace

void EditorSession::check_vertex(int v) const {
  if (v < 0 || v >= mesh().num_vertices())
    throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", v, mesh().num_vertices()));
}

Positions EditorSession::display_positions() const {
  Positions V = mesh().positions();
  if (haptic_) V += haptic_->displacement();
  if (preview_) preview_->add_displacement(V, drag_offset_);
  return V;
}

double EditorSession::drag_begin(const SurfacePoint& point, double radius, const Eigen::VectorXd& stiffness,
                                 const TissueParams& tissue) {
  return begin_preview(CorrectionHandle(mesh(), point, Eigen::Vector3d::Zero()), radius, stiffness, tissue);
}

double EditorSession::drag_begin(int vertex, double radius, const Eigen::VectorXd& stiffness,
                                 const TissueParams& tissue) {
  check_vertex(vertex);
  return begin_preview(CorrectionHandle{vertex, Eigen::Vector3d::Zero()}, radius, stiffness, tissue);
}

double EditorSession::begin_preview(CorrectionHandle handle, double radius, const Eigen::VectorXd& stiffness,
                                    const TissueParams& tissue) {
  if (!(radius > 0) || !std::isfinite(radius)) throw InputError("drag radius must be a length > 0");
  // The release's correction: fem, static, the default boundary and handle size, the
  // session's Laplacian, tissue and held caps, this radius.
  CorrectionParams p;
  p.handles = {std::move(handle)};
  p.radius = radius;
  p.stiffness = stiffness;
  p.tissue = tissue;
  p.laplacian = laplacian_;
  p.held = held_;
  pause();
  const auto t0 = std::chrono::steady_clock::now();
  // Built before the running drag is dropped: a refused request leaves it as it was.
  auto preview = std::make_unique<CorrectionPreview>(mesh(), p, kPreviewLimit);
  drag_end();
  end_poke();  // a new tool ends the probe's relaxation at once
  clear_moved_field();
  preview_ = std::move(preview);
  drag_offset_.setZero();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void EditorSession::drag_move(const Eigen::Vector3d& offset) {
  if (!dragging()) throw InputError("drag_move without drag_begin");
  if (!offset.allFinite()) throw InputError("drag offset is not finite");
  drag_offset_ = offset;
}

RegionRim EditorSession::region_rim(const SurfacePoint& point, double radius) const {
  if (!(radius > 0) || !std::isfinite(radius)) throw InputError("region radius must be a length > 0");
  check_surface_point(mesh(), point, "region rim");
  RegionRim out;
  out.handle_radius = kHandleRadiusFraction * radius;
  // Distances a little beyond the radius, so that every triangle the rim crosses has
  // its corners measured; a corner still unreached lies beyond that reach, and is
  // given the reach (its triangle's crossing then sits a little too far out).
  const double reach = radius + 3 * mean_edge_;
  const Mesh& m = mesh();
  // The distances and triangles kept for the vertices reached only, so that a hover
  // costs what the region costs, not arrays the size of the mesh.
  const std::vector<std::pair<int, double>> reached =
      geodesic_distances_from(m, GeodesicSources{.points = {point}}, reach);
  std::unordered_map<int, double> d;
  d.reserve(reached.size());
  std::vector<int> faces;
  const VertexFaces& around = m.vertex_faces();
  for (const auto& [v, dist] : reached) {
    d.emplace(v, dist);
    out.region_vertices += dist < radius;
    for (int k = around.offsets[static_cast<std::size_t>(v)]; k < around.offsets[static_cast<std::size_t>(v) + 1]; ++k)
      faces.push_back(around.faces[static_cast<std::size_t>(k)]);
  }
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  const auto distance = [&](int v) {
    const auto it = d.find(v);
    return it == d.end() ? reach : it->second;
  };
  out.rim = level_set_segments(m, distance, radius, faces);
  if (out.handle_radius > 0) out.handle = level_set_segments(m, distance, out.handle_radius, faces);
  return out;
}

void EditorSession::drag_end() {
  preview_.reset();
  drag_offset_.setZero();
}

int EditorSession::drag_region_vertices() const {
  return preview_ ? preview_->region_vertices() : 0;
}

const std::vector<int>& EditorSession::drag_moving_vertices() const {
  static const std::vector<int> none;
  return preview_ ? preview_->moving_vertices() : none;
}

void EditorSession::end_poke() {
  if (haptic_) haptic_->stop();
  haptic_.reset();
  poke_geometry_.reset();
}

void EditorSession::poke_begin(int vertex, double influence) {
  check_vertex(vertex);
  if (!(influence >= 0) || !std::isfinite(influence)) throw InputError("poke influence must be a length >= 0");
  clear_moved_field();
  pause();
  // The probe runs on the operators of the surface as it is now (intrinsic ones on
  // badly shaped meshes, so the servo's CG stays well conditioned).
  const std::shared_ptr<const MeshOperators> geometry = geometry_.operators(mesh());
  if (!haptic_ || poke_geometry_ != geometry || influence != poke_influence_) {
    end_poke();
    poke_geometry_ = geometry;
    HapticParams hp;
    hp.influence = influence;
    haptic_ = std::make_unique<HapticSession>(poke_geometry_->mesh, poke_geometry_->ops, hp);
    poke_influence_ = influence;
    haptic_->start();
  }
  haptic_->touch(vertex);
}

void EditorSession::poke_move(const Eigen::Vector3d& offset) {
  if (!haptic_ || !haptic_->touching()) throw InputError("poke_move without poke_begin");
  if (!offset.allFinite()) throw InputError("probe offset is not finite");
  haptic_->move_probe(offset);
}

void EditorSession::poke_end() {
  if (haptic_) haptic_->release();
}

bool EditorSession::poking() const {
  return haptic_ && haptic_->touching();
}
Eigen::Vector3d EditorSession::poke_force() const {
  return haptic_ ? haptic_->latest_force() : Eigen::Vector3d::Zero();
}
int EditorSession::poke_contact() const {
  return haptic_ ? haptic_->contact_vertex() : -1;
}
int EditorSession::poke_active_vertices() const {
  return haptic_ ? haptic_->active_vertices() : 0;
}
int EditorSession::poke_misses() const {
  return haptic_ ? haptic_->misses() : 0;
}
double EditorSession::poke_p99_us() const {
  return haptic_ ? haptic_->recent_p99_us() : 0;
}

CorrectionResult EditorSession::correct(CorrectionParams params) {
  end_poke();
  pause();
  drag_end();  // the correction replaces the preview
  params.laplacian = laplacian_;
  if (params.held.empty()) params.held = held_;
  if (edges_ && !params.image.edges && params.image.weight > 0) {
    params.image.edges = edges_;
    params.image.space = space_;
  }
  const auto t0 = std::chrono::steady_clock::now();
  // What the image did: the same drag without it, from the same surface, scaled to the
  // share of the drag that was applied (the field is linear in it without the image).
  Field unguided;
  if (params.image.edges && params.method == CorrectionMethod::Fem) {
    CorrectionParams plain = params;
    plain.image.edges = nullptr;
    unguided = correct_vessel(mesh(), plain).displacement;
  }
  CorrectionResult r = correction_.apply(params);
  // The wall coloured by how far it moved, until the next action.
  field_ = r.displacement.rowwise().norm();
  field_name_ = kMovedField;
  moved_ = field_;
  pull_.resize(0);
  if (unguided.rows() == r.displacement.rows())
    pull_ = (r.displacement - r.applied_fraction * unguided).rowwise().norm();
  last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  geometry_.refresh();
  info_ = fmt::format("correct: {} vertices moved, {} new self-intersections, {}", r.moved_vertices,
                      r.new_self_intersections, r.intersection_action);
  return r;
}

void EditorSession::clear_moved_field() {
  if (field_name_ != kMovedField && field_name_ != kPullField) return;
  field_.resize(0);
  field_name_.clear();
  moved_.resize(0);
  pull_.resize(0);
}

void EditorSession::show_correction_field(const std::string& name) {
  if (field_name_ != kMovedField && field_name_ != kPullField)
    throw InputError("no correction to colour by: make one first");
  if (name == kMovedField) {
    field_ = moved_;
  } else if (name == kPullField) {
    if (pull_.size() == 0)
      throw InputError("the last correction had no image guidance: there is no image pull to show");
    field_ = pull_;
  } else {
    throw InputError(fmt::format("unknown colouring '{}' ({} or {})", name, kMovedField, kPullField));
  }
  field_name_ = name;
}

void EditorSession::undo() {
  clear_moved_field();
  drag_end();
  end_poke();
  correction_.undo();
  geometry_.refresh();
}

void EditorSession::restore_history(std::vector<Positions> history, std::size_t current) {
  clear_moved_field();
  drag_end();
  end_poke();
  correction_.restore(std::move(history), current);
  geometry_.refresh();
}

void EditorSession::redo() {
  clear_moved_field();
  drag_end();
  end_poke();
  correction_.redo();
  geometry_.refresh();
}

void EditorSession::paint(int vertex, double value, double g1, double g2) {
  check_vertex(vertex);
  if (!std::isfinite(value)) throw InputError("painted value is not finite");
  if (!(g1 >= 0 && g2 >= 0) || g1 + g2 <= 0) throw InputError("g1 and g2 must be >= 0 and not both 0");
  end_poke();
  pause();
  painted_[vertex] = value;
  const auto t0 = std::chrono::steady_clock::now();
  const std::shared_ptr<const MeshOperators> mo = geometry_.operators(mesh());
  // One kept factor while the surface and the weights stay: a click costs an update of
  // it (apps/interpolation.h), not a new factorization.
  if (!paint_solver_ || paint_geometry_ != mo || paint_g1_ != g1 || paint_g2_ != g2) {
    paint_solver_.reset();
    paint_geometry_ = mo;
    paint_g1_ = g1;
    paint_g2_ = g2;
    paint_solver_ = std::make_unique<InterpolationSolver>(mo->mesh, mo->ops, FieldKind::Scalar,
                                                          InterpolationParams{.g1 = g1, .g2 = g2});
    for (const auto& [v, x] : painted_) paint_solver_->set_value(v, Eigen::VectorXd::Constant(1, x));
  } else {
    paint_solver_->set_value(vertex, Eigen::VectorXd::Constant(1, value));
  }
  const InterpolationResult r = paint_solver_->solve();
  last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  field_ = r.values.col(0);
  field_name_ = "paint";
  info_ = fmt::format("paint: {} values interpolated (g1 {}, g2 {}), residual {:.1e}, {} factorization{}",
                      painted_.size(), g1, g2, r.cg.relative_residual, paint_solver_->factorizations(),
                      paint_solver_->factorizations() == 1 ? "" : "s");
}

void EditorSession::paint_vector(int vertex, const Eigen::Vector3d& vector, double g1, double g2) {
  check_vertex(vertex);
  if (!vector.allFinite()) throw InputError("painted vector is not finite");
  if (!(g1 >= 0 && g2 >= 0) || g1 + g2 <= 0) throw InputError("g1 and g2 must be >= 0 and not both 0");
  end_poke();
  pause();
  painted_vectors_[vertex] = vector;
  std::vector<InterpolationConstraint> c;
  for (const auto& [v, x] : painted_vectors_) c.push_back({v, Eigen::VectorXd(x)});
  const auto t0 = std::chrono::steady_clock::now();
  // The connection-aware method needs the mesh's own triangles (it transports
  // vectors across them), so it runs on the cotangent operators.
  const std::shared_ptr<const MeshOperators> cotan = geometry_.cotan(mesh());
  InterpolationParams ip;
  ip.g1 = g1;
  ip.g2 = g2;
  ip.method = TangentMethod::Connection;
  const InterpolationResult r = interpolate(mesh(), cotan->ops, FieldKind::Tangent, c, ip);
  last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  vectors_ = r.values;
  field_ = vectors_.rowwise().norm();
  field_name_ = "vector_length";
  info_ = fmt::format("paint: {} vectors interpolated (connection, g1 {}, g2 {})", painted_vectors_.size(), g1, g2);
}

void EditorSession::clear_paint() {
  painted_vectors_.clear();
  vectors_.resize(0, 3);
  if (field_name_ == "vector_length") {
    field_.resize(0);
    field_name_.clear();
  }
  painted_.clear();
  paint_solver_.reset();
  paint_geometry_.reset();
  if (field_name_ == "paint") {
    field_.resize(0);
    field_name_.clear();
  }
}

void EditorSession::add_source(int vertex) {
  check_vertex(vertex);
  end_poke();  // a new tool ends the probe's relaxation at once
  if (std::find(sources_.begin(), sources_.end(), vertex) == sources_.end()) sources_.push_back(vertex);
}

void EditorSession::clear_sources() {
  pause();
  sources_.clear();
  pde_.reset();
}

void EditorSession::play(const std::string& kind) {
  if (kind != "heat" && kind != "wave") throw InputError(fmt::format("unknown simulation '{}' (heat or wave)", kind));
  if (sources_.empty()) throw InputError("click a source vertex first");
  end_poke();
  const std::shared_ptr<const MeshOperators> geometry = geometry_.operators(mesh());
  if (!pde_ || pde_kind_ != kind || pde_geometry_ != geometry) {  // a new kind, or the surface changed
    pde_.reset();
    pde_geometry_ = geometry;
    // Heat: u_t = lap u, sources held at 1. Wave: u_tt = lap u, sources plucked to 1
    // and released, lightly damped.
    const PdeCoefficients c = kind == "heat" ? PdeCoefficients{.alpha = 0, .b1 = 1, .g1 = 1}
                                             : PdeCoefficients{.alpha = 1, .b1 = 0.05, .g1 = 1};
    // Heat is localized, as in Kim and Rossignac 2004: the active domain starts at the sources and
    // grows with the heat, so a frame costs what is warming, not the mesh. A wave
    // reaches everything within a few frames, so it runs on the whole mesh (its
    // self-adjusting bookkeeping would only add cost).
    const bool local = kind == "heat";
    pde_ = std::make_unique<PdeSession>(pde_geometry_->mesh, pde_geometry_->ops, 1, c,
                                        DomainOptions{.self_adjusting = local});
    if (!local) pde_->activate_all();
    pde_->cg_options.tolerance = 1e-6;
    Field u = Field::Zero(pde_geometry_->mesh.num_vertices(), 1);
    for (int v : sources_) u(v, 0) = 1;
    if (kind == "heat") {
      for (int v : sources_) {
        const double one = 1;
        pde_->constrain(v, std::span<const double>(&one, 1));
      }
    } else {
      pde_->set_values(u, false);
    }
    pde_kind_ = kind;
  }
  playing_ = true;
  field_name_ = kind;
}

void EditorSession::pause() {
  playing_ = false;
}

void EditorSession::advance(int steps) {
  if (!playing_ || !pde_) return;
  const auto t0 = std::chrono::steady_clock::now();
  // A step moves heat by about an edge, a wave by half an edge.
  const double dt = pde_kind_ == "heat" ? mean_edge_ * mean_edge_ : 0.5 * mean_edge_;
  for (int k = 0; k < steps; ++k) pde_->step(dt);
  last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  field_ = pde_->values().col(0);
}

int EditorSession::simulation_active_vertices() const {
  return pde_ ? static_cast<int>(pde_->domain().free_vertices().size()) : 0;
}

MeshData EditorSession::snapshot() const {
  MeshData d = data_;
  d.V = mesh().positions();
  if (field_.size() == d.V.rows() && !field_name_.empty() && field_name_ != kMovedField && field_name_ != kPullField)
    d.vertex_scalars[field_name_] = field_;
  if (vectors_.rows() == d.V.rows()) {
    d.vertex_scalars["paint_vector_x"] = vectors_.col(0);
    d.vertex_scalars["paint_vector_y"] = vectors_.col(1);
    d.vertex_scalars["paint_vector_z"] = vectors_.col(2);
  }
  d.warnings.clear();
  return d;
}

}  // namespace meshpde
