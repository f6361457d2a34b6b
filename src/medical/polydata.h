// Internal to meshpde::medical: VTK PolyData files (.vtp XML and legacy .vtk) read by
// readers of our own. Fuzzing found VTK 9.1's readers of both formats crash on damaged
// files (a 2^64-byte allocation from a block header in vtkXMLDataParser, a segfault in
// vtkDataReader::ReadString), so the bytes never reach VTK: every count in a file is
// checked against the bytes present before anything is allocated, and every error names
// the file. VTK still writes these formats (vtk_mesh_io.cpp), and the tests read every
// encoding it writes with both VTK and these readers.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "meshpde/io/mesh_io.h"

namespace meshpde::detail {

/// One cell list of a PolyData (verts, lines, polys or strips): cell c has the point
/// ids connectivity[offsets[c] .. offsets[c + 1]). offsets has one more entry than cells
/// and starts at 0.
struct CellList {
  std::vector<std::int64_t> offsets{0};
  std::vector<std::int64_t> connectivity;
  std::size_t size() const { return offsets.size() - 1; }
};

/// A numeric data array: `tuples` rows of `components` values, row-major.
struct NamedArray {
  std::string name;
  std::string type;  ///< VTK XML type name: Float32, Float64, Int8 ... UInt64
  int components = 1;
  std::vector<double> values;
  std::size_t tuples() const { return components > 0 ? values.size() / static_cast<std::size_t>(components) : 0; }
};

/// A PolyData as the files hold it, before it becomes a triangle mesh.
struct PolyData {
  std::vector<double> points;           ///< 3 per point
  std::string points_type = "Float64";  ///< the VTK XML type name the points were stored as
  CellList verts, lines, polys, strips;
  std::vector<NamedArray> point_arrays, cell_arrays;
  std::string space;                                               ///< "LPS" or "RAS" from a SPACE= tag, else empty
  std::vector<std::pair<std::string, std::string>> field_strings;  ///< field data: string arrays (first string)
  std::vector<NamedArray> field_arrays;                            ///< field data: numeric arrays
  std::vector<std::string> warnings;                               ///< arrays the reader skipped, and why
  std::size_t point_count() const { return points.size() / 3; }
};

/// Parses a VTK XML PolyData file (every piece; ascii, inline base64 and appended raw
/// or base64 data; UInt32 or UInt64 headers; zlib compression; either byte order).
/// \throw InputError naming `name` on any malformed or unsupported input.
PolyData read_vtp_polydata(const std::string& bytes, const std::string& name);

/// Parses a legacy VTK PolyData file (ASCII or BINARY; versions up to 5.1, the cell
/// lists of both the old "n size" and the new OFFSETS/CONNECTIVITY layout).
/// \throw InputError naming `name` and the line on any malformed or unsupported input.
PolyData read_legacy_vtk_polydata(const std::string& bytes, const std::string& name);

/// "LPS" or "RAS" when `text` carries 3D Slicer's SPACE= tag, else empty (the title of a
/// legacy file, the start of an XML one).
std::string detect_space(std::string_view text);

/// Point ids read as numbers (both formats store them in numeric arrays of any type).
/// \throw InputError "`what`: value I (X) is not an integer id" for a value that is not
/// an integer of int64's range.
std::vector<std::int64_t> integer_ids(const std::vector<double>& values, const std::string& what);

/// The triangle mesh of a PolyData: polygons fanned and strips unrolled into triangles
/// (cell data repeated per triangle), vertex and line cells dropped with a warning,
/// 3-component point arrays split into NAME_x/_y/_z scalars.
/// \throw InputError naming `name` when the data are inconsistent (an id out of range,
/// an array of the wrong length, a non-finite point, no polygons).
MeshData mesh_from_polydata(PolyData&& pd, const std::string& name);

}  // namespace meshpde::detail
