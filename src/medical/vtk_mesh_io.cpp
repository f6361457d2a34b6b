// VTK PolyData files (.vtp XML, .vtk legacy): read by our own readers (polydata.h),
// written through VTK 9.
#include <fmt/format.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataWriter.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkXMLPolyDataWriter.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "polydata.h"
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
  // The points' type as read (Float32 stays Float32); any other type is written as Float64.
  if (d.points_type == "Float32")
    pts->SetDataTypeToFloat();
  else
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
  for (const auto& [key, value] : d.field_strings) {
    auto s = vtkSmartPointer<vtkStringArray>::New();
    s->SetName(key.c_str());
    s->InsertNextValue(value);
    pd->GetFieldData()->AddArray(s);
  }
  for (const auto& [key, arr] : d.field_arrays) pd->GetFieldData()->AddArray(make_array(key, arr.values, arr.type));
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
  if (kind == "vtp") return detail::mesh_from_polydata(detail::read_vtp_polydata(bytes, name), name);
  if (kind == "vtk") return detail::mesh_from_polydata(detail::read_legacy_vtk_polydata(bytes, name), name);
  throw InputError(fmt::format("{}: unknown VTK kind '{}' (vtp or vtk)", name, kind));
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
    // 3D Slicer's convention for XML files: a one-string field-data array named SPACE.
    if (!data.space.empty()) {
      auto tag = vtkSmartPointer<vtkStringArray>::New();
      tag->SetName("SPACE");
      tag->InsertNextValue(data.space);
      pd->GetFieldData()->AddArray(tag);
    }
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

}  // namespace meshpde
