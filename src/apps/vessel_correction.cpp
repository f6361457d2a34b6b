#include "meshpde/apps/vessel_correction.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"

namespace meshpde {

CorrectionMethod parse_correction_method(const std::string& text) {
  if (text == "fem") return CorrectionMethod::Fem;
  if (text == "springs") return CorrectionMethod::Springs;
  throw InputError(fmt::format("unknown correction method '{}' (expected fem or springs)", text));
}

const char* to_string(CorrectionMethod method) {
  return method == CorrectionMethod::Springs ? "springs" : "fem";
}

namespace {

// "DX,DY,DZ": exactly three finite numbers.
Eigen::Vector3d parse_displacement(const std::string& s) {
  Eigen::Vector3d v;
  std::stringstream ss(s);
  std::string item;
  int k = 0;
  while (std::getline(ss, item, ',')) {
    if (k >= 3) break;
    try {
      std::size_t used = 0;
      v[k] = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(v[k])) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw InputError(fmt::format("move '{}': '{}' is not a number", s, item));
    }
    ++k;
  }
  if (k != 3 || ss.rdbuf()->in_avail() > 0)
    throw InputError(fmt::format("move '{}' must be three comma-separated numbers, e.g. 1.5,0,-2, or normal:D", s));
  return v;
}

// The corner of a surface point's triangle with the largest weight.
int nearest_corner(const Mesh& mesh, const SurfacePoint& p) {
  int k = 0;
  p.bary.maxCoeff(&k);
  return mesh.triangles()(p.face, k);
}

// One move as the user writes it: "DX,DY,DZ" or "normal:D" along `normal()` (a unit
// vector, or zero where there is none: then `where` names the place in the error).
template <class Normal>
Eigen::Vector3d parse_move(const std::string& text, Normal&& normal, const std::string& where) {
  if (text.rfind("normal:", 0) != 0) return parse_displacement(text);
  double dist = 0;
  try {
    std::size_t used = 0;
    dist = std::stod(text.substr(7), &used);
    if (used != text.size() - 7 || !std::isfinite(dist)) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw InputError(fmt::format("move '{}': expected normal:DISTANCE, e.g. normal:2.5", text));
  }
  const Eigen::Vector3d n = normal();
  if (!(n.norm() > 0)) throw InputError(fmt::format("{} has no normal (no incident area)", where));
  return dist * n;
}

void check_counts(std::size_t handles, std::size_t moves) {
  if (handles != moves)
    throw InputError(fmt::format("{} handles but {} moves: give one move per handle", handles, moves));
}

}  // namespace

CorrectionHandle::CorrectionHandle(const Mesh& mesh, const SurfacePoint& p, const Eigen::Vector3d& d)
    : displacement(d), point(p) {
  // The triangle here (vertex needs it); the coordinates with the correction (validate).
  check_surface_point(mesh, SurfacePoint{p.face}, "handle point");
  vertex = nearest_corner(mesh, p);
}

std::vector<CorrectionHandle> parse_handles(const Mesh& mesh, const std::vector<int>& vertices,
                                            const std::vector<std::string>& moves) {
  check_counts(vertices.size(), moves.size());
  std::optional<Eigen::MatrixX3d> normals;  // computed once, if a move is along a normal
  std::vector<CorrectionHandle> handles;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const int v = vertices[k];
    if (v < 0 || v >= mesh.num_vertices())
      throw InputError(
          fmt::format("handle vertex {} is out of range (the mesh has {} vertices)", v, mesh.num_vertices()));
    auto normal = [&]() -> Eigen::Vector3d {
      if (!normals) normals = outward_vertex_normals(mesh);
      return normals->row(v).transpose();
    };
    handles.push_back({v, parse_move(moves[k], normal, fmt::format("vertex {}", v))});
  }
  return handles;
}

std::vector<CorrectionHandle> parse_point_handles(const Mesh& mesh, const std::vector<Eigen::Vector3d>& points,
                                                  const std::vector<std::string>& moves) {
  check_counts(points.size(), moves.size());
  const std::vector<SurfacePoint> at = closest_surface_points(mesh, points);
  std::optional<Eigen::MatrixX3d> normals;
  std::vector<CorrectionHandle> handles;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const SurfacePoint& sp = at[k];
    auto normal = [&]() -> Eigen::Vector3d {
      if (!normals) normals = outward_vertex_normals(mesh);
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      for (int c = 0; c < 3; ++c) n += sp.bary[c] * normals->row(mesh.triangles()(sp.face, c)).transpose();
      return n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : n;
    };
    handles.emplace_back(
        mesh, sp,
        parse_move(moves[k], normal,
                   fmt::format("the point ({:g}, {:g}, {:g})", points[k].x(), points[k].y(), points[k].z())));
  }
  return handles;
}

RegionBoundary parse_region_boundary(const std::string& text) {
  if (text == "smooth") return RegionBoundary::Smooth;
  if (text == "clamp") return RegionBoundary::Clamp;
  if (text == "fade") return RegionBoundary::Fade;
  throw InputError(fmt::format("region boundary '{}': expected smooth, clamp or fade", text));
}

const char* to_string(RegionBoundary boundary) {
  switch (boundary) {
    case RegionBoundary::Smooth:
      return "smooth";
    case RegionBoundary::Clamp:
      return "clamp";
    case RegionBoundary::Fade:
      return "fade";
  }
  return "smooth";
}

