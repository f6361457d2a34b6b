// Volume reading by file name: MetaImage, NIfTI-1 and NRRD, each by meshpde's own
// reader (metaimage.cpp, nifti.cpp, nrrd.cpp), and DICOM series (dicom_series.cpp).
#include <fmt/format.h>

#include <algorithm>

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

Volume read_volume(const std::filesystem::path& path, std::size_t max_voxels) {
  VolumeReadOptions options;
  options.max_voxels = max_voxels;
  return read_volume(path, options);
}

}  // namespace meshpde
