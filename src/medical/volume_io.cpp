// Volume reading by file name through the registry (io/file_formats.h), where
// register_formats.cpp puts MetaImage, NIfTI-1, NRRD (meshpde's own readers) and DICOM
// series; and the MetaImage writer.
#include <fmt/format.h>

#include <bit>
#include <cstring>

#include "meshpde/core/errors.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/medical_io.h"

namespace meshpde {

Volume read_volume(const std::filesystem::path& path, const VolumeReadOptions& options) {
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("{}: no such file", path.string()));
  if (const VolumeFileFormat* f = find_volume_format(path)) return f->read(path, options);
  throw InputError(
      fmt::format("{}: unknown volume format (supported: {}, and DICOM: a folder of a series or one file of it)",
                  path.string(), volume_extensions()));
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
