// Local drag: move one vertex by a displacement and let the surface around it
// follow smoothly (seed 000 section 5.3 displacement interpolation; the correction
// of seed 001 in its static form).
//
// The displacement field d (#V x 3) solves the steady problem
//     (g1 K + g2 K D K) d = 0   on the region of influence,
// with d(handle) = displacement and d = 0 outside the region (the two frozen rings
// outside make the join C1 for g2 > 0). Only region vertices are touched.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"

namespace meshpde {

struct DragParams {
  int vertex = 0;                                          ///< handle vertex
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  ///< in mesh units (mm for vessels)
  double radius = 0;  ///< region of influence: edge-path distance from the handle (mesh units); 0: use rings
  int rings = 0;      ///< region of influence in rings of neighbours (used when radius == 0)
  double g1 = 0;      ///< membrane stiffness
  double g2 = 1;      ///< plate (bi-Laplacian) stiffness
  SteadySolver solver = SteadySolver::Direct;
  CgOptions cg{.tolerance = 1e-10, .max_iterations = 50000};  ///< for SteadySolver::Iterative
};

struct DragResult {
  Positions V;                                         ///< deformed positions
  Field displacement;                                  ///< #V x 3
  std::vector<int> region;                             ///< free vertices of the solve
  int moved_vertices = 0;                              ///< |d| > 1e-6 |displacement|
  double max_displacement = 0;                         ///< largest |d|
  Eigen::Vector3d reaction = Eigen::Vector3d::Zero();  ///< force holding the handle
  CgResult cg;
};

/// Vertices whose shortest edge-path distance from `source` is below `radius`,
/// found by Dijkstra restricted to that neighbourhood (cost ~ its size).
std::vector<int> geodesic_ball(const Mesh& mesh, int source, double radius);
/// Vertices within k rings of `source` (the source included).
std::vector<int> ring_ball(const Mesh& mesh, int source, int rings);

/// \throw InputError for a bad vertex or region; SolverError on a breakdown.
DragResult drag_vertex(const Mesh& mesh, const FemOperators& ops, const DragParams& params);

}  // namespace meshpde
