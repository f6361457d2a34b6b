// Planar slices through a volume in the patient frame, as 8-bit images after
// window/level: what the editor shows while a segmentation is corrected against the
// image it came from (docs/editor.md, "The image").
//
// A slice is a plane of constant patient coordinate: axial (constant z: S in LPS and
// RAS), coronal (constant y: P in LPS, A in RAS) or sagittal (constant x). Its pixels
// are trilinear samples of the volume on a square grid in that plane, so an oblique
// volume is resampled, not shown in voxel order. Coordinates are millimetres in the
// frame `space` of the mesh being edited (RAS and LPS differ by the sign of x and y).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string_view>
#include <vector>

#include "meshpde/image/volume.h"

namespace meshpde {

enum class SliceAxis { Axial = 0, Coronal = 1, Sagittal = 2 };

/// "axial", "coronal" or "sagittal". \throw InputError otherwise.
SliceAxis parse_slice_axis(std::string_view text);
const char* to_string(SliceAxis axis);

struct SliceParams {
  SliceAxis axis = SliceAxis::Axial;
  double position = 0;  ///< mm: the plane's coordinate along its normal axis (x, y or z of `space`)
  double window = 0;    ///< width of the value range mapped to 0..255; <= 0: the volume's range
  double level = 0;     ///< centre of that range (ignored when window <= 0)
  double pixel_mm = 0;  ///< pixel size; <= 0: the finest voxel spacing
  int max_side = 1024;  ///< pixels along either side at most (the pixel grows to fit)
};

/// A slice's pixels and where they lie. Pixel (a, b) (column a, row b) samples the
/// point origin + a * u + b * v, in `space` millimetres; u and v are the plane's two
/// in-plane axes (axial: x, y; coronal: x, z; sagittal: y, z) scaled to one pixel.
struct Slice {
  SliceAxis axis = SliceAxis::Axial;
  double position = 0;
  int width = 0, height = 0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero(), u = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
  /// width * height values, row b at b * width: round(255 (value - lo) / (hi - lo))
  /// clamped to 0..255 with lo = level - window / 2, hi = level + window / 2; 0 where
  /// the point lies outside the voxel centres' hull.
  std::vector<std::uint8_t> pixels;
};

/// The slice `p` asks for. The plane's extent is the volume's bounding box (its voxel
/// centres, in `space`) projected onto the plane; a position outside the volume's
/// range along the normal gives an all-zero slice of that extent.
/// \throw InputError for non-finite parameters.
Slice slice_volume(const Volume& volume, Space space, const SliceParams& p);

/// The q-quantiles (each in [0, 1]) of the finite voxel values, from at most about
/// `samples` voxels evenly strided: a default window (the 1st to 99th percentile)
/// that ignores a few extreme voxels. Empty volume: zeros.
std::vector<double> volume_quantiles(const Volume& volume, const std::vector<double>& q, std::size_t samples = 1 << 20);

/// The bounding box of the voxel centres in `space` millimetres: {min, max}.
std::pair<Eigen::Vector3d, Eigen::Vector3d> volume_bounds(const Volume& volume, Space space);

}  // namespace meshpde
