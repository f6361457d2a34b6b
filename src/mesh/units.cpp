#include "meshpde/mesh/units.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <numeric>

#include "aabb_tree.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

namespace {

// Sizes of vessel models in millimetres: a coronary segment is a few centimetres
// across, a whole aorta with its iliacs half a metre; CT and MR segmentations have
// edges of about a voxel (0.2-2 mm), decimated models a few millimetres.
constexpr double kMinDiagonalMm = 15, kMaxDiagonalMm = 2000;
constexpr double kMinEdgeMm = 0.02, kMaxEdgeMm = 8;
constexpr double kTypicalDiagonalMm = 150;
// Finer than a scanner resolves: small, finely meshed and thin all at once.
constexpr double kFineDiagonalMm = 60, kFineEdgeMm = 0.15, kFineRadiusMm = 2.0;

bool plausible_sizes(double diagonal_mm, double edge_mm) {
  return diagonal_mm >= kMinDiagonalMm && diagonal_mm <= kMaxDiagonalMm && edge_mm >= kMinEdgeMm &&
         edge_mm <= kMaxEdgeMm;
}

bool fine_enough_to_ask(double diagonal_mm, double edge_mm) {
  return diagonal_mm < kFineDiagonalMm && edge_mm < kFineEdgeMm;
}

bool plausible(double diagonal_mm, double edge_mm, double radius_mm) {
  if (!plausible_sizes(diagonal_mm, edge_mm)) return false;
  return !(fine_enough_to_ask(diagonal_mm, edge_mm) && radius_mm > 0 && radius_mm < kFineRadiusMm);
}

}  // namespace

LengthUnit parse_length_unit(std::string_view text) {
  std::string t(text);
  std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
  if (t == "mm") return LengthUnit::Millimetre;
  if (t == "cm") return LengthUnit::Centimetre;
  if (t == "m") return LengthUnit::Metre;
  throw InputError(fmt::format("unknown length unit '{}' (mm, cm or m)", text));
}

const char* to_string(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::Millimetre:
      return "mm";
    case LengthUnit::Centimetre:
      return "cm";
    case LengthUnit::Metre:
      return "m";
  }
  return "mm";
}

double millimetres_per(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::Millimetre:
      return 1;
    case LengthUnit::Centimetre:
      return 10;
    case LengthUnit::Metre:
      return 1000;
  }
  return 1;
}

double median_vessel_radius(const Mesh& mesh) {
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  if (mesh.num_faces() == 0) return 0;
  const detail::Tree tree = detail::triangle_tree(V, F);
  const Eigen::MatrixX3d N = outward_vertex_normals(mesh);
  const int step = std::max(1, mesh.num_vertices() / 2000);
  std::vector<double> radii;
  for (int v = 0; v < mesh.num_vertices(); v += step) {
    const Eigen::Vector3d d = -N.row(v).transpose();
    if (!(d.squaredNorm() > 0)) continue;
    const Eigen::Vector3d o = V.row(v).transpose();
    // Moller-Trumbore against each triangle not at v.
    const double t = tree.first_hit(o, d, [&](int f) {
      if (F(f, 0) == v || F(f, 1) == v || F(f, 2) == v) return std::numeric_limits<double>::infinity();
      const Eigen::Vector3d a = V.row(F(f, 0)), e1 = V.row(F(f, 1)).transpose() - a,
                            e2 = V.row(F(f, 2)).transpose() - a;
      const Eigen::Vector3d h = d.cross(e2);
      const double det = e1.dot(h);
      if (std::abs(det) < 1e-300) return std::numeric_limits<double>::infinity();
      const Eigen::Vector3d sv = o - a;
      const double u = sv.dot(h) / det;
      if (u < 0 || u > 1) return std::numeric_limits<double>::infinity();
      const Eigen::Vector3d q = sv.cross(e1);
      const double w = d.dot(q) / det;
      if (w < 0 || u + w > 1) return std::numeric_limits<double>::infinity();
      const double tt = e2.dot(q) / det;
      return tt > 0 ? tt : std::numeric_limits<double>::infinity();
    });
    if (std::isfinite(t)) radii.push_back(0.5 * t);
  }
  if (radii.empty()) return 0;
  std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(radii.size() / 2), radii.end());
  return radii[radii.size() / 2];
}

UnitsCheck check_units(const Mesh& mesh, LengthUnit assumed) {
  UnitsCheck c;
  const auto& V = mesh.positions();
  if (V.rows() == 0 || mesh.num_faces() == 0) return c;
  const double s = millimetres_per(assumed);
  c.diagonal_mm = s * (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  c.mean_edge_mm = s * mean_edge_length(mesh);
  // The radius only decides among small, finely meshed models (a ray cast a vertex).
  if (fine_enough_to_ask(c.diagonal_mm, c.mean_edge_mm)) c.median_radius_mm = s * median_vessel_radius(mesh);
  c.implausible = !plausible(c.diagonal_mm, c.mean_edge_mm, c.median_radius_mm);
  if (!c.implausible) return c;
  double best = 0;
  for (const LengthUnit u : {LengthUnit::Millimetre, LengthUnit::Centimetre, LengthUnit::Metre}) {
    const double f = millimetres_per(u) / s;
    if (u == assumed || !plausible(f * c.diagonal_mm, f * c.mean_edge_mm, f * c.median_radius_mm)) continue;
    const double distance = std::abs(std::log(f * c.diagonal_mm / kTypicalDiagonalMm));
    if (!c.suggested || distance < best) {
      c.suggested = u;
      best = distance;
    }
  }
  return c;
}

std::string units_warning(const Mesh& mesh, LengthUnit assumed, const std::string& name, const std::string& option) {
  const UnitsCheck c = check_units(mesh, assumed);
  if (!c.implausible) return {};
  std::string msg =
      c.median_radius_mm > 0 && plausible_sizes(c.diagonal_mm, c.mean_edge_mm)
          ? fmt::format(
                "{}: read in {}, the mesh is {:.3g} mm across with a mean edge of {:.3g} mm and vessels of {:.3g} mm "
                "median radius, finer than any scanner resolves (a model under 60 mm across with edges under 0.15 "
                "mm and vessels under 2 mm)",
                name, to_string(assumed), c.diagonal_mm, c.mean_edge_mm, c.median_radius_mm)
          : fmt::format(
                "{}: read in {}, the mesh is {:.3g} mm across with a mean edge of {:.3g} mm, unlike a vessel model "
                "(15 mm to 2 m across, edges of 0.02 to 8 mm)",
                name, to_string(assumed), c.diagonal_mm, c.mean_edge_mm);
  if (c.suggested) {
    const double f = millimetres_per(*c.suggested) / millimetres_per(assumed);
    msg += option.empty() ? fmt::format("; its coordinates may be in {} ({:.3g} mm across)", to_string(*c.suggested),
                                        f * c.diagonal_mm)
                          : fmt::format("; if its coordinates are in {}, give {}{} ({:.3g} mm across)",
                                        to_string(*c.suggested), option, to_string(*c.suggested), f * c.diagonal_mm);
  }
  return msg;
}

}  // namespace meshpde