namespace {

// The fade's elastic foundation (RegionBoundary::Fade): zero within kFadeStart R, then
// kFadeStrength / R^4 (for the plate; / R^2 for the membrane) times the cube of the
// distance beyond, in units of (1 - kFadeStart) R; the free set reaches kFadeReach R.
// Chosen on jittered planes and their subdivisions (a prototype over these three
// numbers): the region's edge then changes the result about three times less from one
// resolution to the next than the clamp does.
constexpr double kFadeStart = 0.6, kFadeStrength = 1e3, kFadeReach = 2.0;

// Smooth's foundation (RegionBoundary::Smooth): kSmoothStrength (g2 / R^4 + g1 / R^2)
// x^2 / (1 - x)^4 M_i with x = (s / R - kSmoothStart) / (1 - kSmoothStart), s the surface
// distance from the nearest handle: zero up to kSmoothStart R, then growing without
// bound towards R, so that the displacement falls like a power of (R - s) and reaches
// R with zero value and slope in the continuous problem; the last vertices before R,
// wherever they fall, see a field that is already nearly zero. x is capped at
// kSmoothMaxX (the last 2 % of the band) to keep the matrix's scale finite.
constexpr double kSmoothStrength = 1e3, kSmoothMaxX = 0.98;

bool fades(const CorrectionParams& p) {
  return p.method == CorrectionMethod::Fem && p.boundary == RegionBoundary::Fade && p.radius > 0;
}

bool smooth(const CorrectionParams& p) {
  return p.method == CorrectionMethod::Fem && p.boundary == RegionBoundary::Smooth && p.radius > 0;
}

// The handles' size (mm), resolved: CorrectionParams::handle_radius, else its default
// (a fraction of the radius with the smooth boundary, 0 with the clamp and the fade,
// whose rules predate handles with a size), and 0 for the springs method (which moves
// vertices one by one).
double handle_size(const CorrectionParams& p) {
  if (p.method != CorrectionMethod::Fem) return 0;
  if (p.handle_radius >= 0) return p.handle_radius;
  return smooth(p) ? kHandleRadiusFraction * p.radius : 0.0;
}

// Whether a handle is held at its displacement (a vertex of size 0: the rule of
// corrections before handles had a size) rather than pulled there by a load.
bool held_handle(const CorrectionHandle& h, double size) {
  return !h.point && size == 0;
}

// Whether every handle is held and the region ends by the clamp: the cases the
// multigrid, the global and the iterative solvers take.
bool plain_handles(const CorrectionParams& p) {
  const double size = handle_size(p);
  return std::all_of(p.handles.begin(), p.handles.end(),
                     [&](const CorrectionHandle& h) { return held_handle(h, size); });
}

void validate(const Mesh& mesh, const CorrectionParams& p) {
  const int nv = mesh.num_vertices();
  if (p.handles.empty()) throw InputError("a correction needs at least one handle (vertex and displacement)");
  for (const auto& h : p.handles) {
    if (h.point) {
      check_surface_point(mesh, *h.point, "handle point");
    } else if (h.vertex < 0 || h.vertex >= nv) {
      throw InputError(fmt::format("handle vertex {} does not exist (the mesh has {} vertices)", h.vertex, nv));
    }
    if (!h.displacement.allFinite()) throw InputError(fmt::format("displacement of vertex {} is not finite", h.vertex));
  }
  if (std::isnan(p.handle_radius) || std::isinf(p.handle_radius))
    throw InputError("the handle radius must be a finite number (0: a point; < 0: the default)");
  if (!p.held.empty()) {
    std::vector<char> is_held(static_cast<std::size_t>(nv), 0);
    for (const int v : p.held) {
      if (v < 0 || v >= nv)
        throw InputError(fmt::format("held vertex {} does not exist (the mesh has {} vertices)", v, nv));
      is_held[static_cast<std::size_t>(v)] = 1;
    }
    for (const auto& h : p.handles) {
      if (h.point) {
        const auto& F = mesh.triangles();
        const int f = h.point->face;
        if (is_held[static_cast<std::size_t>(F(f, 0))] && is_held[static_cast<std::size_t>(F(f, 1))] &&
            is_held[static_cast<std::size_t>(F(f, 2))])
          throw InputError(
              fmt::format("the handle point in triangle {} lies on a cap, which is held: a cap's vertices do not "
                          "move (caps off lets it move: --caps off, caps=\"off\" in Python)",
                          f));
        continue;
      }
      if (is_held[static_cast<std::size_t>(h.vertex)])
        throw InputError(
            fmt::format("handle vertex {} lies on a cap, which is held: a cap's vertices do not move "
                        "(caps off lets it move: --caps off, caps=\"off\" in Python)",
                        h.vertex));
    }
  }
  if (p.radius <= 0 && p.rings <= 0)
    throw InputError("give a region of influence: a radius in mm or a number of rings");
  if (!(p.radius >= 0) || !std::isfinite(p.radius)) throw InputError("the region radius must be a finite number >= 0");
  if (p.stiffness.size() != 0) {
    if (p.stiffness.size() != nv)
      throw InputError(fmt::format("stiffness field has {} values for {} vertices", p.stiffness.size(), nv));
    for (int i = 0; i < nv; ++i)
      if (!(p.stiffness[i] > 0) || !std::isfinite(p.stiffness[i]))
        throw InputError(fmt::format("stiffness {} at vertex {} must be a finite positive number", p.stiffness[i], i));
  }
  for (double t : {p.tissue.mass, p.tissue.elasticity, p.tissue.viscosity})
    if (!(t >= 0 && t <= 1)) throw InputError(fmt::format("tissue parameter {} is outside [0, 1]", t));
  const std::pair<const char*, const Eigen::VectorXd*> fields[] = {{"mass", &p.tissue.mass_field},
                                                                   {"elasticity", &p.tissue.elasticity_field},
                                                                   {"viscosity", &p.tissue.viscosity_field}};
  for (const auto& [name, f] : fields) {
    if (f->size() == 0) continue;
    if (f->size() != nv) throw InputError(fmt::format("{} field has {} values for {} vertices", name, f->size(), nv));
    for (int i = 0; i < nv; ++i)
      if (!((*f)[i] >= 0 && (*f)[i] <= 1))
        throw InputError(fmt::format("{} {} at vertex {} is outside [0, 1]", name, (*f)[i], i));
  }
  if (p.dynamic && p.steps < 1) throw InputError("a dynamic correction needs steps >= 1");
  const bool chosen = p.solver == SteadySolver::Global || p.solver == SteadySolver::Iterative;
  if (chosen && (p.dynamic || p.image.edges || p.method != CorrectionMethod::Fem))
    throw InputError("the global and iterative solvers take the static fem correction without image guidance only");
  if (chosen && (p.boundary != RegionBoundary::Clamp || !plain_handles(p)))
    throw InputError(
        "the global and iterative solvers take the clamp boundary with vertex handles of size 0 only (the smooth "
        "boundary and handles with a size solve directly)");
  if (p.solver == SteadySolver::Global && !(p.g2 > 0))
    throw InputError("the global solver needs g2 > 0 (a bi-Laplacian term)");
  if (p.image.edges && p.method == CorrectionMethod::Springs && p.image.cube_size < 3)
    throw InputError("the springs method finds edges with the thesis's direction cube: give a cube size (3 or 5)");
  if (p.image.cube_size != 0 && (p.image.cube_size < 3 || p.image.cube_size % 2 == 0))
    throw InputError(fmt::format("direction cube size {} must be odd and at least 3", p.image.cube_size));
  if (p.boundary == RegionBoundary::Fade) {
    if (p.method != CorrectionMethod::Fem || p.radius <= 0)
      throw InputError("--boundary fade takes the fem method with a radius (not rings)");
    if (chosen) throw InputError("--boundary fade takes the direct solver");
  }
}

// A handle that a load pulls to its displacement: the load's weight at each vertex (the
// force's profile, summing to 1) and the handle point's weight at each vertex (where its
// displacement is read: the barycentric coordinates, or 1 at a vertex).
struct LoadedHandle {
  std::vector<std::pair<int, double>> load, point;
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
};

// What a correction solves for, in the mesh's numbering.
struct FemProblem {
  std::vector<int> region;             // vertices that may move, the held handles first
  std::vector<double> distance;        // Smooth: each region vertex's surface distance from the handles
  std::vector<int> sources;            // one vertex per handle (Fade's distances start there)
  std::vector<CorrectionHandle> held;  // vertex handles of size 0, held at their displacement
  std::vector<LoadedHandle> loaded;    // the others
};

// The handle's load: (1 - (d / r)^2)^2 over the surface within r of its point x, d = |y - x|,
// integrated against each corner's hat function triangle by triangle (each triangle cut
// into n^2 pieces, n = 2 * longest edge / r at most 32, one point each: the profile is
// resolved whatever r is against the edges). The triangles are found by walking from the
// point's own across corners, so the load stays on the sheet of the surface the point is
// on. A load too small to integrate (r far below the edges) is the point load itself.
LoadedHandle loaded_handle(const Mesh& mesh, const VertexFaces& around, const CorrectionHandle& h, double size) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  LoadedHandle out;
  out.displacement = h.displacement;
  std::vector<int> start;
  Eigen::Vector3d x;
  if (h.point) {
    for (int k = 0; k < 3; ++k) out.point.emplace_back(F(h.point->face, k), h.point->bary[k]);
    start.push_back(h.point->face);
    x = position(mesh, *h.point);
  } else {
    out.point.emplace_back(h.vertex, 1.0);
    for (int q = around.offsets[static_cast<std::size_t>(h.vertex)];
         q < around.offsets[static_cast<std::size_t>(h.vertex) + 1]; ++q)
      start.push_back(around.faces[static_cast<std::size_t>(q)]);
    x = V.row(h.vertex).transpose();
  }
  if (start.empty()) throw InputError(fmt::format("handle vertex {} belongs to no triangle", h.vertex));
  std::unordered_map<int, double> load;
  if (size > 0) {
    std::set<int> seen(start.begin(), start.end());
    std::vector<int> stack(start.begin(), start.end());
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(),
                            c = V.row(F(f, 2)).transpose();
      if (point_triangle_distance(x, a, b, c) >= size) continue;
      const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
      // Clamped as a double: a tiny size would overflow the conversion to int.
      const int n = static_cast<int>(std::clamp(std::ceil(2 * longest / size), 1.0, 32.0));
      const double piece = 0.5 * (b - a).cross(c - a).norm() / (n * n);
      Eigen::Vector3d w = Eigen::Vector3d::Zero();  // the triangle's load on its corners
      auto add = [&](double lb, double lc) {
        const Eigen::Vector3d l(1 - lb - lc, lb, lc);
        const double t = ((l[0] * a + l[1] * b + l[2] * c) - x).squaredNorm() / (size * size);
        if (t < 1) w += piece * (1 - t) * (1 - t) * l;
      };
      for (int i = 0; i < n; ++i)
        for (int j = 0; i + j < n; ++j) {
          add((i + 1.0 / 3) / n, (j + 1.0 / 3) / n);                      // the piece pointing up
          if (i + j + 2 <= n) add((i + 2.0 / 3) / n, (j + 2.0 / 3) / n);  // and the one pointing down
        }
      for (int k = 0; k < 3; ++k) {
        if (w[k] > 0) load[F(f, k)] += w[k];
        const int v = F(f, k);
        for (int q = around.offsets[static_cast<std::size_t>(v)]; q < around.offsets[static_cast<std::size_t>(v) + 1];
             ++q)
          if (seen.insert(around.faces[static_cast<std::size_t>(q)]).second)
            stack.push_back(around.faces[static_cast<std::size_t>(q)]);
      }
    }
  }
  double total = 0;
  for (const auto& [v, w] : load) total += w;
  if (!(total > 0)) {
    out.load = out.point;
    return out;
  }
  for (const auto& [v, w] : load) out.load.emplace_back(v, w / total);
  std::sort(out.load.begin(), out.load.end());
  return out;
}

