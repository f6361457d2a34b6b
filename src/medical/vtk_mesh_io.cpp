// VTK PolyData reading and writing (.vtp XML, .vtk legacy) through VTK 9.
#include <fmt/format.h>
#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataReader.h>
#include <vtkPolyDataWriter.h>
#include <vtkSmartPointer.h>
#include <vtkType.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "vtk_capture.h"

namespace meshpde {
namespace {

struct TypeName {
  int vtk;
  const char* name;
};
constexpr TypeName kTypes[] = {
    {VTK_FLOAT, "Float32"},
    {VTK_DOUBLE, "Float64"},
    {VTK_SIGNED_CHAR, "Int8"},
    {VTK_CHAR, "Int8"},
    {VTK_UNSIGNED_CHAR, "UInt8"},
    {VTK_SHORT, "Int16"},
    {VTK_UNSIGNED_SHORT, "UInt16"},
    {VTK_INT, "Int32"},
    {VTK_UNSIGNED_INT, "UInt32"},
    {VTK_LONG_LONG, "Int64"},
    {VTK_UNSIGNED_LONG_LONG, "UInt64"},
    {VTK_ID_TYPE, "Int64"},
    {VTK_LONG, "Int64"},
    {VTK_UNSIGNED_LONG, "UInt64"},
};

std::string type_name(int vtk_type) {
  for (const auto& t : kTypes)
    if (t.vtk == vtk_type) return t.name;
  return "Float64";
}

int type_id(const std::string& name) {
  for (const auto& t : kTypes)
    if (name == t.name) return t.vtk;
  return VTK_DOUBLE;
}

std::string lower_ext(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

std::string detect_space(const std::string& text) {
  if (text.find("SPACE=LPS") != std::string::npos) return "LPS";
  if (text.find("SPACE=RAS") != std::string::npos) return "RAS";
  return {};
}

Eigen::MatrixXd array_values(vtkDataArray* a, const std::vector<vtkIdType>& rows) {
  const int nc = a->GetNumberOfComponents();
  Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), nc);
  for (std::size_t r = 0; r < rows.size(); ++r)
    for (int c = 0; c < nc; ++c) m(static_cast<Eigen::Index>(r), c) = a->GetComponent(rows[r], c);
  return m;
}

MeshData convert(vtkPolyData* pd, const std::string& name, const std::string& space) {
  MeshData d;
  d.space = space;
  const vtkIdType np = pd->GetNumberOfPoints();
  if (np == 0 || !pd->GetPoints()) throw InputError(fmt::format("{}: contains no points", name));
  d.V.resize(np, 3);
  for (vtkIdType i = 0; i < np; ++i) {
    double p[3];
    pd->GetPoint(i, p);
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw InputError(fmt::format("{}: point {} has a non-finite coordinate", name, i));
    d.V.row(i) << p[0], p[1], p[2];
  }

  // Cell data are numbered verts, lines, polys, strips (VTK's PolyData order).
  const vtkIdType first_poly = pd->GetNumberOfVerts() + pd->GetNumberOfLines();
  const vtkIdType first_strip = first_poly + pd->GetNumberOfPolys();
  std::vector<std::array<int, 3>> tris;
  std::vector<vtkIdType> source_cell;
  long long polygons = 0, strips = 0;
  auto check = [&](vtkIdType cell, vtkIdType v) {
    if (v < 0 || v >= np)
      throw InputError(fmt::format("{}: cell {} refers to point {} (the file has {} points)", name, cell, v, np));
    return static_cast<int>(v);
  };
  {
    auto it = vtkSmartPointer<vtkCellArrayIterator>::Take(pd->GetPolys()->NewIterator());
    vtkIdType c = 0;
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++c) {
      vtkIdType n;
      const vtkIdType* p;
      it->GetCurrentCell(n, p);
      if (n < 3) throw InputError(fmt::format("{}: polygon {} has {} corners", name, first_poly + c, n));
      if (n > 3) ++polygons;
      for (vtkIdType k = 1; k + 1 < n; ++k) {
        tris.push_back({check(first_poly + c, p[0]), check(first_poly + c, p[k]), check(first_poly + c, p[k + 1])});
        source_cell.push_back(first_poly + c);
      }
    }
  }
  {
    auto it = vtkSmartPointer<vtkCellArrayIterator>::Take(pd->GetStrips()->NewIterator());
    vtkIdType c = 0;
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++c) {
      vtkIdType n;
      const vtkIdType* p;
      it->GetCurrentCell(n, p);
      ++strips;
      for (vtkIdType k = 0; k + 2 < n; ++k) {
        const vtkIdType cell = first_strip + c;
        // Every other triangle of a strip is reversed to keep one orientation.
        if (k % 2 == 0)
          tris.push_back({check(cell, p[k]), check(cell, p[k + 1]), check(cell, p[k + 2])});
        else
          tris.push_back({check(cell, p[k + 1]), check(cell, p[k]), check(cell, p[k + 2])});
        source_cell.push_back(cell);
      }
    }
  }
  if (tris.empty())
    throw InputError(fmt::format("{}: contains no polygons ({} vertex and {} line cells; a surface is needed)", name,
                                 pd->GetNumberOfVerts(), pd->GetNumberOfLines()));
  d.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    d.F.row(static_cast<Eigen::Index>(t)) << tris[t][0], tris[t][1], tris[t][2];
  if (polygons)
    d.warnings.push_back(
        fmt::format("{}: triangulated {} polygons with more than three corners{}", name, polygons,
                    pd->GetCellData()->GetNumberOfArrays() ? " (their cell data repeated per triangle)" : ""));
  if (strips) d.warnings.push_back(fmt::format("{}: unrolled {} triangle strips", name, strips));
  if (pd->GetNumberOfVerts() + pd->GetNumberOfLines() > 0)
    d.warnings.push_back(
        fmt::format("{}: ignored {} vertex and {} line cells", name, pd->GetNumberOfVerts(), pd->GetNumberOfLines()));

  std::vector<vtkIdType> all_points(static_cast<std::size_t>(np));
  for (vtkIdType i = 0; i < np; ++i) all_points[static_cast<std::size_t>(i)] = i;
  vtkPointData* point_data = pd->GetPointData();
  for (int a = 0; a < point_data->GetNumberOfArrays(); ++a) {
    vtkDataArray* arr = point_data->GetArray(a);
    if (!arr) {
      d.warnings.push_back(fmt::format("{}: ignored non-numeric point array {}", name, a));
      continue;
    }
    const std::string key = arr->GetName() ? arr->GetName() : fmt::format("point_array_{}", a);
    if (arr->GetNumberOfTuples() != np)
      throw InputError(
          fmt::format("{}: point array '{}' has {} tuples for {} points", name, key, arr->GetNumberOfTuples(), np));
    const Eigen::MatrixXd values = array_values(arr, all_points);
    const std::string type = type_name(arr->GetDataType());
    if (values.cols() == 1) {
      d.vertex_scalars[key] = values.col(0);
      d.scalar_types[key] = type;
    } else if (values.cols() == 3) {
      const char* suffix[3] = {"_x", "_y", "_z"};
      for (int c = 0; c < 3; ++c) {
        d.vertex_scalars[key + suffix[c]] = values.col(c);
        d.scalar_types[key + suffix[c]] = type;
      }
    } else {
      d.point_arrays[key] = DataArray{values, type};
    }
  }
  vtkCellData* cell_data = pd->GetCellData();
  for (int a = 0; a < cell_data->GetNumberOfArrays(); ++a) {
    vtkDataArray* arr = cell_data->GetArray(a);
    if (!arr) {
      d.warnings.push_back(fmt::format("{}: ignored non-numeric cell array {}", name, a));
      continue;
    }
    const std::string key = arr->GetName() ? arr->GetName() : fmt::format("cell_array_{}", a);
    if (arr->GetNumberOfTuples() != pd->GetNumberOfCells())
      throw InputError(fmt::format("{}: cell array '{}' has {} tuples for {} cells", name, key,
                                   arr->GetNumberOfTuples(), pd->GetNumberOfCells()));
    d.cell_arrays[key] = DataArray{array_values(arr, source_cell), type_name(arr->GetDataType())};
  }
  return d;
}

