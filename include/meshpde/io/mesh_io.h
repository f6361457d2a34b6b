// Reading and writing triangle meshes: OBJ, OFF, PLY (ascii, binary little and big
// endian) and STL (ascii and binary).
//
// Readers never trust a header: counts are checked against the bytes actually
// present before anything is allocated, every error names the file and the line
// (text) or element (binary), and non-finite coordinates or out-of-range indices
// are rejected. Polygons are fan-triangulated with a warning. STL corners at
// identical positions are welded into one vertex.
//
// Writers are atomic: data goes to a temporary file in the target's directory
// which is then renamed over the target, so a failure never leaves half a file.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

enum class MeshFormat { Obj, Off, Ply, Stl };

/// A data array that only some formats carry (VTK point or cell data with any
/// number of components): rows x components values plus the VTK type name it was
/// read as ("Float32", "Int64", ...), so a round trip writes the same type back.
struct DataArray {
  Eigen::MatrixXd values;
  std::string type = "Float64";
};

/// What a reader returns: plain arrays plus per-vertex scalar fields by name.
///
/// Vector fields follow one convention in every format: a 3-component field NAME
/// is stored as the scalars NAME_x, NAME_y, NAME_z (PLY properties as they are;
/// VTK arrays are split on reading and joined again on writing).
struct MeshData {
  Positions V;
  Triangles F;
  std::map<std::string, Eigen::VectorXd> vertex_scalars;  ///< each of length #V
  std::map<std::string, DataArray> point_arrays;          ///< other point data (VTK only: 2, 4+ components)
  std::map<std::string, DataArray> cell_arrays;           ///< cell data, one row per triangle (VTK only)
  std::map<std::string, std::string> scalar_types;        ///< VTK type of a vertex_scalars entry, when read from VTK
  std::string space;  ///< "LPS" or "RAS" when the file says so (3D Slicer's SPACE= header), else empty
  /// The type the points were stored as (VTK files: "Float32" or "Float64"; other
  /// formats "Float64"); the VTK writers write Float32 points as Float32, any other as
  /// Float64.
  std::string points_type = "Float64";
  /// Data about the whole mesh (VTK field data; .vtp keeps them, the other formats drop
  /// them): one-string arrays by name (a segment's Segment_Name), numeric arrays by name
  /// (tuples x components: a segment's Segment_Color is 1 x 3).
  std::map<std::string, std::string> field_strings;
  std::map<std::string, DataArray> field_arrays;
  std::vector<std::string> warnings;  ///< e.g. "triangulated 78 quads"
};

struct WriteOptions {
  bool binary = true;  ///< PLY and STL: binary (default) or ascii. OBJ and OFF are always text.
};

/// Format from the file extension (case-insensitive). \throw InputError if unknown.
MeshFormat format_from_path(const std::filesystem::path& path);

/// Whether a path's name ends as a registered volume format's does, any case (.mha
/// .mhd .nii .nii.gz .nrrd .nhdr with meshpde::medical linked; io/file_formats.h). The
/// name alone decides: nothing is read.
bool is_volume_path(const std::filesystem::path& path);

/// Reads any registered mesh format (io/file_formats.h), chosen by the extension, any
/// case: .obj .off .ply .stl, and .vtp .vtk where meshpde::medical is linked.
/// \throw InputError naming the file and line/element on any malformed input, and for a
/// folder, a volume or an extension no registered format has.
MeshData read_mesh(const std::filesystem::path& path);

/// Parses a mesh held in memory; `name` is used in messages and `format` picks the parser.
MeshData read_mesh_from_memory(const std::string& bytes, MeshFormat format, const std::string& name);
/// The same for any registered format, chosen by the extension of `name`.
MeshData read_mesh_from_memory(const std::string& bytes, const std::string& name);

/// Writes atomically in the registered format the extension names (as read_mesh).
/// Scalar fields are kept by PLY (as vertex properties), .vtp and .vtk; other formats
/// drop them, and point, cell and field data where the format has no place for them,
/// with a warning in the returned list.
/// \throw Error if the file cannot be written (the target is left untouched).
std::vector<std::string> write_mesh(const std::filesystem::path& path, const MeshData& data,
                                    const WriteOptions& options = {});

/// Serializes to bytes (the content write_mesh would write).
std::string write_mesh_to_memory(const MeshData& data, MeshFormat format, const WriteOptions& options = {});
/// The same for any registered format, chosen by the extension of `name`.
std::string write_mesh_to_memory(const MeshData& data, const std::string& name, const WriteOptions& options = {});

/// The face labels a mesh file carries: its cell array ModelFaceID (SimVascular), else
/// CellEntityIds (VMTK), else MaterialIds, when it has one component of whole numbers;
/// empty otherwise. `name` (optional) receives the array's name.
Eigen::VectorXi face_labels(const MeshData& data, std::string* name = nullptr);

/// Recomputes, on data.V and data.F, every 3-component vertex field and cell array whose
/// name says it holds normals (vmtk's Normals_, Slicer's Normals, SimVascular's cell
/// Normals: the name contains "normal" in any case), keeping the file's orientation
/// (inward or outward, whichever the old normals mostly agree with): moved vertices make
/// normals that were read stale. Returns the names of the fields recomputed.
std::vector<std::string> refresh_normal_fields(MeshData& data);

/// Writes `contents` to `path` through a temporary file and a rename.
void write_file_atomically(const std::filesystem::path& path, const std::string& contents);

/// A private name in the system's temporary folder, removed (with whatever is under it)
/// when this object goes, however the scope is left: for readers that take a path,
/// given bytes that came another way (an upload, a zip entry). Nothing is created.
class TemporaryPath {
 public:
  /// The name is `prefix`, this process's id, a serial number and `suffix`.
  explicit TemporaryPath(std::string_view prefix, std::string_view suffix = "");
  ~TemporaryPath();
  TemporaryPath(const TemporaryPath&) = delete;
  TemporaryPath& operator=(const TemporaryPath&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// The whole file's bytes. \throw InputError naming the file when it cannot be opened or read.
std::string read_file(const std::filesystem::path& path);

}  // namespace meshpde