// The region of influence and the handles' terms. Smooth: the surface within the radius
// of the handles' points (mesh/geodesic_distance.h). Clamp and Fade: mesh/regions.h's
// edge-path rule from the handles' vertices, clamped at the radius for Fem; with the
// fade, the free set reaches kFadeReach times the radius. Held vertices stay out of the
// region, so that they are held at zero like its outside; a loaded handle's own
// triangle is always in it.
FemProblem fem_problem(const Mesh& mesh, const CorrectionParams& p) {
  FemProblem out;
  const double size = handle_size(p);
  const int nv = mesh.num_vertices();
  std::vector<char> is_held(static_cast<std::size_t>(nv), 0);
  for (const int v : p.held) is_held[static_cast<std::size_t>(v)] = 1;
  std::vector<char> in(static_cast<std::size_t>(nv), 0);
  auto add = [&](int v, double dist) {
    if (is_held[static_cast<std::size_t>(v)] || in[static_cast<std::size_t>(v)]++) return;
    out.region.push_back(v);
    if (smooth(p)) out.distance.push_back(dist);
  };
  for (const auto& h : p.handles) {
    out.sources.push_back(h.vertex);
    if (held_handle(h, size)) {
      out.held.push_back(h);
      add(h.vertex, 0.0);
    }
  }
  if (smooth(p)) {
    GeodesicSources sources;
    for (const auto& h : p.handles) {
      if (h.point)
        sources.points.push_back(*h.point);
      else
        sources.vertices.push_back(h.vertex);
    }
    for (const auto& [v, dist] : geodesic_distances_from(mesh, sources, p.radius)) add(v, dist);
  } else {
    const std::vector<int> region =
        fades(p) ? influence_region(mesh, out.sources, RegionSpec{.radius = kFadeReach * p.radius}, false)
                 : influence_region(mesh, out.sources, RegionSpec{.radius = p.radius, .rings = p.rings},
                                    p.method == CorrectionMethod::Fem);
    for (const int v : region) add(v, 0.0);
  }
  if (p.method != CorrectionMethod::Fem) return out;
  // A loaded handle's point is read from its triangle's corners (or its vertex): they
  // belong to the region whatever the radius.
  for (const auto& h : p.handles) {
    if (held_handle(h, size)) continue;
    if (!h.point) {
      add(h.vertex, 0.0);
      continue;
    }
    const Eigen::Vector3d x = position(mesh, *h.point);
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles()(h.point->face, k);
      add(v, (mesh.positions().row(v).transpose() - x).norm());
    }
  }
  // A region that no held vertex or foundation anchors (it covers its whole part of the
  // surface) moves with its handles as a rigid body: a load could not do that (the
  // system would be singular), so its handles are held at their vertices instead.
  bool anchored = smooth(p) && std::any_of(out.distance.begin(), out.distance.end(),
                                           [&](double dist) { return dist > kSmoothStart * p.radius; });
  for (std::size_t k = 0; k < out.region.size() && !anchored; ++k)
    for (const int w : mesh.neighbors(out.region[k]))
      if (!in[static_cast<std::size_t>(w)]) anchored = true;
  for (const auto& h : p.handles) {
    if (held_handle(h, size)) continue;
    if (!anchored) {
      out.held.emplace_back(h.vertex, h.displacement);
      add(h.vertex, 0.0);
      continue;
    }
    out.loaded.push_back(loaded_handle(mesh, mesh.vertex_faces(), h, size));
  }
  return out;
}

// Image guidance: where along its normal (or, with a cube, at which voxel nearby)
// the edge map is strongest, for each pulled vertex at its current position q.
struct ImageTargets {
  std::vector<int> vertices;  // pulled vertices (inside the image)
  std::vector<Eigen::Vector3d> target;
};

// The thesis's direction cube (eq. 13.7): the centre of the strongest voxel of E in the
// cube of g.cube_size voxels around q (q itself when none is inside the image), in the
// mesh's frame.
Eigen::Vector3d strongest_in_cube(const ImageGuidance& g, const Eigen::Vector3d& q) {
  const Volume& E = *g.edges;
  const Eigen::Vector3d idx = E.lps_to_index(to_lps(q, g.space));
  const int h = g.cube_size / 2;
  double best_value = -1;
  Eigen::Vector3d best = q;
  for (int dk = -h; dk <= h; ++dk)
    for (int dj = -h; dj <= h; ++dj)
      for (int di = -h; di <= h; ++di) {
        const int ii = static_cast<int>(std::lround(idx[0])) + di, jj = static_cast<int>(std::lround(idx[1])) + dj,
                  kk = static_cast<int>(std::lround(idx[2])) + dk;
        if (ii < 0 || jj < 0 || kk < 0 || ii >= E.dims[0] || jj >= E.dims[1] || kk >= E.dims[2]) continue;
        if (E.at(ii, jj, kk) > best_value) {
          best_value = E.at(ii, jj, kk);
          best = to_lps(E.index_to_lps(Eigen::Vector3d(ii, jj, kk)), g.space);  // LPS <-> RAS is an involution
        }
      }
  return best;
}

