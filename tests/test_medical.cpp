// meshpde::medical: VTK PolyData and volume readers. The encodings the real data
// lack are written here by hand (base64, zlib, NIfTI header bytes), independently
// of VTK's writers, so the readers are checked against the file formats themselves.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

#include "meshpde/core/errors.h"
#include "meshpde/image/volume_slice.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/zip_archive.h"
#include "meshpde/mesh/mesh.h"
#include "solver_problems.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) {
  return test::scratch_path(name);
}

void write_bytes(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary);
  out.write(s.data(), static_cast<std::streamsize>(s.size()));
}

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8 | (unsigned char)in[i + 2];
    out += {t[v >> 18], t[(v >> 12) & 63], t[(v >> 6) & 63], t[v & 63]};
  }
  if (i + 1 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16;
    out += {t[v >> 18], t[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8;
    out += {t[v >> 18], t[(v >> 12) & 63], t[(v >> 6) & 63], '='};
  }
  return out;
}

template <class T>
std::string bytes_of(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

template <class H>
std::string header_bytes(std::initializer_list<std::size_t> values) {
  std::string s;
  for (auto v : values) {
    const H h = static_cast<H>(v);
    s.append(reinterpret_cast<const char*>(&h), sizeof(H));
  }
  return s;
}

// One VTK XML data block: [header][data], the header as the format defines it for
// uncompressed (byte count) or zlib (one block: 1, size, size, compressed size) data.
template <class H>
std::pair<std::string, std::string> block(const std::string& data, bool compress) {
  if (!compress) return {header_bytes<H>({data.size()}), data};
  uLongf n = compressBound(data.size());
  std::string z(n, '\0');
  EXPECT_EQ(
      compress2(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(data.data()), data.size(), 6),
      Z_OK);
  z.resize(n);
  return {header_bytes<H>({1, data.size(), data.size(), z.size()}), z};
}

// A unit tetrahedron as .vtp text in the requested encoding.
struct VtpOptions {
  bool appended = false;
  bool base64 = true;  // appended: base64 or raw; inline binary is always base64
  bool compress = false;
  bool uint64_header = false;
  bool float64_points = false;
  bool int64_ids = false;
};

template <class H>
std::string make_vtp(const VtpOptions& o) {
  std::vector<double> p64 = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<float> p32(p64.begin(), p64.end());
  std::vector<long long> c64 = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}, o64 = {3, 6, 9, 12};
  std::vector<int> c32(c64.begin(), c64.end()), o32(o64.begin(), o64.end());
  std::vector<float> temperature = {1.5f, 2.5f, 3.5f, 4.5f};
  std::vector<int> label = {7, 8, 9, 10};
  struct Arr {
    std::string name, type, data;
    int comps;
  };
  std::vector<std::vector<Arr>> sections = {
      {{"temperature", "Float32", bytes_of(temperature), 1}},
      {{"label", "Int32", bytes_of(label), 1}},
      {{"Points", o.float64_points ? "Float64" : "Float32", o.float64_points ? bytes_of(p64) : bytes_of(p32), 3}},
      {{"connectivity", o.int64_ids ? "Int64" : "Int32", o.int64_ids ? bytes_of(c64) : bytes_of(c32), 1},
       {"offsets", o.int64_ids ? "Int64" : "Int32", o.int64_ids ? bytes_of(o64) : bytes_of(o32), 1}}};
  std::string appended;
  auto element = [&](const Arr& a) {
    auto [h, d] = block<H>(a.data, o.compress);
    std::string head = "<DataArray type=\"" + a.type + "\" Name=\"" + a.name + "\" NumberOfComponents=\"" +
                       std::to_string(a.comps) + "\" format=\"";
    if (o.appended) {
      const std::string offset = std::to_string(appended.size());
      appended += o.base64 ? base64(h) + base64(d) : h + d;
      return head + "appended\" offset=\"" + offset + "\"/>\n";
    }
    return head + "binary\">" + base64(h) + base64(d) + "</DataArray>\n";
  };
  std::string x = "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\"";
  x += std::string(" header_type=\"") + (o.uint64_header ? "UInt64" : "UInt32") + "\"";
  if (o.compress) x += " compressor=\"vtkZLibDataCompressor\"";
  x += ">\n<PolyData>\n<Piece NumberOfPoints=\"4\" NumberOfPolys=\"4\">\n";
  x += "<PointData>\n" + element(sections[0][0]) + "</PointData>\n";
  x += "<CellData>\n" + element(sections[1][0]) + "</CellData>\n";
  x += "<Points>\n" + element(sections[2][0]) + "</Points>\n";
  x += "<Polys>\n" + element(sections[3][0]) + element(sections[3][1]) + "</Polys>\n";
  x += "</Piece>\n</PolyData>\n";
  if (o.appended)
    x += std::string("<AppendedData encoding=\"") + (o.base64 ? "base64" : "raw") + "\">\n_" + appended +
         "\n</AppendedData>\n";
  x += "</VTKFile>\n";
  return x;
}

void expect_tetrahedron(const MeshData& d, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(d.V.rows(), 4);
  ASSERT_EQ(d.F.rows(), 4);
  EXPECT_EQ(d.V(1, 0), 1.0);
  EXPECT_EQ(d.V(3, 2), 1.0);
  EXPECT_EQ(d.F(0, 1), 2);
  EXPECT_EQ(d.F(3, 2), 3);
  ASSERT_TRUE(d.vertex_scalars.count("temperature"));
  EXPECT_EQ(d.vertex_scalars.at("temperature")(2), 3.5);
  EXPECT_EQ(d.scalar_types.at("temperature"), "Float32");
  ASSERT_TRUE(d.cell_arrays.count("label"));
  EXPECT_EQ(d.cell_arrays.at("label").values(3, 0), 10.0);
  EXPECT_EQ(d.cell_arrays.at("label").type, "Int32");
}

}  // namespace