vtkSmartPointer<vtkDataArray> make_array(const std::string& name, const Eigen::MatrixXd& values,
                                         const std::string& type) {
  auto a = vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(type_id(type)));
  a->SetName(name.c_str());
  a->SetNumberOfComponents(static_cast<int>(values.cols()));
  a->SetNumberOfTuples(values.rows());
  for (Eigen::Index r = 0; r < values.rows(); ++r)
    for (Eigen::Index c = 0; c < values.cols(); ++c) a->SetComponent(r, static_cast<int>(c), values(r, c));
  return a;
}

vtkSmartPointer<vtkPolyData> to_polydata(const MeshData& d) {
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  auto pts = vtkSmartPointer<vtkPoints>::New();
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(d.V.rows());
  for (Eigen::Index i = 0; i < d.V.rows(); ++i) pts->SetPoint(i, d.V(i, 0), d.V(i, 1), d.V(i, 2));
  pd->SetPoints(pts);
  auto polys = vtkSmartPointer<vtkCellArray>::New();
  polys->AllocateExact(d.F.rows(), 3 * d.F.rows());
  for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
    const vtkIdType ids[3] = {d.F(f, 0), d.F(f, 1), d.F(f, 2)};
    polys->InsertNextCell(3, ids);
  }
  pd->SetPolys(polys);

  auto type_of = [&](const std::string& key) {
    const auto it = d.scalar_types.find(key);
    return it == d.scalar_types.end() ? std::string("Float64") : it->second;
  };
  // Join NAME_x/_y/_z back into one 3-component array.
  std::map<std::string, bool> used;
  for (const auto& [key, values] : d.vertex_scalars) {
    if (values.size() != d.V.rows())
      throw InputError(fmt::format("field '{}' has {} values for {} vertices", key, values.size(), d.V.rows()));
    if (key.size() > 2 && key.compare(key.size() - 2, 2, "_x") == 0) {
      const std::string base = key.substr(0, key.size() - 2);
      const auto y = d.vertex_scalars.find(base + "_y"), z = d.vertex_scalars.find(base + "_z");
      if (y != d.vertex_scalars.end() && z != d.vertex_scalars.end()) {
        Eigen::MatrixXd m(d.V.rows(), 3);
        m << values, y->second, z->second;
        pd->GetPointData()->AddArray(make_array(base, m, type_of(key)));
        used[key] = used[base + "_y"] = used[base + "_z"] = true;
      }
    }
  }
  for (const auto& [key, values] : d.vertex_scalars)
    if (!used.count(key)) pd->GetPointData()->AddArray(make_array(key, values, type_of(key)));
  for (const auto& [key, arr] : d.point_arrays) {
    if (arr.values.rows() != d.V.rows())
      throw InputError(fmt::format("point array '{}' has {} rows for {} vertices", key, arr.values.rows(), d.V.rows()));
    pd->GetPointData()->AddArray(make_array(key, arr.values, arr.type));
  }
  for (const auto& [key, arr] : d.cell_arrays) {
    if (arr.values.rows() != d.F.rows())
      throw InputError(fmt::format("cell array '{}' has {} rows for {} triangles", key, arr.values.rows(), d.F.rows()));
    pd->GetCellData()->AddArray(make_array(key, arr.values, arr.type));
  }
  return pd;
}