ImageTargets find_targets(const ImageGuidance& g, const std::vector<int>& pulled, const Positions& Q,
                          const Eigen::MatrixX3d& normals) {
  ImageTargets t;
  const Volume& E = *g.edges;
  const double step = std::min(0.1, 0.25 * E.spacing.minCoeff());
  for (const int i : pulled) {
    const Eigen::Vector3d q = Q.row(i).transpose();
    if (!E.sample(q, g.space)) continue;
    Eigen::Vector3d best = q;
    if (g.cube_size >= 3) {
      best = strongest_in_cube(g, q);
    } else {
      // The nearest ridge of E along the normal: interior local maxima only (a
      // maximum at the end of the window belongs to something farther away), the
      // nearest of those at least half as strong as the strongest.
      const Eigen::Vector3d n = normals.row(i).transpose();
      const int half = static_cast<int>(std::ceil(g.search_radius / step));
      std::vector<double> e(static_cast<std::size_t>(2 * half + 1), -1.0);
      for (int k = -half; k <= half; ++k)
        if (const auto v = E.sample(q + k * step * n, g.space)) e[static_cast<std::size_t>(k + half)] = *v;
      double strongest = -1;
      std::vector<int> ridges;
      for (int k = 1; k + 1 < static_cast<int>(e.size()); ++k)
        if (e[k] > 0 && e[k] >= e[k - 1] && e[k] >= e[k + 1]) {
          ridges.push_back(k);
          strongest = std::max(strongest, e[static_cast<std::size_t>(k)]);
        }
      int chosen = -1;
      for (const int k : ridges)
        if (e[static_cast<std::size_t>(k)] >= 0.5 * strongest &&
            (chosen < 0 || std::abs(k - half) < std::abs(chosen - half)))
          chosen = k;
      if (chosen < 0) continue;  // no edge in reach: the vertex is not pulled
      best = q + (chosen - half) * step * n;
    }
    t.vertices.push_back(i);
    t.target.push_back(best);
  }
  return t;
}

double mean_edge_strength(const ImageGuidance& g, const std::vector<int>& vertices, const Positions& Q) {
  double sum = 0;
  int n = 0;
  for (int i : vertices)
    if (const auto e = g.edges->sample(Q.row(i).transpose(), g.space)) {
      sum += *e;
      ++n;
    }
  return n ? sum / n : 0.0;
}

// Vertex v's value of a tissue property: its field's entry, else the scalar.
double tissue_at(const Eigen::VectorXd& field, double scalar, int v) {
  return field.size() ? field[v] : scalar;
}

// The weights of the Fem operator: the stiffness field times the elasticity field
// relative to p.tissue.elasticity (its largest value after normalized(); at least 1e-3,
// so that no triangle loses all stiffness). Empty when both are absent or every
// weight is 1, so that a constant elasticity field takes the scalar's path exactly.
Eigen::VectorXd operator_weights(const CorrectionParams& p, int nv) {
  const Eigen::VectorXd& e = p.tissue.elasticity_field;
  if (e.size() == 0) return p.stiffness;
  Eigen::VectorXd w = p.stiffness.size() ? p.stiffness : Eigen::VectorXd::Ones(nv);
  bool unit = p.stiffness.size() == 0;
  for (int i = 0; i < nv; ++i) {
    const double r = p.tissue.elasticity > 0 ? std::max(e[i] / p.tissue.elasticity, 1e-3) : 1.0;
    w[i] *= r;
    unit = unit && r == 1.0;
  }
  return unit ? Eigen::VectorXd() : w;
}

// With an elasticity field, its largest value takes the scalar's place (it scales
// (g1, g2) in the dynamic mode, and the field relative to it weighs the operator),
// taken on the whole mesh so that the region's copy weighs alike.
// A point handle's vertex is its nearest corner (the springs method and the edge-path
// regions start there).
CorrectionParams normalized(const CorrectionParams& p, const Mesh& mesh) {
  CorrectionParams q = p;
  if (q.tissue.elasticity_field.size()) q.tissue.elasticity = q.tissue.elasticity_field.maxCoeff();
  for (auto& h : q.handles)
    if (h.point) h.vertex = nearest_corner(mesh, *h.point);
  return q;
}

// The thesis's method (see the header): ring by ring, each vertex moved once to
// where its springs to already-placed neighbours are relaxed down to the
// stability threshold.
Field springs(const Mesh& mesh, const CorrectionParams& p, const std::vector<int>& region) {
  const auto& V = mesh.positions();
  Field d = Field::Zero(mesh.num_vertices(), 3);
  std::vector<char> placed(static_cast<std::size_t>(mesh.num_vertices()), 0);
  for (const int v : p.held) placed[static_cast<std::size_t>(v)] = 1;  // anchors that stay put
  for (const auto& h : p.handles) {
    d.row(h.vertex) = h.displacement.transpose();
    placed[static_cast<std::size_t>(h.vertex)] = 1;
  }
  double scale = 0;
  for (const auto& h : p.handles) scale = std::max(scale, h.displacement.norm());
  for (const int j : region) {
    if (placed[static_cast<std::size_t>(j)]) continue;
    const double c = std::max(tissue_at(p.tissue.elasticity_field, p.tissue.elasticity, j), 1e-3);
    const double viscosity = tissue_at(p.tissue.viscosity_field, p.tissue.viscosity, j);
    const Eigen::Vector3d p0 = V.row(j).transpose();
    std::vector<Eigen::Vector3d> q;
    std::vector<double> rest;
    double mean_rest = 0;
    for (const int i : mesh.neighbors(j))
      if (placed[static_cast<std::size_t>(i)]) {
        q.push_back(V.row(i).transpose() + d.row(i).transpose());
        rest.push_back((V.row(i) - V.row(j)).norm());
        mean_rest += rest.back();
      }
    placed[static_cast<std::size_t>(j)] = 1;
    if (q.empty()) continue;
    mean_rest /= static_cast<double>(q.size());
    // "Stable" when the net spring force is below c * tol: each ring is left that
    // much stretched, so the displacement decays ring by ring (faster with more
    // viscosity), as the thesis reports.
    const double tol = std::max(1e-4 * scale, 0.1 * viscosity * mean_rest);
    const double n = static_cast<double>(q.size());
    auto spring_force = [&](const Eigen::Vector3d& x) {
      Eigen::Vector3d f = Eigen::Vector3d::Zero();
      for (std::size_t k = 0; k < q.size(); ++k) {
        const Eigen::Vector3d r = q[k] - x;
        const double len = r.norm();
        if (len > 0) f += c * (len - rest[k]) / len * r;
      }
      return f;
    };
    // The image step (eq. 13.7), read as a force: towards the strongest voxel of the
    // direction cube around the vertex, c n 0.006 |d| strong, so that the overdamped
    // step moves the vertex 0.003 |d| a step towards it (the thesis moves it by the
    // image's 0.6 of its factor, 0.006 |d|); "stable" then means the springs and the
    // image balance.
    auto image_force = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d {
      if (!p.image.edges) return Eigen::Vector3d::Zero();
      const Eigen::Vector3d to = strongest_in_cube(p.image, x) - x;
      const double len = to.norm();
      return len > 1e-3 * mean_rest ? Eigen::Vector3d(c * n * 0.006 * scale / len * to) : Eigen::Vector3d::Zero();
    };
    Eigen::Vector3d x = p0;
    if (!p.dynamic) {
      const double eta = 0.5 / (c * n);  // overdamped step, stable for unit springs
      for (int it = 0; it < 2000; ++it) {
        const Eigen::Vector3d f = spring_force(x) + image_force(x);
        if (f.norm() <= c * tol) break;
        x += eta * f;
      }
    } else {
      // The thesis's dynamic version: eq. 12.1 with its inertia, m x'' + gamma x' = f,
      // from rest (semi-implicit Euler, dt a tenth of the vertex's period sqrt(m / (c n))),
      // gamma = 2 viscosity sqrt(m c n): viscosity 1 damps the vertex critically between
      // its springs, 0 leaves it ringing until the step limit, where it stays.
      const double m = std::max(tissue_at(p.tissue.mass_field, p.tissue.mass, j), 1e-3);
      const double gamma = 2 * viscosity * std::sqrt(m * c * n);
      const double dt = 0.1 * std::sqrt(m / (c * n));
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (int it = 0; it < 4000; ++it) {
        const Eigen::Vector3d f = spring_force(x) + image_force(x);
        if (f.norm() <= c * tol && v.norm() * 10 * dt <= tol) break;  // at rest within a period
        v += dt / m * (f - gamma * v);
        x += dt * v;
      }
    }
    d.row(j) = (x - p0).transpose();
  }
  return d;
}

