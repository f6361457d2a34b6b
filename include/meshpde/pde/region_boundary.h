// How a region of influence of radius R ends: the rule shared by corrections
// (apps/vessel_correction.h) and drag sessions (apps/local_drag.h).
//
// Smooth adds an elastic foundation kappa(s) M_i to the diagonal of the steady system
// at each free vertex i, s its surface distance from the handles:
//
//     kappa(s) = kSmoothStrength (g2 / R^4 + g1 / R^2) x^2 / (1 - x)^4,
//     x = (s / R - kSmoothStart) / (1 - kSmoothStart), clamped to [0, kSmoothMaxX],
//
// zero up to kSmoothStart R, then growing without bound towards R, so that the
// displacement falls like a power of (R - s) and reaches R with zero value and slope
// in the continuous problem: where the last vertices before R fall hardly matters,
// and independent triangulations of one wall agree (docs/vessel-correction.md, "Handles
// at surface points, regions on the surface, the smooth boundary"). x is capped at
// kSmoothMaxX (the last 2 % of the band) to keep the matrix's scale finite. The factor
// (g2 / R^4 + g1 / R^2) is the stiffness of a bending (stretching) mode of wavelength
// about R, so the foundation's grip does not depend on the units or the weights.
// Units: s and R in the mesh's length unit; kappa in those of g2 / length^4.
#pragma once

#include <string>

namespace meshpde {

/// How a region of radius R ends (`--boundary`).
///  - Smooth (default): the region is the surface within distance R of the handles,
///    measured on the surface (mesh/geodesic_distance.h), ended by the foundation
///    above. Nothing at R or beyond moves.
///  - Clamp: the region ends where the vertices do, and the rings beyond are held at
///    zero: nothing beyond R moves, but the boundary moves with h. (A correction's clamp
///    also pulls its free set in to R - h by edge paths: mesh/regions.h's
///    influence_region.)
///  - Fade (corrections only): the free set reaches 2 R by edge paths and a foundation,
///    zero up to 0.6 R and growing as the cube of the distance beyond, takes the
///    displacement down smoothly; vertices between R and 2 R move a little.
enum class RegionBoundary { Clamp, Fade, Smooth };
/// Where Smooth's foundation starts, as a fraction of the radius.
inline constexpr double kSmoothStart = 0.5;
/// Smooth's foundation strength and where its growth is capped (see above).
inline constexpr double kSmoothStrength = 1e3, kSmoothMaxX = 0.98;
/// "smooth", "clamp" or "fade". \throw InputError otherwise.
RegionBoundary parse_region_boundary(const std::string& text);
const char* to_string(RegionBoundary boundary);

/// kappa(s) of Smooth's foundation (above) for a region of radius R and the system's
/// membrane and plate weights g1, g2, per unit of lumped mass: the diagonal entry a free
/// vertex at surface distance s from the handles gets is kappa(s) times its mass M_i.
class SmoothFoundation {
 public:
  /// \throw InputError for a radius so small that the foundation's scale is not finite.
  SmoothFoundation(double radius, double g1, double g2);
  double operator()(double distance) const;

 private:
  double radius_, kappa0_;
};

}  // namespace meshpde
