#include "meshpde/mesh/units.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>

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

bool plausible(double diagonal_mm, double edge_mm) {
  return diagonal_mm >= kMinDiagonalMm && diagonal_mm <= kMaxDiagonalMm && edge_mm >= kMinEdgeMm &&
         edge_mm <= kMaxEdgeMm;
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

UnitsCheck check_units(const Mesh& mesh, LengthUnit assumed) {
  UnitsCheck c;
  const auto& V = mesh.positions();
  if (V.rows() == 0 || mesh.num_faces() == 0) return c;
  const double s = millimetres_per(assumed);
  c.diagonal_mm = s * (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  c.mean_edge_mm = s * mean_edge_length(mesh);
  c.implausible = !plausible(c.diagonal_mm, c.mean_edge_mm);
  if (!c.implausible) return c;
  double best = 0;
  for (const LengthUnit u : {LengthUnit::Millimetre, LengthUnit::Centimetre, LengthUnit::Metre}) {
    const double f = millimetres_per(u) / s;
    if (u == assumed || !plausible(f * c.diagonal_mm, f * c.mean_edge_mm)) continue;
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
  std::string msg = fmt::format(
      "{}: read in {}, the mesh is {:.3g} mm across with a mean edge of {:.3g} mm, unlike a vessel model "
      "(15 mm to 2 m across, edges of 0.02 to 8 mm)",
      name, to_string(assumed), c.diagonal_mm, c.mean_edge_mm);
  if (c.suggested) {
    const double f = millimetres_per(*c.suggested) / millimetres_per(assumed);
    msg += fmt::format("; if its coordinates are in {}, give {}{} ({:.3g} mm across)", to_string(*c.suggested), option,
                       to_string(*c.suggested), f * c.diagonal_mm);
  }
  return msg;
}

}  // namespace meshpde