TEST(Vtp, EveryEncodingOfTheFormatReads) {
  for (int appended = 0; appended < 2; ++appended)
    for (int b64 = 0; b64 < 2; ++b64)
      for (int compress = 0; compress < 2; ++compress)
        for (int u64 = 0; u64 < 2; ++u64)
          for (int wide = 0; wide < 2; ++wide) {
            if (!appended && !b64) continue;  // inline binary data is always base64
            VtpOptions o{static_cast<bool>(appended), static_cast<bool>(b64),  static_cast<bool>(compress),
                         static_cast<bool>(u64),      static_cast<bool>(wide), static_cast<bool>(wide)};
            const std::string text = u64 ? make_vtp<std::uint64_t>(o) : make_vtp<std::uint32_t>(o);
            const std::string what =
                fmt::format("appended {} base64 {} zlib {} UInt64 {} 64-bit {}", appended, b64, compress, u64, wide);
            expect_tetrahedron(read_vtk_mesh_from_memory(text, "vtp", "tet.vtp"), what);
          }
}

TEST(Vtp, RealFilesReadWithTheirArraysAndQuadsTriangulated) {
  if (!test::have_data("aorta-closed-6k.vtp") || !test::have_data("carotid-ica-4k.vtp")) return;
  const MeshData aorta = read_mesh(test::data_dir() / "aorta-closed-6k.vtp");
  EXPECT_EQ(aorta.V.rows(), 6468);
  EXPECT_EQ(aorta.F.rows(), 12932);
  EXPECT_TRUE(aorta.vertex_scalars.count("Scalars_"));
  EXPECT_TRUE(aorta.vertex_scalars.count("Normals__x") && aorta.vertex_scalars.count("Normals__z"));
  const MeshData carotid = read_mesh(test::data_dir() / "carotid-ica-4k.vtp");
  EXPECT_EQ(carotid.V.rows(), 3862);
  EXPECT_EQ(carotid.F.rows(), 7329 + 2 * 78);
  ASSERT_FALSE(carotid.warnings.empty());
  EXPECT_NE(carotid.warnings[0].find("triangulated 78"), std::string::npos);
}

TEST(Vtp, RoundTripKeepsPointsTrianglesAndArraysWithTheirTypes) {
  VtpOptions o;
  MeshData d = read_vtk_mesh_from_memory(make_vtp<std::uint32_t>(o), "vtp", "tet.vtp");
  d.vertex_scalars["flow_x"] = Eigen::Vector4d(1, 2, 3, 4);
  d.vertex_scalars["flow_y"] = Eigen::Vector4d(5, 6, 7, 8);
  d.vertex_scalars["flow_z"] = Eigen::Vector4d(9, 10, 11, 12);
  d.point_arrays["tensor2"] = DataArray{Eigen::MatrixXd::Constant(4, 2, 0.25), "Float64"};
  // Not representable in float: points of type Float64 are written as doubles (Float32
  // points stay Float32: Vtp.PointsKeepTheirType).
  d.V(2, 1) = 1.0 / 3.0;
  d.points_type = "Float64";
  for (const char* ext : {".vtp", ".vtk"}) {
    SCOPED_TRACE(ext);
    const fs::path p = scratch(std::string("roundtrip") + ext);
    write_mesh(p, d);
    const MeshData r = read_mesh(p);
    EXPECT_EQ(r.V, d.V);
    EXPECT_EQ(r.F, d.F);
    EXPECT_EQ(r.vertex_scalars.at("temperature"), d.vertex_scalars.at("temperature"));
    EXPECT_EQ(r.scalar_types.at("temperature"), "Float32");
    EXPECT_EQ(r.vertex_scalars.at("flow_y"), d.vertex_scalars.at("flow_y"));
    EXPECT_EQ(r.point_arrays.at("tensor2").values, d.point_arrays.at("tensor2").values);
    EXPECT_EQ(r.cell_arrays.at("label").values, d.cell_arrays.at("label").values);
    EXPECT_EQ(r.cell_arrays.at("label").type, "Int32");
  }
}

TEST(Vtp, LegacyAsciiWithSlicerSpaceHeader) {
  const std::string text =
      "# vtk DataFile Version 4.2\n3D Slicer output. SPACE=RAS\nASCII\nDATASET POLYDATA\n"
      "POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nPOLYGONS 2 9\n3 0 1 2\n4 0 1 3 2\n"
      "POINT_DATA 4\nSCALARS thickness float 1\nLOOKUP_TABLE default\n0.5 1 1.5 2\n";
  const MeshData d = read_vtk_mesh_from_memory(text, "vtk", "slicer.vtk");
  EXPECT_EQ(d.space, "RAS");
  EXPECT_EQ(d.F.rows(), 3);  // the quad became two triangles
  EXPECT_EQ(d.vertex_scalars.at("thickness")(3), 2.0);
}

namespace {
// A mesh of one triangle with corners V (3 x 3).
MeshData one_triangle(Positions V) {
  MeshData d;
  d.V = std::move(V);
  d.F = Triangles{{0, 1, 2}};
  return d;
}
}  // namespace

