// A segment of a segmentation and its closed surface, both ways (component
// meshpde::medical; io/segmentation_io.h reads and writes the segmentations).
//
// extract_surface() makes the surface as 3D Slicer's closed-surface conversion does:
// discrete flying edges on the segment's binary label map (padded by one voxel, so the
// surface closes at the grid's border), then, with smoothing F > 0, VTK's windowed-sinc
// filter with 3D Slicer's settings (20 iterations, pass band 10^(-4 F), no boundary or
// feature-edge smoothing). Vertices are in LPS millimetres; triangles face outwards.
//
// voxelize_into() puts a closed surface back (image/voxelize.h decides which voxel
// centres are inside). When the caller gives what moved (the displacement `correct`
// writes), only the voxels between the surface before and after the move are decided
// again, so every other voxel keeps its label exactly; otherwise (or with `full`) every
// voxel of the segment is decided again from the surface.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/image/voxelize.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/io/segmentation_io.h"
#include "meshpde/mesh/field.h"
#include "meshpde/mesh/units.h"

namespace meshpde {

/// Smoothing of extract_surface() by default: 3D Slicer's factor scale (0: none, 0.5:
/// Slicer's default, 1: strong). 0.15 keeps a full re-voxelization of the surface within
/// a Dice coefficient of 0.98 of the segment on thick slices, where Slicer's 0.5 loses
/// more (docs/pipeline.md, "Extraction and re-voxelization").
inline constexpr double kDefaultSegmentSmoothing = 0.15;

/// The closed surface of `segment`, LPS millimetres, with its segment in the field data
/// (Segment_Name, Segment_ID: strings; Segment_LabelValue, Segment_Layer: Int32;
/// Segment_Color: Float64 RGB) and space "LPS".
/// \throw InputError when the segment has no voxels or smoothing is outside [0, 1].
MeshData extract_surface(const Segmentation& segmentation, const Segment& segment,
                         double smoothing = kDefaultSegmentSmoothing);

struct VoxelizeParams {
  int oversampling = 1;  ///< sub-samples along each axis of a voxel (1..8); default 1 (the voxel centre)
  bool full = false;     ///< decide every voxel again even when the displacement is given; default false
};

struct VoxelizeReport {
  SegmentChange change;            ///< voxels added, removed, and left to other segments
  bool partial = false;            ///< only the voxels the move swept were decided
  int moved_vertices = 0;          ///< vertices whose displacement is not zero
  std::size_t decided_voxels = 0;  ///< voxels decided again (partial: those that changed side)
  VoxelBox box;                    ///< voxels looked at
  int vertices_outside_grid = 0;   ///< vertices beyond the grid: the voxels there cannot hold them
};

/// Puts the closed surface (V in LPS mm, F) into `segment` of `segmentation` (see above).
/// `displacement` (#V x 3, mm, or empty): how far each vertex moved to where V puts it.
/// \throw InputError when the surface is not closed, a size does not match, or as voxelize().
VoxelizeReport voxelize_into(Segmentation& segmentation, const Segment& segment, const Positions& V, const Triangles& F,
                             const Field& displacement = {}, const VoxelizeParams& params = {});

/// What voxelize writes into: `path` read as a segmentation when it is one (a .seg.nrrd
/// or a NRRD with SegmentN_ fields, or a label map: a volume file of whole, non-negative
/// values with at most 1,000 labels), else as an image (any volume read_volume reads,
/// DICOM too) whose grid gets a new label map with no segment. `is_image` says which.
/// \throw InputError as read_segmentation and read_volume.
Segmentation voxelize_reference(const std::filesystem::path& path, const VolumeReadOptions& options,
                                bool* is_image = nullptr);

/// The segment of `segmentation` a surface goes into: the one `choice` names (name, ID or
/// label value); without a choice, the one the surface's field data name (Segment_Name,
/// else Segment_LabelValue) when the segmentation has it, else the only segment. A
/// label value (given, or in the field data) that a one-layer segmentation lacks becomes
/// a new segment of that label; with nothing to go by, a segmentation without segments
/// gets segment 1. \throw InputError as find_segment.
Segment segment_for_surface(Segmentation& segmentation, const std::string& choice, const MeshData& surface);

/// A surface file's vertices in LPS millimetres, and what moved them: its vertex field
/// "displacement" (displacement_x/_y/_z, as `correct` writes it), in the same frame and
/// unit, or empty. `space` and `units` say what the file's coordinates are.
struct SurfaceInLps {
  Positions V;
  Field displacement;  ///< #V x 3, or empty
};
SurfaceInLps surface_in_lps(const MeshData& surface, Space space, LengthUnit units);

/// The Dice coefficient 2 |A n B| / (|A| + |B|) of two masks (1 when both are empty).
double dice(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b);

}  // namespace meshpde
