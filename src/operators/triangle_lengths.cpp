#include "meshpde/operators/triangle_lengths.h"

#include <cmath>
#include <utility>

namespace meshpde {

double heron_area(double a, double b, double c) {
  // Sorted so that a >= b >= c, as Kahan's formula needs.
  if (a < b) std::swap(a, b);
  if (b < c) std::swap(b, c);
  if (a < b) std::swap(a, b);
  const double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
  return p > 0 ? 0.25 * std::sqrt(p) : 0.0;
}

double cot_opposite(double a, double b, double c) {
  const double A = heron_area(a, b, c);
  return A > 0 ? (b * b + c * c - a * a) / (4 * A) : 0.0;
}

}  // namespace meshpde
