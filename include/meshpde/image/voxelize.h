// Closed triangle surfaces on voxel grids: which voxels of an image's grid lie inside.
//
// A voxel is inside when its centre is: the winding number of the surface around the
// centre, counted along the grid's rows (i), is not zero. Each triangle that a row
// passes through adds +1 or -1 by its orientation, so the surface's orientation (outward
// or inward) does not matter, nor do non-manifold edges; the surface must be closed.
// The rows sit 3e-5 voxels off the voxel centres, so that a vertex or an edge of a
// surface made from the same grid (on the centres' lines, as marching cubes puts them)
// is never met exactly; a row whose crossings do not sum to zero (rounding at a vertex)
// is counted again on another offset.
//
// With oversampling K > 1 each voxel is K x K x K sub-samples (at (s + 1/2) / K - 1/2
// of a voxel, s = 0..K-1), inside when more than half of them are.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "meshpde/image/volume.h"
#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// A box of voxels: i in [lo[0], hi[0]), j in [lo[1], hi[1]), k in [lo[2], hi[2]).
struct VoxelBox {
  std::array<int, 3> lo{0, 0, 0};
  std::array<int, 3> hi{0, 0, 0};
  bool empty() const { return hi[0] <= lo[0] || hi[1] <= lo[1] || hi[2] <= lo[2]; }
};

/// The whole grid as a box.
VoxelBox whole_grid(const Volume& grid);

/// 1 for each voxel of `grid` (its geometry; values unused) inside the surface (V in LPS
/// millimetres, #V x 3; F, #F x 3), else 0; i fastest, then j, k. Voxels outside `box`
/// (default: the whole grid) are not decided and stay 0.
/// \throw InputError when oversampling is not 1..8, the surface has boundary edges (it is
/// not closed) or a coordinate is not finite.
std::vector<std::uint8_t> voxelize(const Positions& V, const Triangles& F, const Volume& grid, int oversampling = 1,
                                   const VoxelBox* box = nullptr);

/// The smallest box holding the voxels whose centres lie within `margin` voxels of the
/// points (LPS mm), clipped to the grid; empty when none does.
VoxelBox voxel_box_around(const Volume& grid, const std::vector<Eigen::Vector3d>& points_lps, double margin);

}  // namespace meshpde
