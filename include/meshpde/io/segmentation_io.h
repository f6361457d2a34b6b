// Segmentations on a voxel grid, in the component meshpde::medical: 3D Slicer's
// .seg.nrrd and plain label maps (.nii/.nii.gz from ITK-SNAP or nnU-Net, .nrrd/.nhdr,
// .mha/.mhd).
//
// A segmentation is a grid (the geometry of image/volume.h, LPS mm) of integer labels in
// one or more layers, and a table of segments, each a label value in a layer. A .seg.nrrd
// holds its layers along a leading list axis and its table in SegmentN_* header fields
// (ID, Name, LabelValue, Layer, Color, Extent; a file without Layer or LabelValue has
// a layer a segment holding 1). A plain label map has one layer and a segment for each
// non-zero label it holds, named "label N".
//
// Written back to the format it was read from, a segmentation keeps its header as it
// was: every field, key/value pair, comment and segment, the voxel type and the
// compression; only the voxels change (and a .seg.nrrd segment's Extent, widened to
// cover its layer's voxels, since 3D Slicer drops voxels outside it). Written to
// another format it gets a header made from its geometry. Writes are atomic.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/image/volume.h"

namespace meshpde {

struct Segment {
  int index = 0;     ///< N of the SegmentN_ fields (a label map: its position in the table)
  std::string id;    ///< SegmentN_ID; a label map's "label_N"
  std::string name;  ///< SegmentN_Name; a label map's "label N"
  int label = 1;     ///< voxel value of the segment in its layer
  int layer = 0;     ///< layer holding it (0 in a label map)
  Eigen::Vector3d color = Eigen::Vector3d::Constant(0.5);  ///< RGB in [0, 1] (SegmentN_Color)
  bool has_color = false;                                  ///< the file gives the colour
};

enum class SegmentationFormat { SlicerNrrd, Nrrd, Nifti, MetaImage };
const char* to_string(SegmentationFormat format);

struct Segmentation {
  Volume geometry;                                       ///< dims, spacing, origin, direction (LPS mm); values empty
  int layers = 1;                                        ///< values per voxel
  std::vector<std::int32_t> labels;                      ///< layers x dims: layer fastest, then i, j, k
  std::vector<Segment> segments;                         ///< the segment table (empty for an empty label map)
  SegmentationFormat format = SegmentationFormat::Nrrd;  ///< what it was read from
  std::string name;                                      ///< the file, for messages

  /// What writing back to the same format keeps (see above): the header as read and the
  /// voxel storage. Filled by read_segmentation; a segmentation made in memory leaves
  /// them empty and gets a generated header.
  struct Source {
    std::vector<std::string> header_lines;  ///< NRRD and MetaImage header lines
    std::string header_bytes;               ///< NIfTI header and extensions
    std::string element;                    ///< voxel type: uint8, int16, ... float64
    bool compressed = false;
    double slope = 1, intercept = 0;  ///< NIfTI's voxel scaling
  } source;

  std::size_t num_voxels() const { return geometry.num_voxels(); }
  std::int32_t at(std::size_t voxel, int layer) const {
    return labels[voxel * static_cast<std::size_t>(layers) + static_cast<std::size_t>(layer)];
  }
};

/// Whether a path names a 3D Slicer segmentation by its extension (.seg.nrrd, any case).
bool is_slicer_segmentation_path(const std::filesystem::path& path);

/// Whether a file is a segmentation with a segment table: a .seg.nrrd, or a NRRD file
/// whose header has SegmentN_ fields (read from its first 64 KB).
bool holds_segments(const std::filesystem::path& path);

/// .seg.nrrd, .nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd. \throw InputError naming the file
/// when it is not a label map (a voxel value that is not a whole number), a segment's
/// fields are malformed, or as read_volume.
Segmentation read_segmentation(const std::filesystem::path& path);

/// Writes by extension (the formats above but .nhdr and .mhd: their data are attached).
/// \throw InputError when a label does not fit the voxel type; Error on a failed write.
void write_segmentation(const std::filesystem::path& path, const Segmentation& segmentation);

/// The segment `choice` names: its name, its ID or its label value. An empty choice takes
/// the only segment. \throw InputError listing the segments otherwise.
const Segment& find_segment(const Segmentation& segmentation, const std::string& choice);

/// 1 where a voxel holds `segment`, else 0 (i fastest, then j, k).
std::vector<std::uint8_t> segment_mask(const Segmentation& segmentation, const Segment& segment);

/// What set_segment() changed.
struct SegmentChange {
  std::size_t added = 0;      ///< voxels that became the segment
  std::size_t removed = 0;    ///< voxels that left it (now background, 0)
  std::size_t conflicts = 0;  ///< voxels inside that hold another segment of the same layer, left to it
};

/// Makes `segment` the voxels where mask is 1, among the voxels where `decide` is 1 (all
/// voxels when `decide` is empty); every other voxel keeps its label. A voxel that
/// leaves the segment becomes background (0); one that joins it takes its label unless
/// another segment of its layer holds it. \throw InputError on a size mismatch.
SegmentChange set_segment(Segmentation& segmentation, const Segment& segment, const std::vector<std::uint8_t>& mask,
                          const std::vector<std::uint8_t>& decide = {});

}  // namespace meshpde
