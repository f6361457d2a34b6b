// correct_vessel, correction_region and CorrectionPreview: a correction from request
// to result.
#include <fmt/format.h>

#include <chrono>
#include <memory>
#include <optional>
#include <set>

#include "correction_internal.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"

namespace meshpde::correction {

namespace {

// CorrectionResult::handle_warning: the handle points given farther from the surface
// than the region reaches, with the frame hint when the point with x and y negated lies
// within that reach. Coordinates in the mesh's unit (as the user gave them), distances
// in mm (`mm_per_unit` of them to the mesh's unit).
std::string far_handle_points_warning(const Mesh& mesh, const CorrectionParams& p, double mm_per_unit) {
  const double reach = p.radius > 0 ? p.radius : p.rings * mean_edge_length(mesh) * mm_per_unit;
  std::string out;
  for (const CorrectionHandle& h : p.handles) {
    if (!h.given) continue;
    const Eigen::Vector3d at = h.point ? position(mesh, *h.point) : Eigen::Vector3d(mesh.positions().row(h.vertex));
    const double distance = (*h.given - at).norm() * mm_per_unit;
    if (!(distance > reach)) continue;
    const Eigen::Vector3d mirrored(-h.given->x(), -h.given->y(), h.given->z());
    const Eigen::Vector3d mirrored_at =
        position(mesh, closest_surface_points(mesh, std::span<const Eigen::Vector3d>(&mirrored, 1))[0]);
    const double mirrored_distance = (mirrored - mirrored_at).norm() * mm_per_unit;
    std::string text = fmt::format(
        "the handle point ({:g}, {:g}, {:g}) lies {:.3g} mm from the {}, farther than the region's {:.3g} mm: "
        "its handle is the nearest {}, ({:g}, {:g}, {:g})",
        h.given->x(), h.given->y(), h.given->z(), distance, h.point ? "surface" : "nearest vertex", reach,
        h.point ? "surface point" : fmt::format("vertex, {}", h.vertex), at.x(), at.y(), at.z());
    if (mirrored_distance <= reach && mirrored_distance < 0.1 * distance)
      text += fmt::format(
          "; the point with x and y negated, ({:g}, {:g}, {:g}), lies {:.3g} mm from the surface: were the "
          "coordinates given in RAS for a mesh in LPS (3D Slicer's models), or in LPS for one in RAS?",
          mirrored.x(), mirrored.y(), mirrored.z(), mirrored_distance);
    else
      text += "; check that the point is in the mesh's coordinates, frame and unit";
    out += (out.empty() ? "" : "\n") + text;
  }
  return out;
}

// A guided correction whose region lies wholly outside the image cannot be guided:
// there is no edge to pull a vertex to, and every region vertex would be tied to where
// it is, stiffening the wall instead. Refused, naming the other frame when the region
// lies inside the image read in it (RAS and LPS differ by the sign of x and y).
void check_region_in_image(const Mesh& mesh, const CorrectionParams& p, const std::vector<int>& region) {
  const Volume& E = *p.image.edges;
  const auto inside = [&](Space space) {
    int n = 0;
    for (const int v : region) n += E.sample(mesh.positions().row(v).transpose(), space).has_value();
    return n;
  };
  if (region.empty() || inside(p.image.space) > 0) return;
  const Space other = p.image.space == Space::LPS ? Space::RAS : Space::LPS;
  const int other_inside = inside(other);
  throw InputError(fmt::format(
      "image guidance: none of the region's {} vertices lies inside the image ({} x {} x {} voxels) with the mesh's "
      "coordinates read as {}, so the image cannot guide the correction{}",
      region.size(), E.dims[0], E.dims[1], E.dims[2], to_string(p.image.space),
      other_inside > 0 ? fmt::format("; read as {}, {} of them do: is the mesh in {}?", to_string(other), other_inside,
                                     to_string(other))
                       : std::string("; are the mesh and the image of the same scan, in the same unit?")));
}

}  // namespace

CorrectionResult correct_vessel_impl(const Mesh& mesh, const CorrectionParams& p_in,
                                     const SelfIntersectionChecker* checker, std::span<const int> already_moved) {
  if (p_in.units != LengthUnit::Millimetre) {
    // Everything below works in millimetres: solve on the mesh scaled to them and give
    // the displacement back in the mesh's units (added to the input positions, so the
    // vertices that did not move are the input's, bit for bit). The caller's checker
    // holds positions in the mesh's units: one is built on the scaled mesh instead.
    const double s = millimetres_per(p_in.units);
    CorrectionParams mm = p_in;
    mm.units = LengthUnit::Millimetre;
    for (auto& h : mm.handles) h.given.reset();  // warned about here, in the coordinates given
    CorrectionResult r = correct_vessel_impl(Mesh(mesh.positions() * s, mesh.triangles()), mm, nullptr, already_moved);
    r.displacement /= s;
    r.V = mesh.positions() + r.displacement;
    r.handle_warning = far_handle_points_warning(mesh, p_in, s);
    return r;
  }
  const auto t0 = std::chrono::steady_clock::now();
  validate(mesh, p_in);
  const CorrectionParams p = normalized(p_in, mesh);
  CorrectionResult r;
  const FemProblem problem = fem_problem(mesh, p);
  if (p.image.edges && p.image.weight > 0) check_region_in_image(mesh, p, problem.region);
  r.region = problem.region;
  r.handle_radius = handle_size(p);
  r.handle_reading = problem.reading;
  std::set<int> handle_vertices;  // the held handles, and the corners a point is read from
  for (const auto& h : problem.held) handle_vertices.insert(h.vertex);
  for (const auto& h : problem.loaded) handle_vertices.insert(h.corners.begin(), h.corners.end());
  if (r.region.size() <= handle_vertices.size()) {
    double sum = 0;  // mean length of the edges at the handles
    int count = 0;
    for (const auto& h : p.handles)
      for (const int n : mesh.neighbors(h.vertex)) {
        sum += (mesh.positions().row(n) - mesh.positions().row(h.vertex)).norm();
        ++count;
      }
    r.region_warning = fmt::format(
        "the region of influence holds only the handles: a radius of {:.3g} mm is below the {:.3g} mm edges "
        "around them, so only the handles move; give a radius of a few edge lengths",
        p.radius, count ? sum / count : 0.0);
    if (p.radius <= 0) r.region_warning = "the region of influence holds only the handles: only they move";
  }
  r.handle_warning = far_handle_points_warning(mesh, p, 1.0);
  const auto& V0 = mesh.positions();

  // Intersections are always counted (and reported); prevent_intersections only
  // decides whether a correction that creates some is redone.
  std::unique_ptr<SelfIntersectionChecker> own;
  if (!checker) {
    own = std::make_unique<SelfIntersectionChecker>(mesh);
    checker = own.get();
  }
  std::vector<int> check_set(r.region);
  check_set.insert(check_set.end(), already_moved.begin(), already_moved.end());
  std::optional<std::set<std::pair<int, int>>> before;  // pairs at the starting positions, found once
  auto new_pairs = [&](const Positions& V) {
    std::vector<std::pair<int, int>> out;
    if (!before) {
      const auto b = checker->intersecting_pairs(V0, check_set);
      before.emplace(b.begin(), b.end());
    }
    for (const auto& pr : checker->intersecting_pairs(V, check_set))
      if (!before->count(pr)) out.push_back(pr);
    return out;
  };
  auto count_new = [&](const Positions& V) { return static_cast<int>(new_pairs(V).size()); };
  // Pairs that did not intersect at the start are the only ones passed here.
  auto among = [&](const Positions& V, const std::vector<std::pair<int, int>>& pairs) {
    return checker->overlapping_among(V, pairs);
  };

  Field d;
  if (p.method == CorrectionMethod::Springs) {
    d = springs(mesh, p, r.region);
    r.laplacian_reason = "springs: no operator";
    if (p.image.edges) {
      std::vector<int> pulled;
      for (int v : r.region)
        if (p.image.edges->sample(V0.row(v).transpose(), p.image.space)) pulled.push_back(v);
      r.pulled_vertices = static_cast<int>(pulled.size());
      r.image_outside_vertices = static_cast<int>(r.region.size() - pulled.size());
      r.image_mean_edge_before = mean_edge_strength(p.image, pulled, V0);
      r.image_mean_edge_after = mean_edge_strength(p.image, pulled, V0 + d);
    }
    r.new_self_intersections = count_new(V0 + d);  // the thesis method does not prevent them
  } else {
    d = fem_solve(mesh, p, problem, 1.0, r);
    const std::vector<std::pair<int, int>> found = new_pairs(V0 + d);
    r.new_self_intersections = static_cast<int>(found.size());
    if (!found.empty() && p.prevent_intersections) d = guarded_steps(mesh, p, problem, d, found, new_pairs, among, r);
  }
  r.displacement = d;
  r.V = V0 + d;
  double scale = 0;
  for (const auto& h : p.handles) scale = std::max(scale, h.displacement.norm());
  for (int v : r.region) {
    const double len = d.row(v).norm();
    r.max_displacement = std::max(r.max_displacement, len);
    r.moved_vertices += len > 1e-6 * scale;
  }
  r.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace meshpde::correction

namespace meshpde {

CorrectionRegion correction_region(const Mesh& mesh, const CorrectionParams& p) {
  if (p.units != LengthUnit::Millimetre)
    throw InputError(
        fmt::format("correction_region works on a mesh in millimetres, not {}: scale it first", to_string(p.units)));
  correction::validate(mesh, p);
  const CorrectionParams q = correction::normalized(p, mesh);
  CorrectionRegion out;
  out.region = correction::fem_problem(mesh, q).region;
  out.copy = copy_region(mesh, out.region, kCorrectionMarginRings);
  const Eigen::VectorXd all = correction::operator_weights(q, mesh.num_vertices());
  Eigen::VectorXd weights;
  if (all.size()) {
    weights.resize(static_cast<Eigen::Index>(out.copy.to_mesh.size()));
    for (std::size_t k = 0; k < out.copy.to_mesh.size(); ++k)
      weights[static_cast<Eigen::Index>(k)] = all[out.copy.to_mesh[k]];
  }
  out.operators = build_mesh_operators(out.copy.mesh, p.laplacian, weights);
  return out;
}

CorrectionResult correct_vessel(const Mesh& mesh, const CorrectionParams& params,
                                const SelfIntersectionChecker* checker) {
  return correction::correct_vessel_impl(mesh, params, checker, {});
}

struct CorrectionPreview::Impl {
  RegionCopy copy;
  CorrectionParams params;         // in the copy's numbering
  correction::FemProblem problem;  // in the copy's numbering
  correction::FemSetup setup;
  std::unique_ptr<SteadyDirectSolver> solver;
  std::unique_ptr<correction::HandleConstraints> constraints;
  Field unit_held;  // a held handle: its response to a unit value (one column), else empty
  int region_vertices = 0;
};

CorrectionPreview::CorrectionPreview(const Mesh& mesh, const CorrectionParams& params_in, int max_region_vertices)
    : impl_(std::make_unique<Impl>()) {
  if (params_in.units != LengthUnit::Millimetre)
    throw InputError(fmt::format("a correction preview works on a mesh in millimetres, not {}: scale it first",
                                 to_string(params_in.units)));
  if (params_in.handles.size() != 1) throw InputError("a correction preview follows one handle");
  if (params_in.method != CorrectionMethod::Fem || params_in.dynamic || params_in.image.edges)
    throw InputError("a correction preview solves the static fem correction without image guidance");
  correction::validate(mesh, params_in);
  const CorrectionParams p = correction::normalized(params_in, mesh);
  Impl& m = *impl_;
  const correction::FemProblem problem = correction::fem_problem(mesh, p);
  m.region_vertices = static_cast<int>(problem.region.size());
  if (max_region_vertices > 0 && m.region_vertices > max_region_vertices)
    throw InputError(
        fmt::format("a region of {} vertices is too large for a live preview (at most {}); the correction still "
                    "runs on release",
                    m.region_vertices, max_region_vertices));
  m.copy = copy_region(mesh, problem.region, kCorrectionMarginRings);
  // The very steps of a static, unguided correct_vessel (fem_solve_local), so that the
  // preview equals the release to rounding.
  m.params = m.copy.whole ? p : correction::localized(m.copy, p);
  m.problem = m.copy.whole ? problem : correction::localized(m.copy, problem);
  m.setup = correction::fem_setup(m.copy.mesh, m.params, m.problem);
  const Eigen::VectorXd extra = correction::foundations(m.copy.mesh, m.params, m.problem, m.setup);
  const PdeCoefficients coef{.g0 = 0, .g1 = m.params.g1, .g2 = m.params.g2};
  m.solver = std::make_unique<SteadyDirectSolver>(m.setup.mo.mesh, m.setup.mo.ops, coef, m.setup.free,
                                                  SparseCholesky::Backend::Auto,
                                                  extra.maxCoeff() > 0 ? extra : Eigen::VectorXd());
  const int nv = m.copy.mesh.num_vertices();
  m.constraints = std::make_unique<correction::HandleConstraints>(*m.solver, m.problem.loaded, nv);
  if (!m.problem.held.empty()) {
    Field unit = Field::Zero(nv, 1);
    unit(m.problem.held.front().vertex, 0) = 1;
    m.unit_held = m.solver->solve(unit);
  }
}

CorrectionPreview::~CorrectionPreview() = default;

int CorrectionPreview::region_vertices() const {
  return impl_->region_vertices;
}

const std::vector<int>& CorrectionPreview::moving_vertices() const {
  return impl_->copy.to_mesh;
}

void CorrectionPreview::add_displacement(Positions& V, const Eigen::Vector3d& D) const {
  const Impl& m = *impl_;
  Field d;
  if (m.unit_held.size()) {
    d = m.unit_held * D.transpose();
  } else {
    d = Field::Zero(m.copy.mesh.num_vertices(), 3);
    m.constraints->apply(d, std::vector<Eigen::Vector3d>{D});
  }
  for (std::size_t k = 0; k < m.copy.to_mesh.size(); ++k)
    V.row(m.copy.to_mesh[k]) += d.row(static_cast<Eigen::Index>(k));
}

}  // namespace meshpde