struct FemSetup {
  MeshOperators mo;
  std::vector<int> free;
  double length_scale = 1;  // region size in mm, for the dynamic and image scalings
};

FemSetup fem_setup(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem) {
  FemSetup s;
  s.mo = build_mesh_operators(mesh, p.laplacian, operator_weights(p, mesh.num_vertices()));
  std::set<int> handles;
  for (const auto& h : problem.held) handles.insert(h.vertex);
  for (int v : problem.region)
    if (!handles.count(v) && s.mo.ops.mass[v] > 0) s.free.push_back(v);
  s.length_scale = p.radius > 0 ? p.radius : std::max(1e-12, p.rings * mean_edge_length(mesh));
  return s;
}

// The boundary's foundation on the diagonal (#V values; zero for the clamp): the
// fade's kappa(r) M_i, r the edge-path distance from the nearest handle vertex, or
// smooth's kappa(s) M_i, s the surface distance from the handles.
Eigen::VectorXd foundations(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const FemSetup& s) {
  const int nv = mesh.num_vertices();
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(nv);
  if (fades(p)) {
    const std::vector<int>& hv = problem.sources;
    const double R = p.radius;
    // Scaled as the operator is (the dynamic mode weighs it by the elasticity).
    const double kappa0 =
        kFadeStrength * (p.dynamic ? p.tissue.elasticity : 1.0) * (p.g2 / std::pow(R, 4) + p.g1 / (R * R));
    std::vector<char> is_free(static_cast<std::size_t>(nv), 0);
    for (int v : s.free) is_free[static_cast<std::size_t>(v)] = 1;
    for (const auto& [v, dist] : geodesic_distances(mesh, hv, kFadeReach * R + 1e-9 * R)) {
      const double x = std::max(0.0, (dist - kFadeStart * R) / ((1 - kFadeStart) * R));
      if (is_free[static_cast<std::size_t>(v)]) extra[v] += kappa0 * x * x * x * s.mo.ops.mass[v];
    }
  }
  if (smooth(p)) {
    const double R = p.radius;
    const double kappa0 =
        kSmoothStrength * (p.dynamic ? p.tissue.elasticity : 1.0) * (p.g2 / std::pow(R, 4) + p.g1 / (R * R));
    if (!std::isfinite(kappa0 * 1e8))
      throw InputError(fmt::format("a region radius of {:g} mm is too small for the smooth boundary", R));
    // The triangles a handle point is read from carry no foundation: with a radius below
    // an edge they are the whole region, and they must move.
    std::vector<char> own(static_cast<std::size_t>(nv), 0);
    for (const auto& h : problem.loaded)
      for (const auto& [v, w] : h.point) own[static_cast<std::size_t>(v)] = 1;
    for (std::size_t k = 0; k < problem.region.size(); ++k) {
      const int v = problem.region[k];
      if (own[static_cast<std::size_t>(v)]) continue;
      const double x = std::clamp((problem.distance[k] / R - kSmoothStart) / (1 - kSmoothStart), 0.0, kSmoothMaxX);
      extra[v] += kappa0 * x * x / std::pow(1 - x, 4) * s.mo.ops.mass[v];
    }
  }
  return extra;
}

// The loaded handles' constraints on a factored system: each handle's response U_l to its
// load (one solve each, held values zero) and S(k, l), handle k's point in response l.
// A solve's d0 then becomes d0 + sum_l c_l U_l with S c = D - (handle points in d0): the
// handle points land on their displacements, and the force that puts them there is
// spread as their loads say (with a point load, this is the bordered system of a
// point constraint).
class HandleConstraints {
 public:
  HandleConstraints(const SteadyDirectSolver& solver, const std::vector<LoadedHandle>& handles, int nv)
      : handles_(handles) {
    const int n = static_cast<int>(handles.size());
    if (n == 0) return;
    Field load = Field::Zero(nv, n);
    for (int l = 0; l < n; ++l)
      for (const auto& [v, w] : handles[static_cast<std::size_t>(l)].load) load(v, l) = w;
    U_ = solver.solve(Field::Zero(nv, n), &load);
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
    for (int k = 0; k < n; ++k)
      for (const auto& [v, w] : handles[static_cast<std::size_t>(k)].point) S.row(k) += w * U_.row(v);
    lu_.compute(S);
    if (lu_.rank() < n || !(std::abs(lu_.determinant()) > 0))
      throw InputError("two handles are too close to be moved independently: give them further apart, or one handle");
  }
  /// d (#V x 3) with the handle points moved by `fraction` of their displacements.
  void apply(Field& d, double fraction) const {
    std::vector<Eigen::Vector3d> targets;
    for (const auto& h : handles_) targets.push_back(fraction * h.displacement);
    apply(d, targets);
  }
  /// d with handle k's point moved by targets[k].
  void apply(Field& d, const std::vector<Eigen::Vector3d>& targets) const {
    const int n = static_cast<int>(handles_.size());
    if (n == 0) return;
    Eigen::MatrixXd rhs(n, 3);
    for (int k = 0; k < n; ++k) {
      Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
      for (const auto& [v, w] : handles_[static_cast<std::size_t>(k)].point) at += w * d.row(v);
      rhs.row(k) = targets[static_cast<std::size_t>(k)].transpose() - at;
    }
    const Eigen::MatrixXd c = lu_.solve(rhs);
    d += U_ * c;
  }

 private:
  const std::vector<LoadedHandle>& handles_;
  Field U_;
  Eigen::FullPivLU<Eigen::MatrixXd> lu_;
};

