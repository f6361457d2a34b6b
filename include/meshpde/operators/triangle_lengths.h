// A triangle known by its three side lengths only: its area and the cotangents of its
// angles. The one home of these formulas for the intrinsic operators
// (operators/intrinsic_delaunay.h, whose flipped triangles have no positions) and the
// edge-length cotangent construction (operators/cotan_laplacian.h). Units: lengths
// in, length^2 (area) and dimensionless (cotangent) out.
#pragma once

namespace meshpde {

/// Area of a triangle with side lengths a, b, c by Kahan's stable Heron formula
/// ("Miscalculating area and angles of a needle-like triangle"); 0 if the lengths
/// violate the triangle inequality (also by roundoff). Any order of a, b, c.
double heron_area(double a, double b, double c);

/// Cotangent of the angle opposite side a: (b^2 + c^2 - a^2) / (4 A), A = heron_area;
/// 0 for a degenerate triangle (A = 0). Negative for an obtuse angle.
double cot_opposite(double a, double b, double c);

}  // namespace meshpde
