#include "meshpde/pde/region_boundary.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "meshpde/core/errors.h"

namespace meshpde {

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

double smooth_foundation(double distance, double radius, double g1, double g2) {
  const double R = radius;
  const double kappa0 = kSmoothStrength * (g2 / (R * R * R * R) + g1 / (R * R));
  // The largest entry is kappa0 x^2 / (1 - x)^4 at kSmoothMaxX, about 1e7 kappa0.
  if (!(R > 0) || !std::isfinite(kappa0 * 1e8))
    throw InputError(fmt::format("a region radius of {:g} is too small for the smooth boundary", R));
  const double x = std::clamp((distance / R - kSmoothStart) / (1 - kSmoothStart), 0.0, kSmoothMaxX);
  const double y = (1 - x) * (1 - x);
  return kappa0 * x * x / (y * y);
}

}  // namespace meshpde
