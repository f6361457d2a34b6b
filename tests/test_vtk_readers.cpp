// meshpde's own .vtp and legacy .vtk readers against VTK's, the independent oracle: every
// encoding VTK 9 writes (ascii, inline base64, appended raw and base64, zlib in one or
// many blocks, UInt32 and UInt64 headers, both byte orders; legacy ASCII and BINARY in
// file versions 4.2 and 5.1) and every real .vtp in ../shared/data read by both give
// the same points, cells (verts, lines, polys, strips) and arrays, bit for bit.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkCellData.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkFloatArray.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataReader.h>
#include <vtkPolyDataWriter.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkUnsignedCharArray.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <fstream>
#include <sstream>

#include "../src/medical/polydata.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "test_data.h"

namespace meshpde {
namespace {

using detail::CellList;
using detail::NamedArray;
using detail::PolyData;

template <class T>
using Ptr = vtkSmartPointer<T>;

// A PolyData with every kind of cell and arrays of several types and widths.
Ptr<vtkPolyData> sample_polydata() {
  auto pd = Ptr<vtkPolyData>::New();
  auto pts = Ptr<vtkPoints>::New();
  pts->SetDataTypeToDouble();
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 6; ++i) pts->InsertNextPoint(i + 0.1 / (1 + j), j + 1.0 / 3.0, 0.01 * i * j);
  pd->SetPoints(pts);
  auto cells = [](std::initializer_list<std::initializer_list<vtkIdType>> list) {
    auto a = Ptr<vtkCellArray>::New();
    for (const auto& c : list) a->InsertNextCell(static_cast<vtkIdType>(c.size()), c.begin());
    return a;
  };
  pd->SetVerts(cells({{0}, {29}}));
  pd->SetLines(cells({{0, 1}, {6, 7, 8, 9}}));
  pd->SetPolys(cells({{0, 1, 7}, {0, 7, 6}, {1, 2, 8, 7}, {2, 3, 4, 10, 9}, {12, 13, 19}}));
  pd->SetStrips(cells({{18, 24, 19, 25, 20, 26}}));
  const vtkIdType np = pd->GetNumberOfPoints(), nc = pd->GetNumberOfCells();

  auto temperature = Ptr<vtkFloatArray>::New();
  temperature->SetName("temperature");
  auto flow = Ptr<vtkDoubleArray>::New();
  flow->SetName("flow");
  flow->SetNumberOfComponents(3);
  auto uv = Ptr<vtkFloatArray>::New();
  uv->SetName("uv");
  uv->SetNumberOfComponents(2);
  auto mask = Ptr<vtkUnsignedCharArray>::New();
  mask->SetName("mask");
  auto wide = Ptr<vtkDoubleArray>::New();
  wide->SetName("wide");
  wide->SetNumberOfComponents(5);
  for (vtkIdType i = 0; i < np; ++i) {
    temperature->InsertNextValue(static_cast<float>(0.5 * i - 3));
    flow->InsertNextTuple3(i / 7.0, -i / 3.0, 1e-300 * i);
    uv->InsertNextTuple2(i * 0.25, 1 - i * 0.25);
    mask->InsertNextValue(static_cast<unsigned char>(i * 9));
    for (int c = 0; c < 5; ++c) wide->InsertNextValue(i * 10 + c + 0.125);
  }
  pd->GetPointData()->SetScalars(temperature);
  pd->GetPointData()->SetNormals(flow);
  pd->GetPointData()->SetTCoords(uv);
  pd->GetPointData()->AddArray(mask);
  pd->GetPointData()->AddArray(wide);
  auto region = Ptr<vtkIntArray>::New();
  region->SetName("region");
  auto area = Ptr<vtkDoubleArray>::New();
  area->SetName("area");
  for (vtkIdType c = 0; c < nc; ++c) {
    region->InsertNextValue(static_cast<int>(100 + c));
    area->InsertNextValue(1.0 / (c + 1));
  }
  pd->GetCellData()->SetScalars(region);
  pd->GetCellData()->AddArray(area);
  return pd;
}

CellList cell_list_of(vtkCellArray* a) {
  CellList out;
  auto it = Ptr<vtkCellArrayIterator>::Take(a->NewIterator());
  for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell()) {
    vtkIdType n;
    const vtkIdType* p;
    it->GetCurrentCell(n, p);
    out.connectivity.insert(out.connectivity.end(), p, p + n);
    out.offsets.push_back(static_cast<std::int64_t>(out.connectivity.size()));
  }
  return out;
}

