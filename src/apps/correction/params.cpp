// The rules that resolve a correction request (defaults, which handles are held) and
// its validation.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "correction_internal.h"
#include "meshpde/core/errors.h"

namespace meshpde::correction {

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
                          "move (the caps rule off lets it move)",
                          f));
        continue;
      }
      if (is_held[static_cast<std::size_t>(h.vertex)])
        throw InputError(
            fmt::format("handle vertex {} lies on a cap, which is held: a cap's vertices do not move "
                        "(the caps rule off lets it move)",
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
      throw InputError("the boundary fade takes the fem method with a radius (not rings)");
    if (chosen) throw InputError("the boundary fade takes the direct solver");
  }
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

}  // namespace meshpde::correction
