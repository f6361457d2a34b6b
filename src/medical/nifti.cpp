// NIfTI-1 single-file images (.nii, .nii.gz), read by meshpde itself: VTK 9.1's reader
// crashed (SIGBUS, SIGSEGV) on damaged headers. The 348-byte header is read field by
// field at the offsets of the NIfTI-1 standard, in either byte order; gzip is inflated
// only as far as the header says the data reach.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <optional>

#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

constexpr std::size_t kHeaderBytes = 348;

struct Header {
  const std::string& bytes;
  bool swap = false;
  template <class T>
  T get(std::size_t at) const {
    unsigned char b[sizeof(T)];
    std::memcpy(b, bytes.data() + at, sizeof(T));
    if (swap) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }
};

Element nifti_type(int datatype, const std::string& name) {
  switch (datatype) {
    case 2:
      return Element::U8;
    case 4:
      return Element::I16;
    case 8:
      return Element::I32;
    case 16:
      return Element::F32;
    case 64:
      return Element::F64;
    case 256:
      return Element::I8;
    case 512:
      return Element::U16;
    case 768:
      return Element::U32;
    case 1024:
      return Element::I64;
    case 1280:
      return Element::U64;
    default:
      throw InputError(
          fmt::format("{}: NIfTI datatype {} is not a scalar type meshpde reads (complex, RGB?)", name, datatype));
  }
}

}  // namespace

Volume read_nifti(const std::filesystem::path& path, std::size_t max_voxels, StoredVoxels* stored) {
  const std::string name = path.string();
  const std::string file = read_file_bytes(path);
  const bool gz =
      file.size() >= 2 && static_cast<unsigned char>(file[0]) == 0x1f && static_cast<unsigned char>(file[1]) == 0x8b;
  std::optional<Inflater> inflater;
  std::string head;
  if (gz) {
    inflater.emplace(file, 0, name);
    head = inflater->take(kHeaderBytes);
  } else {
    if (file.size() < kHeaderBytes)
      throw InputError(fmt::format("{}: {} bytes, shorter than a NIfTI-1 header (348)", name, file.size()));
    head = file.substr(0, kHeaderBytes);
  }
  Header h{head};
  if (h.get<std::int32_t>(0) != 348) {
    h.swap = true;
    if (h.get<std::int32_t>(0) != 348)
      throw InputError(fmt::format("{}: not a NIfTI-1 file (sizeof_hdr is not 348 in either byte order)", name));
  }
  if (std::memcmp(head.data() + 344, "n+1", 4) != 0)
    throw InputError(fmt::format("{}: not a single-file NIfTI-1 image (magic is not 'n+1')", name));
  const int ndim = h.get<std::int16_t>(40);
  if (ndim < 1 || ndim > 7) throw InputError(fmt::format("{}: dim[0] = {} (must be 1 to 7)", name, ndim));
  std::array<long long, 3> dims{1, 1, 1};
  for (int a = 1; a <= ndim; ++a) {
    const int d = h.get<std::int16_t>(40 + 2 * a);
    if (d < 1) throw InputError(fmt::format("{}: dim[{}] = {}", name, a, d));
    if (a <= 3)
      dims[a - 1] = d;
    else if (d > 1)
      throw InputError(
          fmt::format("{}: dim[{}] = {}: a 3D scalar image is needed (not a time series or vectors)", name, a, d));
  }
  const std::size_t voxels = checked_voxels(dims, name, max_voxels);
  const Element type = nifti_type(h.get<std::int16_t>(70), name);
  const double vox_offset = h.get<float>(108);
  if (!(vox_offset >= 348) || vox_offset > 1e9 || vox_offset != std::floor(vox_offset))
    throw InputError(fmt::format("{}: vox_offset {} (must be a whole number of bytes >= 348)", name, vox_offset));
  const auto offset = static_cast<std::size_t>(vox_offset);
  const VoxelLayout layout{dims, voxels, type, h.swap != (std::endian::native == std::endian::big)};

  Volume v;
  v.name = name;
  v.dims = {static_cast<int>(dims[0]), static_cast<int>(dims[1]), static_cast<int>(dims[2])};
  // The voxels start at vox_offset; in a gzip stream the header is already taken.
  if (stored) {
    if (gz) {
      if (offset - kHeaderBytes + layout.bytes() > inflated_bound(inflater->compressed_size()))
        throw InputError(fmt::format("{}: {} compressed bytes cannot hold {} x {} x {} voxels", name,
                                     inflater->compressed_size(), dims[0], dims[1], dims[2]));
      stored->header = head + inflater->take(offset - kHeaderBytes);
    } else {
      if (file.size() < offset) throw InputError(fmt::format("{}: vox_offset {} is past the file's end", name, offset));
      stored->header = file.substr(0, offset);
    }
    v.values = gz ? inflated_voxels(*inflater, 0, layout, name) : raw_voxels(file, offset, layout, name);
  } else {
    v.values =
        gz ? inflated_voxels(*inflater, offset - kHeaderBytes, layout, name) : raw_voxels(file, offset, layout, name);
  }
  // scl_slope 0 (or not finite) means unscaled, as the standard says.
  double slope = h.get<float>(112), inter = h.get<float>(116);
  if (slope == 0 || !std::isfinite(slope)) slope = 1, inter = 0;
  if (!std::isfinite(inter)) inter = 0;
  if (stored) {
    stored->type = type;
    stored->big_endian = layout.big_endian;
    stored->compressed = gz;
    stored->slope = slope;
    stored->intercept = inter;
  }
  if (slope != 1 || inter != 0)
    for (float& x : v.values) x = static_cast<float>(x * slope + inter);

  // Voxel (i, j, k) to RAS world: the sform when sform_code > 0, else the qform when
  // qform_code > 0, else pixdim scaling alone (the standard's methods 3, 2 and 1).
  double pixdim[4];
  for (int a = 0; a < 4; ++a) pixdim[a] = h.get<float>(76 + 4 * a);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  if (h.get<std::int16_t>(254) > 0) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) A(r, c) = h.get<float>(280 + 16 * r + 4 * c);
      t[r] = h.get<float>(280 + 16 * r + 12);
    }
  } else if (h.get<std::int16_t>(252) > 0) {
    const double b = h.get<float>(256), c = h.get<float>(260), d = h.get<float>(264);
    const double a2 = 1 - (b * b + c * c + d * d);
    const double a = a2 > 0 ? std::sqrt(a2) : 0;  // rounding can leave a2 slightly negative: a = 0 then
    Eigen::Quaterniond q(a, b, c, d);
    if (q.norm() > 0) q.normalize();  // b, c, d beyond the unit ball: the standard's a = 0, renormalized
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const double qfac = pixdim[0] < 0 ? -1 : 1;
    A = R * Eigen::Vector3d(pixdim[1], pixdim[2], qfac * pixdim[3]).asDiagonal();
    for (int r = 0; r < 3; ++r) t[r] = h.get<float>(268 + 4 * r);
  } else {
    A = Eigen::Vector3d(pixdim[1], pixdim[2], pixdim[3]).asDiagonal();
  }
  const Eigen::Matrix3d L = Eigen::Vector3d(-1, -1, 1).asDiagonal();  // RAS -> LPS
  set_geometry_from_axes(v, L * A, L * t);
  v.validate();
  return v;
}

}  // namespace meshpde::detail
