// Length units of mesh coordinates. Segmentations come in millimetres (most pipelines,
// 3D Slicer, vmtk), centimetres (SimVascular models) or metres (some STL exporters),
// and the files do not say which. meshpde's lengths given by the user (displacements,
// radii, search distances) and its images are in millimetres; a mesh in other units is
// scaled to millimetres for the computation and written back in its own units.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

enum class LengthUnit { Millimetre, Centimetre, Metre };

/// "mm", "cm" or "m" (any case). \throw InputError otherwise.
LengthUnit parse_length_unit(std::string_view text);
/// "mm", "cm" or "m".
const char* to_string(LengthUnit unit);
/// Millimetres in one `unit`: 1, 10 or 1000.
double millimetres_per(LengthUnit unit);

/// What a mesh looks like in millimetres when its coordinates are taken to be in
/// `assumed` units: its bounding-box diagonal and mean edge length.
struct UnitsCheck {
  double diagonal_mm = 0;   ///< bounding-box diagonal
  double mean_edge_mm = 0;  ///< mean edge length
  /// The sizes lie outside what a vessel model has (a diagonal of 15 mm to 2 m, a mean
  /// edge of 0.02 to 8 mm): a 9 mm "aorta" is most likely in centimetres.
  bool implausible = false;
  /// When implausible: the unit under which both sizes are plausible (the one whose
  /// diagonal is nearest 150 mm, if several), or none.
  std::optional<LengthUnit> suggested;
};
UnitsCheck check_units(const Mesh& mesh, LengthUnit assumed);

/// A one-line warning naming `name`, the sizes and the unit suggested, or "" when the
/// sizes are plausible in `assumed` units. `option` is how the caller's user says the
/// unit, the unit's name appended: "--units " on the command line, "units=" in Python.
std::string units_warning(const Mesh& mesh, LengthUnit assumed, const std::string& name,
                          const std::string& option = "--units ");

}  // namespace meshpde
