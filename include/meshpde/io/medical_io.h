// Medical-imaging formats, in the separate component meshpde::medical (built on
// VTK 9, kept out of the core library):
//
//  - VTK XML PolyData (.vtp): inline or appended data, raw or base64, zlib
//    compression, UInt32 or UInt64 headers, Float32/Float64 points, Int32/Int64
//    connectivity. Legacy VTK PolyData (.vtk), ascii or binary.
//    Polygons are fan-triangulated (with a warning) and triangle strips unrolled;
//    lines and vertices are ignored with a warning. Point data arrays become
//    vertex_scalars (1 component) or NAME_x/_y/_z (3 components) or point_arrays
//    (others); cell data become cell_arrays, one row per triangle. Each array's
//    VTK type is remembered and written back. A 3D Slicer "SPACE=LPS|RAS" header
//    comment is reported in MeshData::space and written back.
//  - Volumes: MetaImage (.mha, .mhd + raw, compressed or not), NIfTI-1 (.nii,
//    .nii.gz; sform preferred over qform as the NIfTI standard says, scl_slope and
//    scl_inter applied) and NRRD (.nrrd, .nhdr; raw or gzip). Origin, spacing and
//    direction matrix are honoured and returned in LPS (see image/volume.h).
//  - DICOM series (io/dicom.h): parsed by meshpde, compressed pixels decoded by
//    CharLS, OpenJPEG and GDCM.
//
// Errors name the file. Writers are atomic (temporary file, then rename). Linking this
// component registers .vtp, .vtk and the volume formats with io/file_formats.h, so
// read_mesh and write_mesh (io/mesh_io.h) read and write them too.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/image/volume.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/mesh_io.h"

namespace meshpde {

/// .vtp or .vtk. \throw InputError naming the file on malformed input, a file with
/// no polygons, out-of-range indices or non-finite points.
MeshData read_vtk_mesh(const std::filesystem::path& path);
/// Parses bytes held in memory ("vtp" or "vtk" picks the parser; name is for messages).
MeshData read_vtk_mesh_from_memory(const std::string& bytes, const std::string& kind, const std::string& name);

/// .vtp (binary, appended, zlib-compressed) or .vtk (binary legacy), atomically.
void write_vtk_mesh(const std::filesystem::path& path, const MeshData& data);
std::string write_vtk_mesh_to_memory(const MeshData& data, const std::string& kind);

bool is_vtk_mesh_path(const std::filesystem::path& path);

/// .mha .mhd .nii .nii.gz .nrrd .nhdr, or DICOM (a folder holding a series, or one file
/// of it: io/dicom.h): every registered volume format (io/file_formats.h; options
/// there). \throw InputError naming the file.
Volume read_volume(const std::filesystem::path& path, const VolumeReadOptions& options);
Volume read_volume(const std::filesystem::path& path, std::size_t max_voxels = 0);
// Whether read_volume() reads a path: is_volume_path() in mesh_io.h.

/// The volume as a MetaImage file (.mha: one header and 32-bit float voxels, LPS origin
/// and direction as ITK writes them) that read_volume reads back exactly.
/// \throw InputError for a volume that does not validate.
std::string write_metaimage_to_memory(const Volume& volume);

}  // namespace meshpde
