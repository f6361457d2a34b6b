// The file formats meshpde reads and writes, found by the file's name: one registry
// for every front end (the tool, meshpde-mpi, the editor, Python).
//
// The core library registers OBJ, OFF, PLY and STL. The medical component
// (meshpde::medical), when a program links it, registers VTK PolyData (.vtp, .vtk) and
// the volume formats (MetaImage, NIfTI-1, NRRD, DICOM) before main() runs. read_mesh,
// write_mesh (io/mesh_io.h) and read_volume (io/medical_io.h) dispatch through it, so a
// program reads every format its build links, without asking which component is there.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace meshpde {

struct MeshData;
struct WriteOptions;
struct Volume;

/// A mesh format: the extensions it is known by and its in-memory reader and writer.
struct MeshFileFormat {
  std::string name;                     ///< for messages: "VTK XML PolyData"
  std::vector<std::string> extensions;  ///< lower case, with the dot: {".vtp"}
  /// Parses `bytes`; `extension` is the one the name matched, `name` is for messages.
  /// \throw InputError naming `name` on malformed input.
  std::function<MeshData(const std::string& bytes, const std::string& extension, const std::string& name)> read;
  /// Serializes; `extension` as for read.
  std::function<std::string(const MeshData& data, const std::string& extension, const WriteOptions& options)> write;
  bool keeps_vertex_fields = false;  ///< MeshData::vertex_scalars survive a write
  bool keeps_data_arrays = false;    ///< point_arrays and cell_arrays survive a write
  bool keeps_field_data = false;     ///< field_strings and field_arrays survive a write
};

struct VolumeReadOptions {
  /// > 0: a header that declares more voxels is refused before any is read or allocated:
  /// a compressed file of a few megabytes can declare gigabytes (deflate inflates up to
  /// 1,032 times), which is how the editor bounds an uploaded volume. Default 0 (no limit).
  std::size_t max_voxels = 0;
  /// A DICOM folder of several series: the one to read, by SeriesInstanceUID or series
  /// number (io/dicom.h). Default empty: the only series, an error listing them otherwise.
  std::string series;
};

/// A volume format: the endings of the file names it is known by and its reader.
struct VolumeFileFormat {
  std::string name;                   ///< for messages: "NIfTI-1"
  std::vector<std::string> suffixes;  ///< ends of the file name, lower case: {".nii", ".nii.gz"}
  /// Optional: whether the format reads a path its suffixes do not name (DICOM: a
  /// folder holding a series, or a file without an extension).
  std::function<bool(const std::filesystem::path&)> recognizes;
  /// \throw InputError naming the file.
  std::function<Volume(const std::filesystem::path&, const VolumeReadOptions&)> read;
};

/// Adds a format. A later registration of an extension or suffix takes it over.
void register_mesh_format(MeshFileFormat format);
void register_volume_format(VolumeFileFormat format);

/// The mesh format a path's extension (any case) names, or nullptr.
const MeshFileFormat* find_mesh_format(const std::filesystem::path& path);
/// The volume format a path's name ends with (any case), else the first whose
/// `recognizes` accepts the path, else nullptr.
const VolumeFileFormat* find_volume_format(const std::filesystem::path& path);

/// Every registered mesh extension, for messages: ".obj .off .ply .stl" (and ".vtp .vtk"
/// with the medical component).
std::string mesh_extensions();
/// Every registered volume suffix, for messages; empty without the medical component.
std::string volume_extensions();

}  // namespace meshpde