TEST(Vtp, TheFrameIsWrittenAsSlicerWritesIt) {
  // A .vtp carries its frame as 3D Slicer's SPACE field data, as a legacy .vtk carries
  // it in its header; both read back (that VTK, so Slicer, finds the array:
  // VtkReaders.OurVtpFrameIsTheFieldDataSlicerReads).
  for (const std::string frame : {"RAS", "LPS"}) {
    MeshData d = one_triangle(Positions{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    d.space = frame;
    for (const std::string kind : {"vtp", "vtk"}) {
      const std::string bytes = write_vtk_mesh_to_memory(d, kind);
      EXPECT_EQ(read_vtk_mesh_from_memory(bytes, kind, "framed." + kind).space, frame) << kind;
    }
  }
  const MeshData plain = one_triangle(Positions{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  EXPECT_EQ(read_vtk_mesh_from_memory(write_vtk_mesh_to_memory(plain, "vtp"), "vtp", "plain.vtp").space, "");
}

TEST(Vtp, PointsKeepTheirType) {
  // Float32 points (vmtk's, Slicer's) are written back as Float32, Float64 as Float64,
  // in both VTK formats; reading reports the type.
  if (test::have_data("aorta-closed-6k.vtp")) {
    EXPECT_EQ(read_vtk_mesh(test::data_dir() / "aorta-closed-6k.vtp").points_type, "Float32");
  }
  for (const std::string type : {"Float32", "Float64"}) {
    MeshData d = one_triangle(Positions{{0, 0, 0}, {1.1, 0, 0}, {0, 1.3, 0.1}});
    d.points_type = type;
    for (const std::string kind : {"vtp", "vtk"}) {
      const MeshData back = read_vtk_mesh_from_memory(write_vtk_mesh_to_memory(d, kind), kind, "typed." + kind);
      EXPECT_EQ(back.points_type, type) << kind;
      EXPECT_LE((back.V - d.V).cwiseAbs().maxCoeff(), type == "Float32" ? 1e-7 : 0.0) << kind;
      if (type == "Float32") {
        EXPECT_GT((back.V - d.V).cwiseAbs().maxCoeff(), 0.0) << kind;  // rounded to float
      }
    }
  }
}

TEST(Vtp, ASpaceArrayOfOtherThanBytesIsNoFrame) {
  // Found by fuzzing: an ascii SPACE string array holding a number that is no byte
  // (6058) was converted to a character (undefined behaviour); it is now no frame.
  auto vtp = [](const std::string& codes) {
    return R"(<?xml version="1.0"?>
<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian" header_type="UInt32">
<PolyData><FieldData><Array type="String" Name="SPACE" NumberOfTuples="1" format="ascii">)" +
           codes + R"(</Array></FieldData>
<Piece NumberOfPoints="3" NumberOfPolys="1">
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0</DataArray></Points>
<Polys><DataArray type="Int64" Name="connectivity" format="ascii">0 1 2</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">3</DataArray></Polys>
</Piece></PolyData></VTKFile>
)";
  };
  EXPECT_EQ(read_vtk_mesh_from_memory(vtp("82 65 83 0"), "vtp", "ras.vtp").space, "RAS");
  EXPECT_EQ(read_vtk_mesh_from_memory(vtp("76 80 83 0"), "vtp", "lps.vtp").space, "LPS");
  for (const char* bad : {"82 6058 83 0", "82 -1 83 0", "82 65.5 83 0", "1e300"}) {
    const MeshData d = read_vtk_mesh_from_memory(vtp(bad), "vtp", "bad.vtp");
    EXPECT_EQ(d.space, "") << bad;
    EXPECT_EQ(d.F.rows(), 1) << bad;
  }
}

TEST(Vtp, BadInputIsAnErrorNamingTheFile) {
  const std::string good = make_vtp<std::uint32_t>({});
  auto expect_error = [](const std::string& text, const std::string& kind, const std::string& needle) {
    try {
      read_vtk_mesh_from_memory(text, kind, "broken.vtp");
      ADD_FAILURE() << "no error for " << needle;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("broken.vtp"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(good.substr(0, good.size() / 2), "vtp", "broken.vtp");
  expect_error("hello", "vtp", "not a VTK XML file");
  expect_error(
      "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n"
      "POLYGONS 1 4\n3 0 1 7\n",
      "vtk", "refers to point 7");
  if (test::have_data("aorta-centerlines.vtp")) {
    try {
      read_mesh(test::data_dir() / "aorta-centerlines.vtp");
      ADD_FAILURE() << "centerlines read as a surface";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no polygons"), std::string::npos) << e.what();
    }
  }
}

// ---------------------------------------------------------------- volumes

namespace {

// The test pattern: value = i + 10 j + 100 k, linear, so trilinear sampling is exact.
std::vector<float> ramp(int nx, int ny, int nz) {
  std::vector<float> v;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) v.push_back(static_cast<float>(i + 10 * j + 100 * k));
  return v;
}

// A rotation of 30 degrees about z, spacing (0.5, 0.7, 1.2), in the given world frame.
const double kTheta = M_PI / 6;
Eigen::Matrix3d rotation() {
  Eigen::Matrix3d R;
  R << std::cos(kTheta), -std::sin(kTheta), 0, std::sin(kTheta), std::cos(kTheta), 0, 0, 0, 1;
  return R;
}
const Eigen::Vector3d kSpacing(0.5, 0.7, 1.2);
const Eigen::Vector3d kOffset(10, -20, 5);

// Checks the volume maps index ijk to world_of(ijk) (given in `space`) with value f(ijk).
void expect_geometry(const Volume& v, Space space, const std::function<Eigen::Vector3d(Eigen::Vector3d)>& world_of,
                     double slope, double inter) {
  ASSERT_EQ(v.dims[0], 4);
  ASSERT_EQ(v.dims[1], 5);
  ASSERT_EQ(v.dims[2], 6);
  for (const Eigen::Vector3d& ijk :
       {Eigen::Vector3d(1.5, 2.25, 3.5), Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(3, 4, 5)}) {
    const auto value = v.sample(world_of(ijk), space);
    ASSERT_TRUE(value.has_value()) << ijk.transpose();
    EXPECT_NEAR(*value, slope * (ijk[0] + 10 * ijk[1] + 100 * ijk[2]) + inter, 1e-3) << ijk.transpose();
  }
  EXPECT_FALSE(v.sample(world_of(Eigen::Vector3d(-1, 0, 0)), space).has_value());
}

std::string gzip(const std::string& data) {
  z_stream s{};
  EXPECT_EQ(deflateInit2(&s, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&s, data.size()) + 32, '\0');
  s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  s.avail_in = static_cast<uInt>(data.size());
  s.next_out = reinterpret_cast<Bytef*>(out.data());
  s.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&s, Z_FINISH), Z_STREAM_END);
  out.resize(s.total_out);
  deflateEnd(&s);
  return out;
}

// NIfTI-1 single file: 348-byte header, 4 bytes of extension flag, float32 data.
std::string nifti(bool use_sform, double slope, double inter) {
  std::string h(352, '\0');
  auto put = [&](std::size_t at, auto value) { std::memcpy(h.data() + at, &value, sizeof(value)); };
  put(0, std::int32_t{348});
  const std::int16_t dim[8] = {3, 4, 5, 6, 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) put(40 + 2 * i, dim[i]);
  put(70, std::int16_t{16});  // DT_FLOAT32
  put(72, std::int16_t{32});
  const float pixdim[8] = {1, float(kSpacing[0]), float(kSpacing[1]), float(kSpacing[2]), 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) put(76 + 4 * i, pixdim[i]);
  put(108, float{352});
  put(112, static_cast<float>(slope));
  put(116, static_cast<float>(inter));
  put(123, std::uint8_t{10});  // xyzt_units: mm, s
  const Eigen::Matrix3d A = rotation() * kSpacing.asDiagonal();
  if (use_sform) {
    put(254, std::int16_t{1});
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) put(280 + 16 * r + 4 * c, static_cast<float>(A(r, c)));
      put(280 + 16 * r + 12, static_cast<float>(kOffset[r]));
    }
  } else {
    put(252, std::int16_t{1});
    put(264, static_cast<float>(std::sin(kTheta / 2)));  // quatern_d; b = c = 0
    for (int r = 0; r < 3; ++r) put(268 + 4 * r, static_cast<float>(kOffset[r]));
  }
  std::memcpy(h.data() + 344, "n+1\0", 4);
  return h + bytes_of(ramp(4, 5, 6));
}

}  // namespace

