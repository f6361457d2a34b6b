// The cotangent Laplacian L (#V x #V, negative semi-definite, libigl's cotmatrix
// convention): L_ij = 1/2 (cot a_ij + cot b_ij), L_ii = -sum_j L_ij.
//
// Two constructions, both independent of the element formula in fem_operators.h
// (which must satisfy K = -L):
//  - Angles: each corner angle from atan2(|u x v|, u . v), then cot = 1 / tan.
//    Accurate to roundoff even on 0.02-degree slivers.
//  - EdgeLengths: intrinsic, from edge lengths only: cot C = (a^2 + b^2 - c^2) / (4 A)
//    with A from Kahan's stable Heron formula; the basis of intrinsic (Delaunay)
//    operators. On slivers the area is ill-conditioned in the lengths (condition
//    ~ 1 / angle^2), so expect ~1e-11 relative differences on marching-cubes meshes.
// Degenerate triangles (same test as fem_operators.h) contribute nothing.
#pragma once

#include <Eigen/SparseCore>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/triangle_lengths.h"  // heron_area, cot_opposite

namespace meshpde {

enum class CotanFormula { Angles, EdgeLengths };

Eigen::SparseMatrix<double> cotan_laplacian(const Mesh& mesh, CotanFormula formula = CotanFormula::Angles);

}  // namespace meshpde