std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", path.string()));
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

bool is_vtk_mesh_path(const std::filesystem::path& path) {
  const std::string ext = lower_ext(path);
  return ext == ".vtp" || ext == ".vtk";
}

MeshData read_vtk_mesh_from_memory(const std::string& bytes, const std::string& kind, const std::string& name) {
  detail::VtkErrorCapture capture;
  vtkSmartPointer<vtkPolyData> pd;
  std::string space;
  if (kind == "vtp") {
    if (bytes.find("<VTKFile") == std::string::npos)
      throw InputError(fmt::format("{}: not a VTK XML file (no <VTKFile> element)", name));
    if (bytes.find("type=\"PolyData\"") == std::string::npos)
      throw InputError(fmt::format("{}: the VTK XML file does not hold PolyData", name));
    auto reader = vtkSmartPointer<vtkXMLPolyDataReader>::New();
    capture.watch(reader);
    reader->ReadFromInputStringOn();
    reader->SetInputString(bytes);
    reader->Update();
    if (const auto e = capture.error(); !e.empty()) throw InputError(fmt::format("{}: {}", name, e));
    pd = reader->GetOutput();
    space = detect_space(bytes.substr(0, std::min<std::size_t>(bytes.size(), 4096)));
  } else if (kind == "vtk") {
    if (bytes.rfind("# vtk DataFile", 0) != 0)
      throw InputError(fmt::format("{}:1: not a legacy VTK file (expected '# vtk DataFile Version')", name));
    auto reader = vtkSmartPointer<vtkPolyDataReader>::New();
    capture.watch(reader);
    reader->ReadFromInputStringOn();
    reader->SetInputString(bytes);
    reader->ReadAllScalarsOn();
    reader->ReadAllVectorsOn();
    reader->ReadAllNormalsOn();
    reader->ReadAllFieldsOn();
    reader->ReadAllTensorsOn();
    reader->ReadAllTCoordsOn();
    reader->ReadAllColorScalarsOn();
    reader->Update();
    if (const auto e = capture.error(); !e.empty()) throw InputError(fmt::format("{}: {}", name, e));
    pd = reader->GetOutput();
    if (reader->GetHeader()) space = detect_space(reader->GetHeader());
  } else {
    throw InputError(fmt::format("{}: unknown VTK kind '{}' (vtp or vtk)", name, kind));
  }
  if (!pd) throw InputError(fmt::format("{}: the reader produced no PolyData", name));
  return convert(pd, name, space);
}

