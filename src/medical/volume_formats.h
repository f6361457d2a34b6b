// Internal to meshpde::medical: the volume readers of our own (MetaImage and NIfTI-1:
// fuzzing found VTK 9.1's readers of both crash, leak or abort on damaged files), and
// what they share with each other and with the VTK PolyData readers (polydata.h). Every size in a header is checked
// against the bytes present before anything is allocated; every error names the file.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "meshpde/image/volume.h"

namespace meshpde::detail {

/// A whole file's bytes. \throw InputError naming the file when it cannot be read.
std::string read_file_bytes(const std::filesystem::path& path);

/// Inflates zlib or gzip data (detected from its header) on demand, never more than
/// asked for: a header can be read first and the data's size checked before the rest.
class Inflater {
 public:
  Inflater(const std::string& bytes, std::size_t offset, std::string name);
  ~Inflater();
  Inflater(const Inflater&) = delete;
  Inflater& operator=(const Inflater&) = delete;
  /// The next n bytes of the inflated stream. \throw InputError if the stream is
  /// damaged or ends before n bytes.
  std::string take(std::size_t n);
  /// Compressed bytes in the stream (for a bound on what it can inflate to).
  std::size_t compressed_size() const { return compressed_; }

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::size_t compressed_;
  std::string name_;
};

/// The most bytes deflate can expand `compressed` bytes to (its ratio is at most about
/// 1032:1), plus a margin: a larger claimed size is a damaged or hostile header.
std::size_t inflated_bound(std::size_t compressed);

/// Voxel element types of the file formats.
enum class Element { U8, I8, U16, I16, U32, I32, U64, I64, F32, F64 };
std::size_t element_size(Element e);
/// Converts n elements at `data` (big- or little-endian) to float, times `slope` plus
/// `intercept`.
void convert_elements(const char* data, std::size_t n, Element e, bool big_endian, double slope, double intercept,
                      std::vector<float>& out);
/// The same, to double and unscaled (mesh coordinates and arrays keep their precision).
void convert_elements(const char* data, std::size_t n, Element e, bool big_endian, std::vector<double>& out);
/// An unsigned 4- or 8-byte integer at `data` (VTK XML block headers).
std::uint64_t load_unsigned(const char* data, std::size_t bytes, bool big_endian);

/// Lower-cased copy; whitespace-trimmed copy (the header parsers' keys and values).
std::string lower(std::string s);
std::string trim(const std::string& s);

/// Whether a header's data-file value is one plain file name (not a list, a printf
/// pattern like "slice%03d.raw", or several names), the only kind read.
bool is_single_data_file(const std::string& value);

/// How the voxels are stored: their count along i, j, k, their element type and byte order.
struct VoxelLayout {
  std::array<long long, 3> dims{};
  std::size_t voxels = 0;  ///< checked_voxels(dims)
  Element type = Element::F32;
  bool big_endian = false;
  std::size_t bytes() const { return voxels * element_size(type); }
};
/// The voxels stored raw at data[offset...], as floats. \throw InputError naming the
/// file when fewer bytes are there than the layout needs.
std::vector<float> raw_voxels(const std::string& data, std::size_t offset, const VoxelLayout& layout,
                              const std::string& name);
/// The voxels from a compressed stream, after `skip` bytes that precede them (NIfTI's
/// extensions). \throw InputError when the compressed bytes cannot inflate to that much
/// (checked before anything is allocated) or the stream is damaged or short.
std::vector<float> inflated_voxels(Inflater& inflater, std::size_t skip, const VoxelLayout& layout,
                                   const std::string& name);

/// Voxel count of dims, or throws InputError (naming the volume) when a dimension is
/// not positive, the count would overflow, or it exceeds max_voxels (when > 0): called
/// on the header, before any voxel is read or allocated.
std::size_t checked_voxels(const std::array<long long, 3>& dims, const std::string& name, std::size_t max_voxels = 0);

/// Splits A = direction * diag(spacing) into spacing (column norms) and a unit-column
/// direction; sets the origin. \throw InputError for a zero or non-finite column.
void set_geometry_from_axes(Volume& v, const Eigen::Matrix3d& axes, const Eigen::Vector3d& origin_lps);

/// A NRRD file as read: its header as written, and its voxels, with one leading list
/// axis of several values per voxel allowed (a 3D Slicer segmentation's layers).
struct NrrdImage {
  Volume geometry;                                              ///< values set only when components == 1
  std::vector<float> values;                                    ///< components fastest, then i, j, k
  int components = 1;                                           ///< values per voxel (the list axis)
  std::vector<std::string> lines;                               ///< the header lines, magic first, in order
  std::map<std::string, std::string> fields;                    ///< "field: value" lines, fields lower-cased
  std::vector<std::pair<std::string, std::string>> key_values;  ///< "key:=value" lines, in order
  Element type = Element::F32;
  bool big_endian = false;
  std::string encoding;  ///< lower-cased
};
NrrdImage read_nrrd_image(const std::filesystem::path& path, std::size_t max_voxels);

/// How a MetaImage or NIfTI file stores its voxels: what a writer needs to write the
/// same file back with other voxel values (a label map edited in place).
struct StoredVoxels {
  /// NIfTI: the bytes before vox_offset (header and extensions, inflated); MetaImage:
  /// the header lines up to and including ElementDataFile.
  std::string header;
  Element type = Element::F32;
  bool big_endian = false;
  bool compressed = false;
  bool detached = false;            ///< the voxels were in another file (.mhd's ElementDataFile)
  double slope = 1, intercept = 0;  ///< NIfTI's scl_slope and scl_inter as applied
};

Volume read_metaimage(const std::filesystem::path& path, std::size_t max_voxels, StoredVoxels* stored = nullptr);
Volume read_nifti(const std::filesystem::path& path, std::size_t max_voxels, StoredVoxels* stored = nullptr);
Volume read_nrrd(const std::filesystem::path& path, std::size_t max_voxels);

}  // namespace meshpde::detail