// One Fem solve on `mesh` (the region and its margin only) for the handles scaled by
// `fraction`; returns d.
Field fem_solve_local(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, double fraction,
                      CorrectionResult& r) {
  FemSetup s = fem_setup(mesh, p, problem);
  r.laplacian = s.mo.kind;
  r.laplacian_reason = s.mo.reason;
  const int nv = mesh.num_vertices();
  Field held = Field::Zero(nv, 3);
  for (const auto& h : problem.held) held.row(h.vertex) = fraction * h.displacement.transpose();
  const bool guided = p.image.edges != nullptr;
  const double L = s.length_scale;
  // Stiffness of the region's slowest mode (wavelength about 2 L), per unit area.
  const double stiff = std::max(p.g2 * std::pow(M_PI / L, 4) + p.g1 * std::pow(M_PI / L, 2), 1e-300);
  Eigen::VectorXd extra = foundations(mesh, p, problem, s);
  // Image guidance: every free vertex of the region is tied to its target by a
  // spring lambda M_i; weight 1 makes the pull as strong as the region's slowest
  // bending mode, so edges win over smoothness at that scale and above.
  std::vector<int> pulled;
  const double lambda = p.image.weight * stiff;
  if (guided)
    for (int v : s.free) {
      pulled.push_back(v);
      extra[v] += lambda * s.mo.ops.mass[v];
    }
  // Dynamic: implicit steps of alpha M d'' + b1 M d' + Kt d = f with the thesis's
  // parameters (see the header), per vertex: alpha_i M_i and b1_i M_i, and
  // (alpha_i / dt^2 + b1_i / dt) M_i joins the diagonal. Scalars are constant fields.
  const double e = p.tissue.elasticity;  // the largest of an elasticity field (normalized())
  Eigen::VectorXd alpha = Eigen::VectorXd::Zero(nv), b1 = Eigen::VectorXd::Zero(nv);
  double alpha_min = std::numeric_limits<double>::infinity();
  for (int v : s.free) {
    alpha[v] = std::max(tissue_at(p.tissue.mass_field, p.tissue.mass, v), 1e-6);
    alpha_min = std::min(alpha_min, alpha[v]);
  }
  if (s.free.empty()) alpha_min = std::max(p.tissue.mass, 1e-6);
  const double k_eff = std::max(e, 1e-6) * stiff;
  const double omega = std::sqrt(k_eff / alpha_min);
  // A quarter of 1/omega a step (omega of the stiffest, lightest tissue): backward
  // Euler's own damping stays small against the tissue's (so viscosity matters), and
  // the default 50 steps span 12.5 / omega.
  const double dt = 0.25 / omega;
  for (int v : s.free) {
    const double k_v = std::max(tissue_at(p.tissue.elasticity_field, e, v), 1e-6) * stiff;
    b1[v] = 2 * tissue_at(p.tissue.viscosity_field, p.tissue.viscosity, v) * std::sqrt(alpha[v] * k_v);
  }
  const PdeCoefficients coef{.g0 = 0, .g1 = p.dynamic ? e * p.g1 : p.g1, .g2 = p.dynamic ? e * p.g2 : p.g2};
  if (p.dynamic)
    for (int v : s.free) extra[v] += (alpha[v] / (dt * dt) + b1[v] / dt) * s.mo.ops.mass[v];
  // Auto: the multigrid's try on a large static, unguided region without the fade's
  // foundation (the cases the global solver takes), kept where it converges; the direct
  // solve (with its condition estimate) otherwise.
  const bool plain_static = !p.dynamic && !guided && !(extra.maxCoeff() > 0) && problem.loaded.empty();
  r.solver = p.solver == SteadySolver::Auto ? SteadySolver::Direct : p.solver;
  if (p.solver == SteadySolver::Auto && plain_static && auto_tries_multigrid(s.mo.mesh, coef, s.free))
    if (std::optional<SteadySolveResult> g = try_multigrid_solve(s.mo.mesh, s.mo.ops, coef, s.free, held)) {
      r.solver = SteadySolver::Global;
      r.relative_residual = std::max(r.relative_residual, g->relative_residual);
      return std::move(g->values);
    }
  if (r.solver != SteadySolver::Direct) {  // static and unguided (validate() made sure)
    SteadySolveResult sr =
        solve_steady(s.mo.mesh, s.mo.ops, coef, s.free, held, r.solver, kAutoGlobalFromFreeVertices, p.cg);
    r.relative_residual = std::max(r.relative_residual, sr.relative_residual);
    if (!sr.converged) {
      r.converged = false;
      r.solver_message = sr.message;
    }
    return std::move(sr.values);
  }
  const SteadyDirectSolver solver(s.mo.mesh, s.mo.ops, coef, s.free, SparseCholesky::Backend::Auto,
                                  extra.maxCoeff() > 0 ? extra : Eigen::VectorXd());
  const HandleConstraints constraints(solver, problem.loaded, nv);
  const Eigen::MatrixX3d normals = guided ? vertex_normals(mesh) : Eigen::MatrixX3d();
  const auto& V = mesh.positions();
  auto image_load = [&](const Field& d, Field& f) {
    if (!guided) return;
    Positions Q = V + d;
    const ImageTargets t = find_targets(p.image, pulled, Q, normals);
    for (std::size_t k = 0; k < t.vertices.size(); ++k) {
      const int i = t.vertices[k];
      // lambda M_i (target - p_i): the spring's rest point, relative to the original position.
      f.row(i) += lambda * s.mo.ops.mass[i] * (t.target[k] - V.row(i).transpose()).transpose();
    }
  };
  Field d = held;
  double worst = 0;
  if (!p.dynamic) {
    const int passes = guided ? std::max(1, p.image.passes) : 1;
    for (int pass = 0; pass < passes; ++pass) {
      Field f = Field::Zero(nv, 3);
      image_load(d, f);
      d = solver.solve(held, guided ? &f : nullptr);
      worst = std::max(worst, solver.last_relative_residual());
      constraints.apply(d, fraction);
    }
  } else {
    Field prev = Field::Zero(nv, 3), cur = Field::Zero(nv, 3);
    for (const auto& h : problem.held) cur.row(h.vertex) = prev.row(h.vertex) = held.row(h.vertex);
    for (int step = 0; step < p.steps; ++step) {
      Field f = Field::Zero(nv, 3);
      for (int v : s.free)
        f.row(v) = s.mo.ops.mass[v] * (alpha[v] / (dt * dt) * (2 * cur.row(v) - prev.row(v)) + b1[v] / dt * cur.row(v));
      image_load(cur, f);
      Field next = solver.solve(held, &f);
      worst = std::max(worst, solver.last_relative_residual());
      constraints.apply(next, fraction);
      prev = cur;
      cur = next;
    }
    d = cur;
  }
  r.relative_residual = std::max(r.relative_residual, worst);
  // Whether these solves can be trusted to 1e-5 of the drag (badly shaped meshes with
  // the plain cotangent operator cannot): a few extra solves with the same factor.
  const SteadyDirectSolver::Conditioning cond = solver.conditioning();
  r.condition_estimate = std::max(r.condition_estimate, cond.condition_1);
  r.error_bound = std::max(r.error_bound, cond.relative_error);
  if (!cond.sufficient) r.accuracy_warning = cond.message;
  if (guided) {
    r.pulled_vertices = static_cast<int>(pulled.size());
    r.image_mean_edge_before = mean_edge_strength(p.image, pulled, V);
    r.image_mean_edge_after = mean_edge_strength(p.image, pulled, V + d);
  }
  return d;
}

// A correction's parameters and problem in a region copy's numbering.
CorrectionParams localized(const RegionCopy& c, const CorrectionParams& p) {
  CorrectionParams lp = p;
  auto localize = [&](const Eigen::VectorXd& field, Eigen::VectorXd& local) {
    if (field.size() == 0) return;
    local.resize(static_cast<Eigen::Index>(c.to_mesh.size()));
    for (std::size_t k = 0; k < c.to_mesh.size(); ++k) local[static_cast<Eigen::Index>(k)] = field[c.to_mesh[k]];
  };
  localize(p.stiffness, lp.stiffness);
  localize(p.tissue.mass_field, lp.tissue.mass_field);
  localize(p.tissue.elasticity_field, lp.tissue.elasticity_field);
  localize(p.tissue.viscosity_field, lp.tissue.viscosity_field);
  return lp;
}

