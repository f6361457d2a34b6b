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

SmoothFoundation::SmoothFoundation(double radius, double g1, double g2)
    : radius_(radius), kappa0_(kSmoothStrength * (g2 / (radius * radius * radius * radius) + g1 / (radius * radius))) {
  // The largest entry is kappa0 x^2 / (1 - x)^4 at kSmoothMaxX, about 1e7 kappa0.
  if (!(radius > 0) || !std::isfinite(kappa0_ * 1e8))
    throw InputError(fmt::format("a region radius of {:g} is too small for the smooth boundary", radius));
}

double SmoothFoundation::operator()(double distance) const {
  const double x = std::clamp((distance / radius_ - kSmoothStart) / (1 - kSmoothStart), 0.0, kSmoothMaxX);
  const double y = (1 - x) * (1 - x);
  return kappa0_ * x * x / (y * y);
}

}  // namespace meshpde