TEST(Volume, AortaMeshLiesOnTheZeroLevelOfItsSegmentation) {
  if (!test::have_data("aorta-levelset.mha") || !test::have_data("aorta-closed-6k.vtp")) return;
  const Volume phi = read_volume(test::data_dir() / "aorta-levelset.mha");
  EXPECT_EQ(phi.dims[0], 157);
  EXPECT_EQ(phi.dims[2], 34);
  EXPECT_EQ(phi.direction(0, 0), -1.0);
  const MeshData aorta = read_mesh(test::data_dir() / "aorta-closed-6k.vtp");
  double worst = 0;
  int outside_lps = 0;
  for (Eigen::Index i = 0; i < aorta.V.rows(); ++i) {
    const Eigen::Vector3d p = aorta.V.row(i).transpose();
    const auto value = phi.sample(p, Space::RAS);
    ASSERT_TRUE(value.has_value()) << "vertex " << i << " outside the image";
    worst = std::max(worst, std::abs(*value));
    if (!phi.sample(p, Space::LPS)) ++outside_lps;
  }
  EXPECT_LT(worst, 1e-3);
  // Reading the RAS mesh as LPS puts it outside the image: the option matters.
  EXPECT_EQ(outside_lps, aorta.V.rows());
}

// The editor's slices on the registered pair (RAS mesh, LPS image): an axial slice
// through a vertex, read back at the vertex's place in the slice's pixels, gives the
// level set's zero, so the planes and the mesh line up.
TEST(Volume, AortaSlicesThroughVerticesShowTheZeroLevel) {
  if (!test::have_data("aorta-levelset.mha") || !test::have_data("aorta-closed-6k.vtp")) return;
  const Volume phi = read_volume(test::data_dir() / "aorta-levelset.mha");
  const MeshData aorta = read_mesh(test::data_dir() / "aorta-closed-6k.vtp");
  // The largest distance from the zero level, in mm, read off the slices when the
  // mesh is taken to be in `space`.
  const auto worst_in = [&](Space space) {
    SliceParams p;
    p.window = 7.0;  // the level set's range, +-3.5 mm: 36 grey levels a millimetre
    p.level = 0.0;
    double worst = 0;
    int checked = 0;
    for (Eigen::Index i = 0; i < aorta.V.rows(); i += 97)
      for (const SliceAxis axis : {SliceAxis::Axial, SliceAxis::Coronal, SliceAxis::Sagittal}) {
        const Eigen::Vector3d x = aorta.V.row(i).transpose();
        const int n = static_cast<int>(axis) == 0 ? 2 : static_cast<int>(axis) == 1 ? 1 : 0;
        p.axis = axis;
        p.position = x[n];
        const Slice s = slice_volume(phi, space, p);
        // The vertex in pixel coordinates, and the slice's bilinear value there.
        const double a = (x - s.origin).dot(s.u) / s.u.squaredNorm(), b = (x - s.origin).dot(s.v) / s.v.squaredNorm();
        const int a0 = std::clamp(static_cast<int>(a), 0, s.width - 2),
                  b0 = std::clamp(static_cast<int>(b), 0, s.height - 2);
        const double fa = a - a0, fb = b - b0;
        const auto px = [&](int da, int db) {
          return static_cast<double>(s.pixels[static_cast<std::size_t>((b0 + db) * s.width + a0 + da)]);
        };
        const double grey =
            (1 - fb) * ((1 - fa) * px(0, 0) + fa * px(1, 0)) + fb * ((1 - fa) * px(0, 1) + fa * px(1, 1));
        worst = std::max(worst, std::abs((grey / 255.0 - 0.5) * p.window));
        ++checked;
      }
    EXPECT_GT(checked, 150);
    return worst;
  };
  // Quantization (half a grey level, 0.014 mm) and the pixel grid's resampling of
  // the slab's 1.5 mm layers (up to 0.15 mm in coronal and sagittal slices).
  EXPECT_LT(worst_in(Space::RAS), 0.25) << "mm off the zero level";
  // Taken as LPS, the mesh lies off the volume: the slices show it nowhere near.
  EXPECT_GT(worst_in(Space::LPS), 3.0);
}

TEST(Volume, MetaImageWithRotatedDirectionAndDetachedData) {
  const fs::path raw = scratch("ramp.raw"), mhd = scratch("ramp.mhd");
  write_bytes(raw, bytes_of(ramp(4, 5, 6)));
  const Eigen::Matrix3d R = rotation();
  // Columns of the direction matrix, written one after the other (ITK's order).
  write_bytes(mhd, fmt::format("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                               "CompressedData = False\nTransformMatrix = {} {} {} {} {} {} {} {} {}\n"
                               "Offset = {} {} {}\nElementSpacing = {} {} {}\nDimSize = 4 5 6\n"
                               "ElementType = MET_FLOAT\nElementDataFile = ramp.raw\n",
                               R(0, 0), R(1, 0), R(2, 0), R(0, 1), R(1, 1), R(2, 1), R(0, 2), R(1, 2), R(2, 2),
                               kOffset[0], kOffset[1], kOffset[2], kSpacing[0], kSpacing[1], kSpacing[2]));
  const Volume v = read_volume(mhd);
  expect_geometry(
      v, Space::LPS,
      [&](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + R * kSpacing.cwiseProduct(ijk); }, 1, 0);
}

