// Volume reading: MetaImage and NIfTI-1 by meshpde's own readers (metaimage.cpp,
// nifti.cpp), NRRD through Teem.
#include <fmt/format.h>
#include <teem/nrrd.h>

#include <algorithm>
#include <cmath>

#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "volume_formats.h"

namespace meshpde {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// NRRD through Teem, the format's reference library: VTK 9.1's vtkNrrdReader
// ignores the space directions and guesses that a first axis of 9 or fewer samples
// holds vector components.
Volume read_nrrd(const std::filesystem::path& path) {
  Nrrd* nrrd = nrrdNew();
  struct Free {
    Nrrd* n;
    ~Free() { nrrdNuke(n); }
  } guard{nrrd};
  if (nrrdLoad(nrrd, path.string().c_str(), nullptr)) {
    char* err = biffGetDone(NRRD);
    std::string message = err ? err : "unreadable";
    free(err);
    while (!message.empty() && message.back() == '\n') message.pop_back();
    for (char& c : message)
      if (c == '\n') c = ' ';
    throw InputError(fmt::format("{}: {}", path.string(), message));
  }
  Volume v;
  v.name = path.string();
  if (nrrd->dim != 3) throw InputError(fmt::format("{}: has {} axes; a 3D scalar image is needed", v.name, nrrd->dim));
  for (int a = 0; a < 3; ++a) v.dims[a] = static_cast<int>(nrrd->axis[a].size);
  const std::size_t n = v.num_voxels();
  v.values.resize(n);
  for (std::size_t i = 0; i < n; ++i) v.values[i] = static_cast<float>(nrrdDLookup[nrrd->type](nrrd->data, i));

  Eigen::Matrix3d L = Eigen::Matrix3d::Identity();  // the file's space -> LPS
  switch (nrrd->space) {
    case nrrdSpaceRightAnteriorSuperior:
    case nrrdSpaceScannerXYZ:
      L = Eigen::Vector3d(-1, -1, 1).asDiagonal();
      break;
    case nrrdSpaceLeftAnteriorSuperior:
      L = Eigen::Vector3d(1, -1, 1).asDiagonal();
      break;
    case nrrdSpaceUnknown:
    case nrrdSpaceLeftPosteriorSuperior:
    case nrrdSpace3DRightHanded:
      break;
    default:
      throw InputError(fmt::format("{}: unsupported NRRD space '{}'", v.name, airEnumStr(nrrdSpace, nrrd->space)));
  }
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  if (nrrd->spaceDim == 3) {
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) axes(r, c) = nrrd->axis[c].spaceDirection[r];
    for (int r = 0; r < 3; ++r) origin[r] = std::isfinite(nrrd->spaceOrigin[r]) ? nrrd->spaceOrigin[r] : 0.0;
  } else {
    for (int c = 0; c < 3; ++c) axes(c, c) = std::isfinite(nrrd->axis[c].spacing) ? nrrd->axis[c].spacing : 1.0;
  }
  detail::set_geometry_from_axes(v, L * axes, L * origin);
  v.validate();
  return v;
}

}  // namespace

namespace {

bool name_ends(const std::filesystem::path& path, const std::string& suffix) {
  const std::string name = lower(path.filename().string());
  return name.size() >= suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

bool is_volume_path(const std::filesystem::path& path) {
  for (const char* e : {".mha", ".mhd", ".nii", ".nii.gz", ".nrrd", ".nhdr"})
    if (name_ends(path, e)) return true;
  return false;
}

Volume read_volume(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("{}: no such file", path.string()));
  auto ends = [&](const std::string& s) { return name_ends(path, s); };
  if (ends(".mha") || ends(".mhd")) return detail::read_metaimage(path);
  if (ends(".nii") || ends(".nii.gz")) return detail::read_nifti(path);
  if (ends(".nrrd") || ends(".nhdr")) return read_nrrd(path);
  throw InputError(
      fmt::format("{}: unknown volume format (supported: .mha .mhd .nii .nii.gz .nrrd .nhdr)", path.string()));
}

}  // namespace meshpde
