// Volume reading by file name: MetaImage, NIfTI-1 and NRRD, each by meshpde's own
// reader (metaimage.cpp, nifti.cpp, nrrd.cpp), and DICOM series (dicom_series.cpp).
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cstring>

#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"
#include "meshpde/io/medical_io.h"
#include "volume_formats.h"

namespace meshpde {
namespace {

bool name_ends(const std::filesystem::path& path, const std::string& suffix) {
  const std::string name = detail::lower(path.filename().string());
  return name.size() >= suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

Volume read_volume(const std::filesystem::path& path, const VolumeReadOptions& options) {
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("{}: no such file", path.string()));
  auto ends = [&](const std::string& s) { return name_ends(path, s); };
  const std::size_t max_voxels = options.max_voxels;
  if (ends(".mha") || ends(".mhd")) return detail::read_metaimage(path, max_voxels);
  if (ends(".nii") || ends(".nii.gz")) return detail::read_nifti(path, max_voxels);
  if (ends(".nrrd") || ends(".nhdr")) return detail::read_nrrd(path, max_voxels);
  if (is_dicom_path(path)) return read_dicom_series(path, options.series, max_voxels);
  throw InputError(fmt::format(
      "{}: unknown volume format (supported: .mha .mhd .nii .nii.gz .nrrd .nhdr, and DICOM: a folder of a series or "
      "one file of it)",
      path.string()));
}

std::string write_metaimage_to_memory(const Volume& v) {
  static_assert(std::endian::native == std::endian::little, "MET_FLOAT is written little-endian");
  v.validate();
  const auto three = [](const Eigen::Vector3d& x) { return fmt::format("{:.17g} {:.17g} {:.17g}", x[0], x[1], x[2]); };
  // ITK's TransformMatrix lists the direction matrix column by column (the LPS
  // direction of i first), as read_metaimage reads it.
  std::string out = fmt::format(
      "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nCompressedData = False\n"
      "TransformMatrix = {} {} {}\nOffset = {}\nElementSpacing = {}\n"
      "DimSize = {} {} {}\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
      three(v.direction.col(0)), three(v.direction.col(1)), three(v.direction.col(2)), three(v.origin),
      three(v.spacing), v.dims[0], v.dims[1], v.dims[2]);
  const std::size_t header = out.size();
  out.resize(header + sizeof(float) * v.values.size());
  std::memcpy(out.data() + header, v.values.data(), sizeof(float) * v.values.size());
  return out;
}

Volume read_volume(const std::filesystem::path& path, std::size_t max_voxels) {
  VolumeReadOptions options;
  options.max_voxels = max_voxels;
  return read_volume(path, options);
}

}  // namespace meshpde