FemProblem localized(const RegionCopy& c, const FemProblem& problem) {
  FemProblem local;
  local.distance = problem.distance;
  local.region.reserve(problem.region.size());
  for (const int v : problem.region) local.region.push_back(c.local(v));
  for (const int v : problem.sources) local.sources.push_back(c.from_mesh.count(v) ? c.local(v) : -1);
  std::erase(local.sources, -1);
  for (CorrectionHandle h : problem.held) {
    h.vertex = c.local(h.vertex);
    local.held.push_back(h);
  }
  // A load reaching beyond the copy (a handle larger than the region) acts on held
  // vertices there, where it does nothing.
  auto in_copy = [&](const std::vector<std::pair<int, double>>& weights) {
    std::vector<std::pair<int, double>> out;
    for (const auto& [v, w] : weights)
      if (const auto it = c.from_mesh.find(v); it != c.from_mesh.end()) out.emplace_back(it->second, w);
    return out;
  };
  for (const LoadedHandle& h : problem.loaded)
    local.loaded.push_back({in_copy(h.load), in_copy(h.point), h.displacement});
  return local;
}

Field fem_solve(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, double fraction,
                CorrectionResult& r) {
  const RegionCopy c = copy_region(mesh, problem.region, kCorrectionMarginRings);
  if (c.whole) return fem_solve_local(mesh, p, problem, fraction, r);
  const Field dl = fem_solve_local(c.mesh, localized(c, p), localized(c, problem), fraction, r);
  Field d = Field::Zero(mesh.num_vertices(), 3);
  for (std::size_t k = 0; k < c.to_mesh.size(); ++k) d.row(c.to_mesh[k]) = dl.row(static_cast<Eigen::Index>(k));
  return d;
}

}  // namespace

TissueProperty parse_tissue_property(const std::string& text) {
  for (const TissueProperty t :
       {TissueProperty::Stiffness, TissueProperty::Mass, TissueProperty::Elasticity, TissueProperty::Viscosity})
    if (text == to_string(t)) return t;
  throw InputError(fmt::format("unknown tissue property '{}' (stiffness, mass, elasticity or viscosity)", text));
}

const char* to_string(TissueProperty property) {
  switch (property) {
    case TissueProperty::Stiffness:
      return "stiffness";
    case TissueProperty::Mass:
      return "mass";
    case TissueProperty::Elasticity:
      return "elasticity";
    case TissueProperty::Viscosity:
      return "viscosity";
  }
  return "stiffness";
}

void paint_tissue(const Mesh& mesh, CorrectionParams& params, TissueProperty property, const Brush& brush) {
  if (property == TissueProperty::Stiffness) {
    apply_brush(mesh, params.stiffness, brush);
    return;
  }
  if (!(brush.value >= 0 && brush.value <= 1))
    throw InputError(fmt::format("a {} brush paints values in [0, 1], not {}", to_string(property), brush.value));
  TissueParams& t = params.tissue;
  Eigen::VectorXd& field = property == TissueProperty::Mass         ? t.mass_field
                           : property == TissueProperty::Elasticity ? t.elasticity_field
                                                                    : t.viscosity_field;
  const double scalar = property == TissueProperty::Mass         ? t.mass
                        : property == TissueProperty::Elasticity ? t.elasticity
                                                                 : t.viscosity;
  if (field.size() == 0) field = Eigen::VectorXd::Constant(mesh.num_vertices(), scalar);
  apply_brush(mesh, field, brush);
}

void paint_tissue(const Mesh& mesh, CorrectionParams& params, const std::string& text, double millimetres_per_unit) {
  try {
    TissueProperty property = TissueProperty::Stiffness;
    std::string spec = text;
    if (const auto colon = text.find(':');
        colon != std::string::npos && !text.empty() && std::isalpha(static_cast<unsigned char>(text[0]))) {
      property = parse_tissue_property(text.substr(0, colon));
      spec = text.substr(colon + 1);
    }
    Brush brush = parse_brush(mesh, spec);
    brush.radius /= millimetres_per_unit;
    paint_tissue(mesh, params, property, brush);
  } catch (const InputError& e) {
    throw InputError(fmt::format("brush '{}': {}", text, e.what()));
  }
}

CorrectionRegion correction_region(const Mesh& mesh, const CorrectionParams& p) {
  if (p.units != LengthUnit::Millimetre)
    throw InputError(
        fmt::format("correction_region works on a mesh in millimetres, not {}: scale it first", to_string(p.units)));
  validate(mesh, p);
  CorrectionRegion out;
  out.region = fem_problem(mesh, normalized(p, mesh)).region;
  out.copy = copy_region(mesh, out.region, kCorrectionMarginRings);
  const Eigen::VectorXd all = operator_weights(normalized(p, mesh), mesh.num_vertices());
  Eigen::VectorXd weights;
  if (all.size()) {
    weights.resize(static_cast<Eigen::Index>(out.copy.to_mesh.size()));
    for (std::size_t k = 0; k < out.copy.to_mesh.size(); ++k)
      weights[static_cast<Eigen::Index>(k)] = all[out.copy.to_mesh[k]];
  }
  out.operators = build_mesh_operators(out.copy.mesh, p.laplacian, weights);
  return out;
}