TEST(Volume, DescribeReportsGeometryOrientationAndValueRange) {
  Volume v;
  v.dims = {3, 4, 5};
  v.spacing = Eigen::Vector3d(0.5, 1.0, 2.0);
  v.origin = Eigen::Vector3d(10, -20, 30);
  // i towards the patient's right, j anterior, k superior: a typical NIfTI (RAS).
  v.direction = Eigen::Vector3d(-1, -1, 1).asDiagonal();
  v.values.resize(v.num_voxels());
  for (std::size_t n = 0; n < v.values.size(); ++n) v.values[n] = static_cast<float>(n) - 7.0f;
  v.values[5] = std::numeric_limits<float>::quiet_NaN();
  const VolumeReport r = describe(v);
  EXPECT_EQ(r.orientation, "RAS");
  EXPECT_FALSE(r.oblique);
  EXPECT_EQ(r.nonfinite, 1u);
  EXPECT_EQ(r.min, -7.0);
  EXPECT_EQ(r.max, 59.0 - 7.0);
  // corners of the voxel-centre box: origin + direction * spacing * (dims - 1)
  EXPECT_TRUE(r.bbox_min.isApprox(Eigen::Vector3d(10 - 1.0, -20 - 3.0, 30)));
  EXPECT_TRUE(r.bbox_max.isApprox(Eigen::Vector3d(10, -20, 30 + 8.0)));
  // rotated by 30 degrees about z: oblique, still nearest to L and P
  v.direction = Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const VolumeReport o = describe(v);
  EXPECT_TRUE(o.oblique);
  EXPECT_EQ(o.orientation, "LPS");
}

TEST(Volume, NiftiSformQformScalingAndGzip) {
  const Eigen::Matrix3d R = rotation();
  // NIfTI's world is RAS: the same numbers as the MetaImage case, read in RAS.
  auto world = [&](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + R * kSpacing.cwiseProduct(ijk); };
  for (int sform = 0; sform < 2; ++sform) {
    SCOPED_TRACE(sform ? "sform" : "qform");
    const std::string bytes = nifti(sform, 2.0, 3.0);
    const fs::path nii = scratch("ramp.nii"), gz = scratch("ramp.nii.gz");
    write_bytes(nii, bytes);
    write_bytes(gz, gzip(bytes));
    expect_geometry(read_volume(nii), Space::RAS, world, 2.0, 3.0);
    expect_geometry(read_volume(gz), Space::RAS, world, 2.0, 3.0);
  }
}

