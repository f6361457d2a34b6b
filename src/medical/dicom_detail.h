// Internal to meshpde::medical: what the DICOM reader takes from each file (GDCM, in
// dicom_gdcm.cpp, the one translation unit that includes it) and the geometry it builds
// from those frames (dicom_series.cpp, plain C++).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()
#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace meshpde::detail {

/// One image of a series: a single-frame file, or one frame of a multi-frame file.
struct DicomFrame {
  std::filesystem::path file;
  int frame = 0;            ///< index in a multi-frame file, 0 otherwise
  int frames_in_file = 1;   ///< NumberOfFrames
  std::string series_uid;   ///< (0020,000E)
  int series_number = 0;    ///< (0020,0011)
  std::string description;  ///< (0008,103E)
  std::string modality;     ///< (0008,0060)
  int rows = 0, cols = 0;   ///< (0028,0010), (0028,0011)
  int samples_per_pixel = 1;
  bool has_position = false;  ///< ImagePositionPatient present
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool has_orientation = false;  ///< ImageOrientationPatient present
  Eigen::Vector3d row_dir = Eigen::Vector3d::UnitX(), col_dir = Eigen::Vector3d::UnitY();
  double row_spacing = 1, col_spacing = 1;  ///< PixelSpacing: between rows (j), between columns (i)
  bool has_spacing = false;
  double slice_thickness = 0;  ///< (0018,0050), the spacing of a single slice
  double slope = 1, intercept = 0;
};

/// Walks the element structure of a Part 10 file (dicom_check.cpp) before GDCM parses
/// it: GDCM aborts on some damaged files. \throw InputError naming `name` and the byte
/// at fault.
void check_dicom_structure(const std::string& bytes, const std::string& name);

/// The frames of one file, read up to its pixel data. Empty, with `why_not` set, for a
/// file that is not a DICOM image (no DICM preamble, no pixel data, a DICOMDIR).
/// \throw InputError naming the file when it is DICOM but damaged.
std::vector<DicomFrame> read_dicom_frames(const std::filesystem::path& file, std::string& why_not);
std::vector<DicomFrame> read_dicom_frames_from_memory(const std::string& bytes, const std::string& name,
                                                      std::string& why_not);

/// The stored values of every frame of a file (frame after frame, row after row),
/// decoded from whatever transfer syntax it has; not rescaled. \throw InputError naming
/// the file when its pixels cannot be decoded or do not match rows x cols x frames.
std::vector<float> read_dicom_pixels(const std::filesystem::path& file, int rows, int cols, int frames);
std::vector<float> read_dicom_pixels_from_memory(const std::string& bytes, const std::string& name, int rows, int cols,
                                                 int frames);

/// The grid of a series: its frames in slice order (indices into the input) and the
/// geometry of dicom.h.
struct DicomGrid {
  std::vector<std::size_t> order;
  std::array<int, 3> size{0, 0, 0};
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
};

/// Orders the frames of one series along the slice normal and checks that they form one
/// regular grid. \throw InputError starting with `series` (how the series is named in
/// messages) and naming the frames at fault.
DicomGrid dicom_grid(const std::vector<DicomFrame>& frames, const std::string& series);

/// How a frame is named in messages: its file's name, and ", frame F" in a multi-frame file.
std::string frame_name(const DicomFrame& f);

}  // namespace meshpde::detail
