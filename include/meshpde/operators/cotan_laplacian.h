// The cotangent Laplacian L (#V x #V, negative semi-definite, libigl's cotmatrix
// convention): L_ij = 1/2 (cot a_ij + cot b_ij), L_ii = -sum_j L_ij.
//
// Built intrinsically, from edge lengths only: cot C = (a^2 + b^2 - c^2) / (4 A)
// with A from Kahan's stable Heron formula. This is a construction independent of
// the vector formula in fem_operators.h (which must satisfy K = -L), and the
// starting point of intrinsic (edge-length based) operators.
// Degenerate triangles (same test as fem_operators.h) contribute nothing.
#pragma once

#include <Eigen/SparseCore>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

Eigen::SparseMatrix<double> cotan_laplacian(const Mesh& mesh);

/// Area of a triangle with side lengths a, b, c (Kahan's formula; 0 if the lengths
/// violate the triangle inequality by roundoff).
double heron_area(double a, double b, double c);

}  // namespace meshpde