std::vector<NamedArray> arrays_of(vtkDataSetAttributes* data) {
  std::vector<NamedArray> out;
  for (int a = 0; a < data->GetNumberOfArrays(); ++a) {
    vtkDataArray* arr = data->GetArray(a);
    if (!arr) continue;
    NamedArray n;
    n.name = arr->GetName() ? arr->GetName() : "";
    n.components = arr->GetNumberOfComponents();
    for (vtkIdType t = 0; t < arr->GetNumberOfTuples(); ++t)
      for (int c = 0; c < n.components; ++c) n.values.push_back(arr->GetComponent(t, c));
    out.push_back(std::move(n));
  }
  return out;
}

void expect_same_cells(const CellList& ours, const CellList& vtk, const char* kind) {
  EXPECT_EQ(ours.offsets, vtk.offsets) << kind;
  EXPECT_EQ(ours.connectivity, vtk.connectivity) << kind;
}

void expect_same_arrays(const std::vector<NamedArray>& ours, const std::vector<NamedArray>& vtk, const char* kind) {
  ASSERT_EQ(ours.size(), vtk.size()) << kind;
  for (const NamedArray& v : vtk) {
    const auto o = std::find_if(ours.begin(), ours.end(), [&](const NamedArray& a) { return a.name == v.name; });
    ASSERT_NE(o, ours.end()) << kind << " array " << v.name;
    EXPECT_EQ(o->components, v.components) << v.name;
    EXPECT_EQ(o->values, v.values) << v.name;  // bit for bit
  }
}

// Our reader's PolyData equals what VTK's reader makes of the same bytes.
void expect_same(const PolyData& ours, vtkPolyData* vtk) {
  ASSERT_EQ(static_cast<vtkIdType>(ours.point_count()), vtk->GetNumberOfPoints());
  for (vtkIdType i = 0; i < vtk->GetNumberOfPoints(); ++i) {
    double p[3];
    vtk->GetPoint(i, p);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(ours.points[3 * static_cast<std::size_t>(i) + c], p[c]) << "point " << i;
  }
  expect_same_cells(ours.verts, cell_list_of(vtk->GetVerts()), "verts");
  expect_same_cells(ours.lines, cell_list_of(vtk->GetLines()), "lines");
  expect_same_cells(ours.polys, cell_list_of(vtk->GetPolys()), "polys");
  expect_same_cells(ours.strips, cell_list_of(vtk->GetStrips()), "strips");
  expect_same_arrays(ours.point_arrays, arrays_of(vtk->GetPointData()), "point");
  expect_same_arrays(ours.cell_arrays, arrays_of(vtk->GetCellData()), "cell");
}

vtkSmartPointer<vtkPolyData> vtk_read_xml(const std::string& bytes) {
  auto r = Ptr<vtkXMLPolyDataReader>::New();
  r->ReadFromInputStringOn();
  r->SetInputString(bytes);
  r->Update();
  return r->GetOutput();
}