TEST(Volume, AVoxelLimitRefusesTheHeaderBeforeReadingVoxels) {
  // What the editor does with an uploaded volume (EditorPage::kMaxUploadedVoxels): a
  // gzip-compressed NIfTI of 128^3 zeros is 8 MB of voxels in a few kilobytes.
  std::string bytes = nifti(true, 1.0, 0.0).substr(0, 352);
  const std::int16_t dim[4] = {3, 128, 128, 128};
  std::memcpy(bytes.data() + 40, dim, sizeof dim);
  bytes += std::string(std::size_t{128} * 128 * 128 * 4, '\0');
  const fs::path gz = scratch("zeros.nii.gz");
  write_bytes(gz, gzip(bytes));
  EXPECT_LT(fs::file_size(gz), 64u * 1024);
  EXPECT_EQ(read_volume(gz).values.size(), std::size_t{128} * 128 * 128);  // no limit: it reads
  auto expect_error = [](const std::function<void()>& read, std::initializer_list<const char*> needles) {
    try {
      read();
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      for (const char* needle : needles) EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error([&] { read_volume(gz, 1000000); }, {"zeros.nii.gz", "128 x 128 x 128", "1000000 at most"});
  // The limit is checked on the header: a MetaImage whose voxels are missing altogether
  // gets the limit's message, not the short data's.
  const fs::path mha = scratch("huge.mha");
  write_bytes(mha,
              "ObjectType = Image\nNDims = 3\nDimSize = 2000 2000 2000\nElementType = MET_FLOAT\n"
              "ElementDataFile = LOCAL\n");
  expect_error([&] { read_volume(mha, 1u << 28); }, {"huge.mha", "2000 x 2000 x 2000", "at most"});
}

TEST(Volume, NrrdRasSpaceRawAndGzip) {
  const Eigen::Matrix3d A = rotation() * kSpacing.asDiagonal();
  auto world = [&](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + A * ijk; };
  for (int compressed = 0; compressed < 2; ++compressed) {
    SCOPED_TRACE(compressed ? "gzip" : "raw");
    const std::string header = fmt::format(
        "NRRD0004\ntype: float\ndimension: 3\nspace: right-anterior-superior\nsizes: 4 5 6\n"
        "space directions: ({},{},{}) ({},{},{}) ({},{},{})\nkinds: domain domain domain\nendian: little\n"
        "encoding: {}\nspace origin: ({},{},{})\n\n",
        A(0, 0), A(1, 0), A(2, 0), A(0, 1), A(1, 1), A(2, 1), A(0, 2), A(1, 2), A(2, 2), compressed ? "gzip" : "raw",
        kOffset[0], kOffset[1], kOffset[2]);
    const std::string data = bytes_of(ramp(4, 5, 6));
    const fs::path p = scratch(compressed ? "ramp_gz.nrrd" : "ramp.nrrd");
    write_bytes(p, header + (compressed ? gzip(data) : data));
    expect_geometry(read_volume(p), Space::RAS, world, 1, 0);
  }
}

TEST(Volume, GradientMagnitudeOfALinearRampIsItsSlopePerMillimetre) {
  const fs::path raw = scratch("ramp2.raw"), mhd = scratch("ramp2.mhd");
  write_bytes(raw, bytes_of(ramp(4, 5, 6)));
  write_bytes(mhd,
              "ObjectType = Image\nNDims = 3\nBinaryData = True\nCompressedData = False\n"
              "ElementSpacing = 0.5 0.7 1.2\nDimSize = 4 5 6\nElementType = MET_FLOAT\nElementDataFile = ramp2.raw\n");
  const Volume v = read_volume(mhd);
  const Volume g = gradient_magnitude(v, 0.0);
  const double expected = Eigen::Vector3d(1 / 0.5, 10 / 0.7, 100 / 1.2).norm();
  EXPECT_NEAR(g.at(2, 2, 2), expected, 1e-3 * expected);
  EXPECT_NEAR(g.at(0, 0, 0), expected, 1e-3 * expected);  // one-sided at the border
  // Smoothing a linear field leaves it linear inside (clamped edges aside).
  const Volume gs = gradient_magnitude(v, 0.3);
  EXPECT_NEAR(gs.at(2, 2, 3), expected, 2e-2 * expected);
}

TEST(Volume, BadVolumesAreErrorsNamingTheFile) {
  const fs::path mhd = scratch("short.mhd"), raw = scratch("short.raw");
  write_bytes(raw, std::string(10, '\0'));
  write_bytes(mhd,
              "ObjectType = Image\nNDims = 3\nBinaryData = True\nElementSpacing = 1 1 1\nDimSize = 4 5 6\n"
              "ElementType = MET_FLOAT\nElementDataFile = short.raw\n");
  EXPECT_THROW(read_volume(mhd), InputError);
  EXPECT_THROW(read_volume(scratch("absent.nii")), InputError);
  const fs::path txt = scratch("x.nrrd");
  write_bytes(txt, "hello\n");
  try {
    read_volume(txt);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("x.nrrd"), std::string::npos);
  }
}

// meshpde's own MetaImage and NIfTI readers (fuzzing found VTK's crash and leak on
// damaged files): both byte orders, extensions, compressed data, and refusals in words.
namespace {

// The NIfTI-1 header of nifti(), with every field it sets written big-endian, and
// big-endian data: what a big-endian machine writes.
std::string nifti_big_endian(const std::string& little) {
  std::string b = little;
  auto swap_at = [&](std::size_t at, std::size_t n) { std::reverse(b.begin() + at, b.begin() + at + n); };
  swap_at(0, 4);
  for (int i = 0; i < 8; ++i) swap_at(40 + 2 * i, 2);
  swap_at(70, 2);
  swap_at(72, 2);
  for (int i = 0; i < 8; ++i) swap_at(76 + 4 * i, 4);
  for (const std::size_t at : {108, 112, 116}) swap_at(at, 4);
  swap_at(252, 2);
  swap_at(254, 2);
  for (int i = 0; i < 6; ++i) swap_at(256 + 4 * i, 4);  // quatern_b..d, qoffset_x..z
  for (int i = 0; i < 12; ++i) swap_at(280 + 4 * i, 4);
  for (std::size_t at = 352; at + 4 <= b.size(); at += 4) swap_at(at, 4);
  return b;
}

std::string refusal(const fs::path& p) {
  try {
    read_volume(p);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(read)";
}

}  // namespace

TEST(Volume, OwnReadersTakeBothByteOrdersExtensionsAndCompressedData) {
  const Eigen::Matrix3d R = rotation();
  auto world = [&](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + R * kSpacing.cwiseProduct(ijk); };
  for (int sform = 0; sform < 2; ++sform) {
    SCOPED_TRACE(sform ? "sform" : "qform");
    const std::string little = nifti(sform, 2.0, 3.0);
    const fs::path big = scratch("big.nii"), big_gz = scratch("big.nii.gz");
    write_bytes(big, nifti_big_endian(little));
    write_bytes(big_gz, gzip(nifti_big_endian(little)));
    expect_geometry(read_volume(big), Space::RAS, world, 2.0, 3.0);
    expect_geometry(read_volume(big_gz), Space::RAS, world, 2.0, 3.0);
    // A 48-byte extension between the header and the data: vox_offset 400.
    std::string extended = little.substr(0, 352) + std::string(48, '\x07') + little.substr(352);
    const float offset = 400;
    std::memcpy(extended.data() + 108, &offset, 4);
    const fs::path ext = scratch("extended.nii.gz");
    write_bytes(ext, gzip(extended));
    expect_geometry(read_volume(ext), Space::RAS, world, 2.0, 3.0);
  }
  // MetaImage: 16-bit big-endian voxels, zlib-compressed, attached.
  std::string shorts;
  for (const float x : ramp(4, 5, 6)) {
    const auto s = static_cast<std::uint16_t>(x);
    shorts += static_cast<char>(s >> 8);
    shorts += static_cast<char>(s & 0xff);
  }
  uLongf size = compressBound(shorts.size());
  std::string z(size, '\0');
  ASSERT_EQ(
      compress(reinterpret_cast<Bytef*>(z.data()), &size, reinterpret_cast<const Bytef*>(shorts.data()), shorts.size()),
      Z_OK);
  z.resize(size);
  const fs::path mha = scratch("shorts.mha");
  write_bytes(mha,
              fmt::format("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = True\n"
                          "CompressedData = True\nCompressedDataSize = {}\nElementSpacing = 0.5 0.7 1.2\n"
                          "Offset = 10 -20 5\nDimSize = 4 5 6\nElementType = MET_USHORT\nElementDataFile = LOCAL\n",
                          z.size()) +
                  z);
  expect_geometry(
      read_volume(mha), Space::LPS,
      [](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + kSpacing.cwiseProduct(ijk); }, 1, 0);
}

TEST(Volume, OwnReadersRefuseDamagedHeadersInWords) {
  const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 5 6\nElementType = MET_FLOAT\n";
  const fs::path mha = scratch("damaged.mha");
  write_bytes(mha, head + "ElementDataFile = LIST\n");
  EXPECT_NE(refusal(mha).find("only LOCAL or one data file"), std::string::npos) << refusal(mha);
  write_bytes(mha, head + "ElementDataFile = slice%03d.raw\n");
  EXPECT_NE(refusal(mha).find("only LOCAL or one data file"), std::string::npos) << refusal(mha);
  write_bytes(mha,
              "ObjectType = Image\nNDims = 3\nDimSize = 1000 1000 1000\nElementType = MET_FLOAT\n"
              "CompressedData = True\nElementDataFile = LOCAL\n" +
                  gzip(std::string(64, '\0')));
  EXPECT_NE(refusal(mha).find("cannot hold 1000 x 1000 x 1000 voxels"), std::string::npos) << refusal(mha);
  write_bytes(mha, head + "ElementDataFile = LOCAL\n" + std::string(10, '\0'));
  EXPECT_NE(refusal(mha).find("truncated data"), std::string::npos) << refusal(mha);
  write_bytes(mha, "ObjectType = Image\nNDims = 3\nDimSize = 4 5 x\nElementDataFile = LOCAL\n");
  EXPECT_NE(refusal(mha).find("'x' is not a number"), std::string::npos) << refusal(mha);

  const std::string good = nifti(true, 1, 0);
  const fs::path nii = scratch("damaged.nii.gz");
  const std::string z = gzip(good);
  write_bytes(nii, z.substr(0, z.size() / 2));
  EXPECT_NE(refusal(nii).find("ends after"), std::string::npos) << refusal(nii);
  std::string series = good;
  const std::int16_t four = 4, two = 2;
  std::memcpy(series.data() + 40, &four, 2);
  std::memcpy(series.data() + 48, &two, 2);
  const fs::path s = scratch("series.nii");
  write_bytes(s, series);
  EXPECT_NE(refusal(s).find("a 3D scalar image is needed"), std::string::npos) << refusal(s);
  write_bytes(s, good.substr(0, 200));
  EXPECT_NE(refusal(s).find("shorter than a NIfTI-1 header"), std::string::npos) << refusal(s);
  write_bytes(s, good.substr(0, 400));
  EXPECT_NE(refusal(s).find("truncated data"), std::string::npos) << refusal(s);
}

TEST(Volume, NrrdEncodingsDetachedDataAndSpacesByMeshpdesOwnReader) {
  const std::vector<float> values = ramp(4, 5, 6);
  auto lps = [](const Eigen::Vector3d& ijk) -> Eigen::Vector3d { return kOffset + kSpacing.cwiseProduct(ijk); };
  const std::string common = "NRRD0005\n# a comment\ntype: float\ndimension: 3\nsizes: 4 5 6\nkey:=value\n";
  const std::string geometry =
      "space: left-posterior-superior\nspace directions: (0.5,0,0) (0,0.7,0) (0,0,1.2)\n"
      "space origin: (10,-20,5)\n";
  // ascii
  std::string text;
  for (const float x : values) text += fmt::format("{} ", x);
  const fs::path a = scratch("ascii.nrrd");
  write_bytes(a, common + geometry + "encoding: ascii\n\n" + text + "\n");
  expect_geometry(read_volume(a), Space::LPS, lps, 1, 0);
  // hex, big-endian
  std::string hex;
  for (const float x : values) {
    std::uint32_t u;
    std::memcpy(&u, &x, 4);
    hex += fmt::format("{:08x}\n", u);
  }
  write_bytes(a, common + geometry + "endian: big\nencoding: hex\n\n" + hex);
  expect_geometry(read_volume(a), Space::LPS, lps, 1, 0);
  // detached raw data with a leading junk block skipped from the end (byte skip -1)
  const fs::path nhdr = scratch("detached.nhdr"), raw = scratch("detached.raw");
  write_bytes(raw, std::string(17, 'x') + bytes_of(values));
  write_bytes(nhdr, common + geometry + "endian: little\nencoding: raw\nbyte skip: -1\ndata file: detached.raw\n");
  expect_geometry(read_volume(nhdr), Space::LPS, lps, 1, 0);
  // left-anterior-superior: the file's y axis is LPS's -y
  write_bytes(a, common +
                     "space: left-anterior-superior\nspace directions: (0.5,0,0) (0,-0.7,0) (0,0,1.2)\n"
                     "space origin: (10,20,5)\nendian: little\nencoding: raw\n\n" +
                     bytes_of(values));
  expect_geometry(read_volume(a), Space::LPS, lps, 1, 0);
  // refused in words
  write_bytes(a, common + "space: left-posterior-superior\nspace directions: none (0,1,0) (0,0,1)\nencoding: raw\n\n" +
                     bytes_of(values));
  EXPECT_NE(refusal(a).find("without a direction"), std::string::npos) << refusal(a);
  write_bytes(a, common + "encoding: bzip2\n\nBZh");
  EXPECT_NE(refusal(a).find("encoding 'bzip2' is not read"), std::string::npos) << refusal(a);
  // Four axes: a leading list axis of values per voxel (a segmentation's layers) is not a
  // scalar image; four spatial axes (a time series) are not read at all.
  write_bytes(a,
              "NRRD0004\ntype: float\ndimension: 4\nsizes: 2 4 5 6\nkinds: list domain domain domain\n"
              "encoding: raw\n\n" +
                  bytes_of(std::vector<float>(240, 1.0f)));
  EXPECT_NE(refusal(a).find("2 values per voxel; a scalar image is needed"), std::string::npos) << refusal(a);
  write_bytes(a,
              "NRRD0004\ntype: float\ndimension: 4\nsizes: 1 4 5 6\nkinds: domain domain domain domain\n"
              "encoding: raw\n\n");
  EXPECT_NE(refusal(a).find("only a leading list axis"), std::string::npos) << refusal(a);
  write_bytes(a, "NRRD0004\ntype: float\ndimension: 5\nsizes: 1 4 5 6 2\nencoding: raw\n\n");
  EXPECT_NE(refusal(a).find("a 3D image is needed"), std::string::npos) << refusal(a);
  write_bytes(a, common + "encoding: gzip\n\n" + gzip(std::string(100, '\0')));
  EXPECT_NE(refusal(a).find("ends after"), std::string::npos) << refusal(a);
  write_bytes(a, "NRRD0004\ntype: float\ndimension: 3\nsizes: 1000 1000 1000\nencoding: ascii\n\n1 2 3\n");
  EXPECT_NE(refusal(a).find("cannot hold"), std::string::npos) << refusal(a);
}

TEST(Medical, VolumePathsAreKnownByTheirExtensionInAnyCase) {
  // The volume formats the component registers (io/file_formats.h).
  for (const char* yes : {"scan.mha", "scan.MHD", "a/b/ct.nii", "CT.Nii.Gz", "seg.nrrd", "seg.NHDR"})
    EXPECT_TRUE(is_volume_path(yes)) << yes;
  for (const char* no : {"mesh.ply", "mesh.vtp", "scan.nii.gz.ply", "folder.nii/mesh.obj", "nii", "scan.gz", "a.dcm"})
    EXPECT_FALSE(is_volume_path(no)) << no;
  EXPECT_NE(volume_extensions().find(".nii.gz"), std::string::npos);
  ASSERT_NE(find_volume_format("CT.NII.GZ"), nullptr);
  EXPECT_EQ(find_volume_format("CT.NII.GZ")->name, "NIfTI-1");
}

TEST(Medical, ReadMeshAndWriteMeshKnowTheComponentsFormats) {
  EXPECT_NE(mesh_extensions().find(".vtp"), std::string::npos);
  EXPECT_NE(mesh_extensions().find(".vtk"), std::string::npos);
  const auto g = latlong_sphere(5);
  MeshData d;
  d.V = g.V;
  d.F = g.F;
  d.cell_arrays["ModelFaceID"] = DataArray{Eigen::MatrixXd::Ones(g.F.rows(), 1), "Int32"};
  for (const char* name : {"registry.vtp", "REGISTRY.VTK"}) {
    const auto path = test::scratch_path(name);
    EXPECT_TRUE(write_mesh(path, d).empty()) << name;  // VTK keeps the cell array: no warning
    const MeshData back = read_mesh(path);
    EXPECT_EQ(back.F, d.F) << name;
    EXPECT_EQ(back.cell_arrays.at("ModelFaceID").type, "Int32") << name;
    std::filesystem::remove(path);
  }
  try {
    read_mesh(test::scratch_path("scan.nii.gz"));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a volume, not a mesh"), std::string::npos) << e.what();
  }
}

TEST(Vtp, EveryRealVtpMeshGetsTheDirectSolversAnswerFromTheGlobalSolver) {
  // The global-solver check (tests/solver_problems.h) on the .vtp meshes of ../shared/data; the
  // subdivided aorta-103k is the bench's (global_bilap_*_aorta-103k).
  for (const char* name : {"aorta-closed-6k.vtp", "carotid-ica-4k.vtp", "vessel-boolean-nonmanifold.vtp"}) {
    if (!test::have_data(name)) continue;
    test::expect_global_matches_direct(name, read_mesh(test::data_dir() / name));
  }
}

// write_metaimage_to_memory: an oblique volume with odd spacing and non-integer values
// reads back exactly (every voxel, origin, spacing and direction bit for bit).
TEST(Volume, AMetaImageWrittenInMemoryReadsBackExactly) {
  Volume v;
  v.dims = {4, 5, 6};
  v.values = ramp(4, 5, 6);
  for (float& x : v.values) x = x / 3.0f - 7.25f;
  v.spacing = kSpacing;
  v.origin = kOffset + Eigen::Vector3d(0.1, 1.0 / 3, -2.0 / 7);
  v.direction = rotation();
  const fs::path mha = scratch("written.mha");
  write_bytes(mha, write_metaimage_to_memory(v));
  const Volume back = read_volume(mha);
  EXPECT_EQ(back.dims, v.dims);
  EXPECT_EQ(back.values, v.values);
  EXPECT_EQ(back.spacing, v.spacing);
  EXPECT_EQ(back.origin, v.origin);
  EXPECT_EQ(back.direction, v.direction);
  v.spacing[1] = 0;
  EXPECT_THROW(write_metaimage_to_memory(v), InputError);
}

// io/zip_archive.h: entries written into an archive in memory read back as they were
// (empty, binary with zero bytes, a megabyte); a damaged or oversized archive is
// refused naming it.
TEST(Zip, AnArchiveWrittenInMemoryReadsBackItsEntries) {
  std::string binary(1000, '\0');
  for (std::size_t i = 0; i < binary.size(); i += 7) binary[i] = static_cast<char>(i);
  std::string big(1 << 20, 'x');
  for (std::size_t i = 0; i < big.size(); i += 4096) big[i] = static_cast<char>('a' + i % 26);
  const std::vector<std::pair<std::string, std::string>> entries = {
      {"session.json", R"({"format": "meshpde-session"})"},
      {"empty.bin", ""},
      {"binary.bin", binary},
      {"big.txt", big}};
  const std::string zip = write_zip(entries);
  EXPECT_LT(zip.size(), big.size() / 10) << "entries are deflated";
  const auto back = read_zip_entries(zip, "test.meshpde", 2 << 20);
  ASSERT_EQ(back.size(), entries.size());
  for (const auto& [name, data] : entries) EXPECT_EQ(back.at(name), data) << name;
  // Beyond the size given: refused before unpacking.
  EXPECT_NE(
      test::error_of([&] { read_zip_entries(zip, "test.meshpde", 1 << 20); }).find("test.meshpde: unpacks to more"),
      std::string::npos);
  // Cut short, or not an archive at all.
  EXPECT_NE(test::error_of([&] {
              read_zip_entries(zip.substr(0, zip.size() / 2), "cut.meshpde", 2 << 20);
            }).find("cut.meshpde"),
            std::string::npos);
  EXPECT_NE(
      test::error_of([&] { read_zip_entries("not a zip", "text.meshpde", 2 << 20); }).find("text.meshpde: not a zip"),
      std::string::npos);
}