namespace {

// The guard's continuation, for a one-shot field `one_shot` (the whole displacement
// solved at once) that creates the new intersections `found`. From each surface
// reached (first the mesh itself) it takes the largest step of the rest of the
// displacement (all of it, its half, its quarter ... down to 1 / max_substeps of the
// whole; from the mesh itself at most half) that creates none, and solves again on
// the operators of the surface reached. When no step fits, the smallest one tried is
// limited by bisection to the largest fraction that creates none, and so is the
// one-shot field: the one that applies more is kept. A step of a static, unguided
// solve is linear in its size (the handles' share), so trying a smaller one costs an
// intersection check, not a solve: the solves are the surfaces reached. With an image
// each step is solved at its size.
//
// Checks: `new_pairs(V)` finds the pairs intersecting at V that did not at the start
// (all triangles of the region: the costly check); `among(V, pairs)` tests given pairs
// only. A state is tried against the pairs met so far first, and only when none of them
// intersects against all. A bisection runs on the pairs met so far, and its answer is
// then checked against all; pairs found there join, and it goes on below that answer.
template <typename NewPairs, typename Among>
Field guarded_steps(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const Field& one_shot,
                    const std::vector<std::pair<int, int>>& found, NewPairs&& new_pairs, Among&& among,
                    CorrectionResult& r) {
  const Positions& V0 = mesh.positions();
  using Pairs = std::vector<std::pair<int, int>>;
  Pairs met;  // new intersections seen so far
  auto meet = [&](const Pairs& more) {
    met.insert(met.end(), more.begin(), more.end());
    std::sort(met.begin(), met.end());
    met.erase(std::unique(met.begin(), met.end()), met.end());
  };
  meet(found);
  auto clean = [&](const Positions& V) {
    if (!among(V, met).empty()) return false;
    const Pairs more = new_pairs(V);
    meet(more);
    return more.empty();
  };
  // The largest t in [0, 1] (to 2^-12) with no new intersection at base + t step; base
  // has none.
  auto limit = [&](const Field& base, const Field& step) {
    double lo = 0, hi = 1;
    for (int round = 0; round < 8; ++round) {
      for (int it = 0; it < 12; ++it) {
        const double mid = 0.5 * (lo + hi);
        (among(V0 + base + mid * step, met).empty() ? lo : hi) = mid;
      }
      if (lo == 0) return 0.0;
      const Pairs more = new_pairs(V0 + base + lo * step);
      if (more.empty()) return lo;
      meet(more);
      hi = lo;
      lo = 0;
    }
    return 0.0;
  };
  const bool linear = p.image.edges == nullptr;
  const double smallest = 1.0 / std::max(1, p.max_substeps);
  Field total = Field::Zero(mesh.num_vertices(), 3);
  double done = 0;
  int steps = 0;
  Mesh cur = mesh;
  Field unit = one_shot;  // linear case: the whole displacement's field from the current state
  bool fresh = true;      // whether `unit` belongs to the current state
  auto step_of = [&](double size) {
    if (!linear) return fem_solve(cur, p, problem, size, r);
    if (!fresh) {
      unit = fem_solve(cur, p, problem, 1.0, r);
      fresh = true;
    }
    return Field(size * unit);
  };
  for (;;) {
    const double remainder = 1 - done;
    double failed = remainder;  // the smallest step tried here (all intersect)
    Field failed_step;          // its field
    bool taken = false;
    // From V0 the whole displacement is the one-shot field, which intersects.
    for (double size = steps == 0 ? 0.5 : remainder; size == remainder || size >= smallest * (1 - 1e-12); size *= 0.5) {
      const Field step = step_of(size);
      if (clean(V0 + total + step)) {
        total += step;
        done += size;
        ++steps;
        taken = true;
        break;
      }
      failed = size;
      failed_step = step;
    }
    if (!taken) {
      // (No step tried when max_substeps allows none smaller than the first: the whole.)
      const Field step = failed_step.size() > 0 ? failed_step : step_of(failed);
      const double t = limit(total, step);
      // The one-shot field limited as a whole may reach farther.
      const double whole = limit(Field::Zero(mesh.num_vertices(), 3), one_shot);
      if (whole >= done + t * failed) {
        total = whole * one_shot;
        done = whole;
        steps = 1;
      } else {
        total += t * step;
        done += t * failed;
        steps += t > 0;
      }
      break;
    }
    if (done >= 1 - 1e-12) break;
    cur.set_positions(V0 + total);
    fresh = false;
  }
  r.substeps = std::max(steps, 1);
  if (done >= 1 - 1e-12) {
    r.intersection_action = fmt::format("split into {} steps", steps);
  } else {
    r.applied_fraction = done;
    r.intersection_action = fmt::format("limited to {:.3f} of the displacement", done);
  }
  r.new_self_intersections = 0;  // every state taken was checked against all pairs
  return total;
}

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
    CorrectionResult r = correct_vessel_impl(Mesh(mesh.positions() * s, mesh.triangles()), mm, nullptr, already_moved);
    r.displacement /= s;
    r.V = mesh.positions() + r.displacement;
    return r;
  }
  const auto t0 = std::chrono::steady_clock::now();
  validate(mesh, p_in);
  const CorrectionParams p = normalized(p_in, mesh);
  CorrectionResult r;
  const FemProblem problem = fem_problem(mesh, p);
  r.region = problem.region;
  r.handle_radius = handle_size(p);
  std::set<int> handle_vertices;  // the held handles, and the corners a point is read from
  for (const auto& h : problem.held) handle_vertices.insert(h.vertex);
  for (const auto& h : problem.loaded)
    for (const auto& [v, w] : h.point) handle_vertices.insert(v);
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

}  // namespace

CorrectionResult correct_vessel(const Mesh& mesh, const CorrectionParams& params,
                                const SelfIntersectionChecker* checker) {
  return correct_vessel_impl(mesh, params, checker, {});
}

struct CorrectionPreview::Impl {
  RegionCopy copy;
  CorrectionParams params;  // in the copy's numbering
  FemProblem problem;       // in the copy's numbering
  FemSetup setup;
  std::unique_ptr<SteadyDirectSolver> solver;
  std::unique_ptr<HandleConstraints> constraints;
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
  validate(mesh, params_in);
  const CorrectionParams p = normalized(params_in, mesh);
  Impl& m = *impl_;
  const FemProblem problem = fem_problem(mesh, p);
  m.region_vertices = static_cast<int>(problem.region.size());
  if (max_region_vertices > 0 && m.region_vertices > max_region_vertices)
    throw InputError(
        fmt::format("a region of {} vertices is too large for a live preview (at most {}); the correction still "
                    "runs on release",
                    m.region_vertices, max_region_vertices));
  m.copy = copy_region(mesh, problem.region, kCorrectionMarginRings);
  // The very steps of a static, unguided correct_vessel (fem_solve_local), so that the
  // preview equals the release to rounding.
  m.params = m.copy.whole ? p : localized(m.copy, p);
  m.problem = m.copy.whole ? problem : localized(m.copy, problem);
  m.setup = fem_setup(m.copy.mesh, m.params, m.problem);
  const Eigen::VectorXd extra = foundations(m.copy.mesh, m.params, m.problem, m.setup);
  const PdeCoefficients coef{.g0 = 0, .g1 = m.params.g1, .g2 = m.params.g2};
  m.solver = std::make_unique<SteadyDirectSolver>(m.setup.mo.mesh, m.setup.mo.ops, coef, m.setup.free,
                                                  SparseCholesky::Backend::Auto,
                                                  extra.maxCoeff() > 0 ? extra : Eigen::VectorXd());
  const int nv = m.copy.mesh.num_vertices();
  m.constraints = std::make_unique<HandleConstraints>(*m.solver, m.problem.loaded, nv);
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

CorrectionSession::CorrectionSession(Mesh mesh)
    : mesh_(std::move(mesh)), history_{mesh_.positions()}, original_checker_(mesh_) {}

CorrectionResult CorrectionSession::apply(const CorrectionParams& params) {
  // The checker keeps the original positions; every vertex moved so far is checked
  // at its current position along with this correction's region.
  CorrectionResult r = correct_vessel_impl(mesh_, params, &original_checker_, touched_);
  std::set<int> t(touched_.begin(), touched_.end());
  for (int v : r.region)
    if (r.displacement.row(v).squaredNorm() > 0) t.insert(v);
  touched_.assign(t.begin(), t.end());
  history_.resize(current_ + 1);
  history_.push_back(r.V);
  ++current_;
  mesh_.set_positions(r.V);
  return r;
}

void CorrectionSession::undo() {
  if (!can_undo()) throw InputError("nothing to undo");
  --current_;
  mesh_.set_positions(history_[current_]);
}

void CorrectionSession::redo() {
  if (!can_redo()) throw InputError("nothing to redo");
  ++current_;
  mesh_.set_positions(history_[current_]);
}

void CorrectionSession::restore(std::vector<Positions> history, std::size_t current) {
  const Positions& original = history_.front();
  if (history.empty() || current >= history.size())
    throw InputError(fmt::format("a history of {} steps cannot be at step {}", history.size(), current));
  std::vector<int> touched;
  std::vector<char> moved(static_cast<std::size_t>(original.rows()), 0);
  for (std::size_t k = 0; k < history.size(); ++k) {
    const Positions& P = history[k];
    if (P.rows() != original.rows() || !P.allFinite())
      throw InputError(fmt::format("history step {}: {} positions for {} vertices, or one not finite", k, P.rows(),
                                   original.rows()));
    if (k == 0 && P != original) throw InputError("history step 0 is not the mesh's own positions");
    for (Eigen::Index v = 0; v < P.rows(); ++v)
      if (!moved[static_cast<std::size_t>(v)] && P.row(v) != original.row(v)) {
        moved[static_cast<std::size_t>(v)] = 1;
        touched.push_back(static_cast<int>(v));
      }
  }
  std::sort(touched.begin(), touched.end());
  history_ = std::move(history);
  current_ = current;
  touched_ = std::move(touched);
  mesh_.set_positions(history_[current_]);
}

int CorrectionSession::new_self_intersections() const {
  return original_checker_.count_new(mesh_.positions(), touched_);
}

}  // namespace meshpde
