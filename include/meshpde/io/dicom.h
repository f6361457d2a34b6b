// DICOM image series, in the component meshpde::medical. The files are parsed by
// meshpde; compressed pixels are decoded by CharLS (JPEG-LS), OpenJPEG (JPEG 2000) and
// GDCM (the JPEG family), RLE by meshpde.
//
// A series is the images of one SeriesInstanceUID. Its slices are ordered by their
// position along the slice normal (row x column direction cosines), never by file name
// or instance number, and they become one volume in the geometry of volume.h (LPS mm):
//
//   i: along a row (ImageOrientationPatient's first three values), spacing PixelSpacing[1]
//   j: down a column (its last three values), spacing PixelSpacing[0]
//   k: the slice normal, spacing the distance between consecutive slice positions
//   origin: ImagePositionPatient of the first slice in that order
//
// Voxel values are the stored values times RescaleSlope plus RescaleIntercept, slice by
// slice (CT in Hounsfield units). Transfer syntaxes read: implicit and explicit VR little
// endian, explicit VR big endian, deflated, RLE, JPEG baseline, extended and lossless,
// JPEG-LS and JPEG 2000 (lossless and lossy). Enhanced multi-frame files (one file, many
// frames) take each frame's position and orientation from the per-frame and shared
// functional groups.
//
// A series that is not one regular grid is refused with a message naming the series
// and the slices: images of different sizes, orientations or pixel spacings, two
// slices at one position (several echoes or acquisitions in one series), slices that
// are not stacked along their normal (a gantry tilt), or unequal spacing between
// slices (a missing slice shows as one gap twice the others), an image without
// ImageOrientationPatient, ImagePositionPatient or PixelSpacing. No resampling is done.
//
// Files are recognised by the DICM preamble of DICOM Part 10; anything else in a folder
// (DICOMDIR, reports, pictures, files without pixel data) is passed over and listed.
#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/image/volume.h"

namespace meshpde {

/// One series found in a folder: what `meshpde info DIR --json` lists under "series".
struct DicomSeries {
  std::string uid;                                          ///< SeriesInstanceUID
  int number = 0;                                           ///< SeriesNumber (0 when absent)
  std::string description;                                  ///< SeriesDescription
  std::string modality;                                     ///< CT, MR, ...
  std::array<int, 3> size{0, 0, 0};                         ///< voxels along i, j, k
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();        ///< mm along i, j, k
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();         ///< LPS mm of voxel (0, 0, 0)
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  ///< columns: LPS directions of i, j, k
  std::vector<std::filesystem::path> files;                 ///< in slice order (a multi-frame file once)
  /// Why the series is not one regular grid (see above); empty when it reads as a volume.
  std::string problem;
};

/// What a folder holds: its series, ordered by series number, then UID, and the files
/// that were passed over with the reason (`path: reason`).
struct DicomListing {
  std::vector<DicomSeries> series;
  std::vector<std::string> skipped;
};

/// Whether `path` names DICOM input: a folder, a file that starts with the DICM
/// preamble, or a name ending in .dcm or .dicom (any case).
bool is_dicom_path(const std::filesystem::path& path);

/// The series under a folder (recursively), or the series of one file: a multi-frame
/// file alone, else every file of its folder with its SeriesInstanceUID. Reads headers
/// only. \throw InputError naming the path when it holds no DICOM image at all.
DicomListing list_dicom_series(const std::filesystem::path& folder_or_file);

/// The series `choice` names, by UID or by series number; with an empty `choice` the only
/// series. \throw InputError listing every series when `choice` is empty and there are
/// several, or when it names none of them.
const DicomSeries& choose_dicom_series(const DicomListing& listing, const std::string& choice, const std::string& name);

/// The series as a volume (see above). With max_voxels > 0 a series of more voxels is
/// refused before any pixel is decoded. \throw InputError naming the series and file.
Volume read_dicom_series(const std::filesystem::path& folder_or_file, const std::string& choice = "",
                         std::size_t max_voxels = 0);

/// A series from a .zip archive of DICOM files held in memory (a folder zipped for an
/// upload): its files are unpacked under private names into a private temporary folder,
/// read as read_dicom_series reads a folder, and removed. An archive that declares more
/// than `max_bytes` unpacked, or more than 100,000 files, is refused before unpacking.
/// \throw InputError naming `name` (and the file inside it) on a damaged archive.
Volume read_dicom_zip(const std::string& bytes, const std::string& name, const std::string& choice = "",
                      std::size_t max_voxels = 0, std::size_t max_bytes = std::size_t{1} << 32);

/// Parses one file held in memory as read_dicom_series would (its header, then its
/// pixels), for the fuzz target. \throw InputError naming `name`.
Volume read_dicom_file_from_memory(const std::string& bytes, const std::string& name);

}  // namespace meshpde
