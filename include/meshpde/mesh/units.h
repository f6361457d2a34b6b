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

/// Median over (up to 2,000 evenly spread) vertices of half the distance from the vertex
/// to the surface along its inward normal: the radius of a tube, the local radius of a
/// vessel tree. Mesh units; 0 when no ray meets the surface (an open sheet).
double median_vessel_radius(const Mesh& mesh);

/// What a mesh looks like in millimetres when its coordinates are taken to be in
/// `assumed` units: its bounding-box diagonal, mean edge length and vessel radius.
///
/// The rule (measured on the vessel models of the test data and SimVascular models): a
/// vessel model in millimetres is 15 mm to 2 m across with a mean edge of 0.02 to 8 mm;
/// and a model under 60 mm across whose edges are under 0.15 mm and whose vessels have
/// a median radius under 2 mm is finer than any clinical scanner resolves: a whole aorta
/// read from centimetres (SimVascular's unit: 15 to 40 units across, edges of 0.03 to
/// 0.1, aorta and branches 0.2 to 1.5 in radius) looks exactly like that in millimetres.
struct UnitsCheck {
  double diagonal_mm = 0;   ///< bounding-box diagonal
  double mean_edge_mm = 0;  ///< mean edge length
  /// Median over the vertices of half the distance to the opposite wall along the inward
  /// normal (the vessel's radius there); measured only when diagonal and edge are small
  /// enough for it to matter (0 otherwise).
  double median_radius_mm = 0;
  /// The sizes are unlike a vessel model's in `assumed` units (see above): a 9 mm "aorta"
  /// or a 30 mm one with 0.05 mm edges and 0.8 mm vessels is most likely in centimetres.
  bool implausible = false;
  /// When implausible: the unit under which the sizes are plausible (the one whose
  /// diagonal is nearest 150 mm, if several), or none.
  std::optional<LengthUnit> suggested;
};
UnitsCheck check_units(const Mesh& mesh, LengthUnit assumed);

/// A one-line warning naming `name`, the sizes and the unit suggested, or "" when the
/// sizes are plausible in `assumed` units. `option` is how the caller's user says the
/// unit, the unit's name appended ("--units " on the command line, "units=" in Python);
/// empty: the unit is named alone.
std::string units_warning(const Mesh& mesh, LengthUnit assumed, const std::string& name,
                          const std::string& option = "");

}  // namespace meshpde
