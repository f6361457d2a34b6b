// Scalar volumes (CT/MR images, level sets) placed in the patient's world frame.
//
// World coordinates are millimetres. A volume keeps its geometry the way ITK,
// MetaImage, NRRD and DICOM do, in LPS (x to the patient's Left, y Posterior,
// z Superior):
//
//   p_LPS = origin + direction * (spacing o ijk)
//
// with ijk continuous voxel indices (voxel centres at integers), spacing in mm and
// direction an orthonormal 3x3 matrix whose columns are the LPS directions of the
// i, j and k axes. NIfTI files (RAS world) are converted to this form on reading.
//
// Meshes carry no frame of their own: 3D Slicer writes LPS (it says SPACE=LPS in
// its model headers), vmtk and older Slicer write RAS. The caller says which with
// `Space`; RAS and LPS differ by the sign of x and y.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace meshpde {

enum class Space { LPS, RAS };

/// "lps" or "ras" (any case). \throw InputError otherwise.
Space parse_space(std::string_view text);
const char* to_string(Space space);

/// A point given in `space`, expressed in LPS (RAS -> LPS negates x and y).
inline Eigen::Vector3d to_lps(const Eigen::Vector3d& p, Space space) {
  return space == Space::LPS ? p : Eigen::Vector3d(-p.x(), -p.y(), p.z());
}

struct Volume {
  std::array<int, 3> dims{0, 0, 0};                         ///< voxels along i, j, k
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();        ///< mm per voxel along i, j, k
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();         ///< LPS mm of voxel (0, 0, 0)
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  ///< columns: LPS axes of i, j, k
  std::vector<float> values;                                ///< i fastest, then j, then k
  std::string name;                                         ///< file name, for messages

  std::size_t num_voxels() const {
    return static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) * static_cast<std::size_t>(dims[2]);
  }
  float at(int i, int j, int k) const {
    return values[static_cast<std::size_t>(i) +
                  static_cast<std::size_t>(dims[0]) *
                      (static_cast<std::size_t>(j) + static_cast<std::size_t>(dims[1]) * static_cast<std::size_t>(k))];
  }
  Eigen::Vector3d index_to_lps(const Eigen::Vector3d& ijk) const;
  Eigen::Vector3d lps_to_index(const Eigen::Vector3d& p_lps) const;

  /// Trilinear value at an LPS point; nullopt outside the voxel centres' hull.
  std::optional<double> sample_lps(const Eigen::Vector3d& p_lps) const;
  /// Trilinear value at a point given in `space`.
  std::optional<double> sample(const Eigen::Vector3d& p, Space space) const { return sample_lps(to_lps(p, space)); }
  /// Gradient (value per mm) of the trilinear interpolant at an LPS point, in LPS
  /// components; nullopt outside.
  std::optional<Eigen::Vector3d> gradient_lps(const Eigen::Vector3d& p_lps) const;

  /// \throw InputError (naming the file) on zero dimensions, non-positive or
  /// non-finite spacing, a singular direction, or a value count that does not match.
  void validate() const;
};

/// What `meshpde info` reports of a volume.
struct VolumeReport {
  std::array<int, 3> dims{0, 0, 0};
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();        ///< mm
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();         ///< LPS mm of voxel (0, 0, 0)
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  ///< columns: LPS axes of i, j, k
  /// The anatomical direction each voxel axis points to, nearest of L/R, P/A, S/I, as
  /// ITK writes it: "LPS" for an axial DICOM series, "RAS" for a typical NIfTI.
  std::string orientation;
  bool oblique = false;                                ///< an axis more than 1 degree off the nearest patient axis
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();  ///< LPS mm, over the voxel centres
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  double min = 0, max = 0, mean = 0;  ///< over finite voxel values
  std::size_t nonfinite = 0;          ///< NaN or infinite voxels
};

/// Geometry and value range of a volume.
VolumeReport describe(const Volume& volume);

/// The report as one JSON object ("kind": "volume", "frame": "LPS", the fields above;
/// vectors as [x, y, z], the direction as its rows): what `meshpde info --json` prints
/// of a volume and Python's meshpde.info returns.
std::string to_json(const VolumeReport& report);

/// The volume smoothed by a Gaussian of standard deviation `sigma_mm` (per axis in
/// voxels: sigma_mm / spacing; edges clamped). sigma_mm = 0 returns a copy.
Volume gaussian_smooth(const Volume& volume, double sigma_mm);

/// |grad (G_sigma * I)| in value per mm on the same grid: the "edge strength" map
/// that image-guided correction climbs. Central differences inside, one-sided at
/// the border, converted from index to physical space (direction and spacing).
Volume gradient_magnitude(const Volume& volume, double sigma_mm);

}  // namespace meshpde