MeshData read_vtk_mesh(const std::filesystem::path& path) {
  const std::string ext = lower_ext(path);
  if (!is_vtk_mesh_path(path))
    throw InputError(fmt::format("{}: not a VTK mesh file (expected .vtp or .vtk)", path.string()));
  return read_vtk_mesh_from_memory(slurp(path), ext.substr(1), path.string());
}

std::string write_vtk_mesh_to_memory(const MeshData& data, const std::string& kind) {
  detail::VtkErrorCapture capture;
  auto pd = to_polydata(data);
  if (kind == "vtp") {
    auto w = vtkSmartPointer<vtkXMLPolyDataWriter>::New();
    capture.watch(w);
    w->SetInputData(pd);
    w->SetDataModeToAppended();
    w->EncodeAppendedDataOff();
    w->SetCompressorTypeToZLib();
    w->SetHeaderTypeToUInt64();
    w->WriteToOutputStringOn();
    if (!w->Write() || !capture.error().empty()) throw Error(fmt::format("VTK XML writer failed: {}", capture.error()));
    return w->GetOutputString();
  }
  if (kind == "vtk") {
    auto w = vtkSmartPointer<vtkPolyDataWriter>::New();
    capture.watch(w);
    w->SetInputData(pd);
    w->SetFileTypeToBinary();
    const std::string header = data.space.empty() ? "meshpde output" : "meshpde output. SPACE=" + data.space;
    w->SetHeader(header.c_str());
    w->WriteToOutputStringOn();
    if (!w->Write() || !capture.error().empty())
      throw Error(fmt::format("VTK legacy writer failed: {}", capture.error()));
    return w->GetOutputStdString();
  }
  throw InputError(fmt::format("unknown VTK kind '{}' (vtp or vtk)", kind));
}

void write_vtk_mesh(const std::filesystem::path& path, const MeshData& data) {
  if (!is_vtk_mesh_path(path))
    throw InputError(fmt::format("{}: not a VTK mesh file name (expected .vtp or .vtk)", path.string()));
  write_file_atomically(path, write_vtk_mesh_to_memory(data, lower_ext(path).substr(1)));
}

namespace {

// The core readers know only their own formats; name every format this build reads.
void require_mesh_extension(const std::filesystem::path& path) {
  if (is_vtk_mesh_path(path)) return;
  const std::string ext = lower_ext(path);
  if (ext == ".obj" || ext == ".off" || ext == ".ply" || ext == ".stl") return;
  if (is_volume_path(path))
    throw InputError(
        fmt::format("{}: a volume, not a mesh (volumes go to --image; `meshpde info` describes them)", path.string()));
  throw InputError(
      fmt::format("{}: unknown mesh format '{}' (supported: .obj .off .ply .stl .vtp .vtk)", path.string(), ext));
}

}  // namespace

MeshData read_any_mesh(const std::filesystem::path& path) {
  require_mesh_extension(path);
  return is_vtk_mesh_path(path) ? read_vtk_mesh(path) : read_mesh(path);
}

std::vector<std::string> write_any_mesh(const std::filesystem::path& path, const MeshData& data,
                                        const WriteOptions& options) {
  require_mesh_extension(path);
  if (!is_vtk_mesh_path(path)) return write_mesh(path, data, options);
  write_vtk_mesh(path, data);
  return {};
}

}  // namespace meshpde