vtkSmartPointer<vtkPolyData> vtk_read_legacy(const std::string& bytes) {
  auto r = Ptr<vtkPolyDataReader>::New();
  r->ReadFromInputStringOn();
  r->SetInputString(bytes);
  r->ReadAllScalarsOn();
  r->ReadAllVectorsOn();
  r->ReadAllNormalsOn();
  r->ReadAllFieldsOn();
  r->ReadAllTensorsOn();
  r->ReadAllTCoordsOn();
  r->ReadAllColorScalarsOn();
  r->Update();
  return r->GetOutput();
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(VtkReaders, EveryXmlEncodingVtkWritesReadsAsVtkReadsIt) {
  const auto pd = sample_polydata();
  int cases = 0;
  for (const int mode : {vtkXMLWriterBase::Ascii, vtkXMLWriterBase::Binary, vtkXMLWriterBase::Appended})
    for (const bool base64 : {false, true})
      for (const bool zlib : {false, true})
        for (const bool u64 : {false, true})
          for (const bool big : {false, true})
            for (const int block : {32768, 40}) {
              if (mode != vtkXMLWriterBase::Appended && !base64) continue;  // only appended data can be raw
              if (mode == vtkXMLWriterBase::Ascii && (zlib || u64 || big || block != 32768)) continue;
              if (!zlib && block != 32768) continue;
              auto w = Ptr<vtkXMLPolyDataWriter>::New();
              w->SetInputData(pd);
              w->SetDataMode(mode);
              w->SetEncodeAppendedData(base64);
              if (zlib)
                w->SetCompressorTypeToZLib();
              else
                w->SetCompressorTypeToNone();
              w->SetBlockSize(block);
              w->SetHeaderType(u64 ? vtkXMLWriterBase::UInt64 : vtkXMLWriterBase::UInt32);
              w->SetByteOrder(big ? vtkXMLWriterBase::BigEndian : vtkXMLWriterBase::LittleEndian);
              w->WriteToOutputStringOn();
              ASSERT_TRUE(w->Write());
              const std::string bytes = w->GetOutputString();
              SCOPED_TRACE(fmt::format("mode {} base64 {} zlib {} UInt64 {} big-endian {} block {}", mode, base64, zlib,
                                       u64, big, block));
              expect_same(detail::read_vtp_polydata(bytes, "sample.vtp"), vtk_read_xml(bytes));
              ++cases;
            }
  EXPECT_EQ(cases, 37);  // ascii 1, inline binary 12, appended raw and base64 24
}

TEST(VtkReaders, SlicersSpaceFieldDataIsReadInEveryXmlEncoding) {
  // 3D Slicer writes the frame of a .vtp as a field-data string array SPACE ("LPS" or
  // "RAS"), which VTK stores as NUL-terminated bytes in whatever encoding it writes.
  for (const std::string frame : {"LPS", "RAS"})
    for (const int mode : {vtkXMLWriterBase::Ascii, vtkXMLWriterBase::Binary, vtkXMLWriterBase::Appended})
      for (const bool zlib : {false, true}) {
        if (mode == vtkXMLWriterBase::Ascii && zlib) continue;
        const auto pd = sample_polydata();
        auto tag = Ptr<vtkStringArray>::New();
        tag->SetName("SPACE");
        tag->InsertNextValue(frame);
        pd->GetFieldData()->AddArray(tag);
        auto w = Ptr<vtkXMLPolyDataWriter>::New();
        w->SetInputData(pd);
        w->SetDataMode(mode);
        if (zlib)
          w->SetCompressorTypeToZLib();
        else
          w->SetCompressorTypeToNone();
        w->WriteToOutputStringOn();
        ASSERT_TRUE(w->Write());
        const std::string bytes = w->GetOutputString();
        SCOPED_TRACE(fmt::format("{} mode {} zlib {}", frame, mode, zlib));
        ASSERT_EQ(bytes.find("SPACE=" + frame), std::string::npos);  // only the field data says it
        const PolyData ours = detail::read_vtp_polydata(bytes, "slicer.vtp");
        EXPECT_EQ(ours.space, frame);
        expect_same(ours, vtk_read_xml(bytes));
      }
}

TEST(VtkReaders, OurVtpFrameIsTheFieldDataSlicerReads) {
  MeshData d;
  d.V = Positions{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  d.F = Triangles{{0, 1, 2}};
  d.space = "RAS";
  auto reader = Ptr<vtkXMLPolyDataReader>::New();
  reader->ReadFromInputStringOn();
  reader->SetInputString(write_vtk_mesh_to_memory(d, "vtp"));
  reader->Update();
  auto* tag = vtkStringArray::SafeDownCast(reader->GetOutput()->GetFieldData()->GetAbstractArray("SPACE"));
  ASSERT_NE(tag, nullptr);
  ASSERT_EQ(tag->GetNumberOfValues(), 1);
  EXPECT_EQ(tag->GetValue(0), "RAS");
}

TEST(VtkReaders, LegacyAsciiAndBinaryInBothFileVersionsReadAsVtkReadsThem) {
  const auto pd = sample_polydata();
  for (const int version : {vtkDataWriter::VTK_LEGACY_READER_VERSION_4_2, vtkDataWriter::VTK_LEGACY_READER_VERSION_5_1})
    for (const bool binary : {false, true}) {
      auto w = Ptr<vtkPolyDataWriter>::New();
      w->SetInputData(pd);
      w->SetFileVersion(version);
      if (binary)
        w->SetFileTypeToBinary();
      else
        w->SetFileTypeToASCII();
      w->SetHeader("written by the test. SPACE=LPS");
      w->WriteToOutputStringOn();
      ASSERT_TRUE(w->Write());
      const std::string bytes = w->GetOutputStdString();
      SCOPED_TRACE(fmt::format("version {} binary {}", version, binary));
      const PolyData ours = detail::read_legacy_vtk_polydata(bytes, "sample.vtk");
      EXPECT_EQ(ours.space, "LPS");
      if (binary) {
        expect_same(ours, vtk_read_legacy(bytes));
      } else {
        // ASCII rounds to VTK's printed precision; both readers parse the same digits.
        const auto vtk = vtk_read_legacy(bytes);
        ASSERT_EQ(static_cast<vtkIdType>(ours.point_count()), vtk->GetNumberOfPoints());
        expect_same_cells(ours.polys, cell_list_of(vtk->GetPolys()), "polys");
        expect_same_cells(ours.strips, cell_list_of(vtk->GetStrips()), "strips");
        expect_same_cells(ours.lines, cell_list_of(vtk->GetLines()), "lines");
        const auto theirs = arrays_of(vtk->GetPointData());
        ASSERT_EQ(ours.point_arrays.size(), theirs.size());
        for (const NamedArray& t : theirs) {
          const auto o = std::find_if(ours.point_arrays.begin(), ours.point_arrays.end(),
                                      [&](const NamedArray& a) { return a.name == t.name; });
          ASSERT_NE(o, ours.point_arrays.end()) << t.name;
          ASSERT_EQ(o->values.size(), t.values.size()) << t.name;
          for (std::size_t i = 0; i < t.values.size(); ++i)
            EXPECT_NEAR(o->values[i], t.values[i], 1e-6 * (1 + std::abs(t.values[i]))) << t.name << " " << i;
        }
      }
    }
}

TEST(VtkReaders, EveryRealVtpFileReadsAsVtkReadsIt) {
  int files = 0;
  for (const char* name : {"aorta-closed-6k.vtp", "aorta-103k.vtp", "carotid-ica-4k.vtp",
                           "vessel-boolean-nonmanifold.vtp", "aorta-centerlines.vtp"}) {
    if (!test::have_data(name)) continue;
    SCOPED_TRACE(name);
    const std::string bytes = slurp(test::data_dir() / name);
    const PolyData ours = detail::read_vtp_polydata(bytes, name);
    expect_same(ours, vtk_read_xml(bytes));
    // And written by VTK as legacy binary, version 5.1, read back the same way.
    auto w = Ptr<vtkPolyDataWriter>::New();
    w->SetInputData(vtk_read_xml(bytes));
    w->SetFileTypeToBinary();
    w->WriteToOutputStringOn();
    ASSERT_TRUE(w->Write());
    expect_same(detail::read_legacy_vtk_polydata(w->GetOutputStdString(), name),
                vtk_read_legacy(w->GetOutputStdString()));
    ++files;
  }
  if (test::under_ci()) {
    EXPECT_EQ(files, 5);
  }
}

TEST(VtkReaders, DamagedHeadersAreErrorsNotAllocations) {
  // A block header claiming 2^64 - 1 bytes made VTK 9.1's reader try to allocate them.
  const std::string appended =
      "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
      "<PolyData><Piece NumberOfPoints=\"3\" NumberOfPolys=\"1\"><Points>"
      "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/></Points>"
      "</Piece></PolyData>\n<AppendedData encoding=\"raw\">\n_" +
      std::string(8, '\xff') + std::string(36, '\0') + "\n</AppendedData></VTKFile>\n";
  try {
    detail::read_vtp_polydata(appended, "huge.vtp");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.vtp"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("claims"), std::string::npos) << e.what();
  }
  // A legacy count larger than the file.
  try {
    detail::read_legacy_vtk_polydata(
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\nPOINTS 99999999999 float\n\x01\x02", "huge.vtk");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.vtk"), std::string::npos) << e.what();
  }
}

}  // namespace meshpde
