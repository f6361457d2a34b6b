#include "fuzz_seeds.h"

#include <fmt/format.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#ifdef MESHPDE_FUZZ_EDITOR
#include "editor_page.h"
#endif
#ifdef MESHPDE_FUZZ_MEDICAL
#include "meshpde/io/medical_io.h"
#endif

namespace meshpde::fuzz {

namespace {

namespace fs = std::filesystem;

void put(const fs::path& dir, const std::string& name, const std::string& bytes, int& count) {
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary) << bytes;
  ++count;
}

// A small closed mesh with a scalar and a vector field, as every format can hold.
MeshData small_mesh() {
  const GeneratedMesh g = icosphere(1, 2.0);
  MeshData d;
  d.V = g.V;
  d.F = g.F;
  d.vertex_scalars["phi"] = g.V.col(2);
  for (const char* c : {"_x", "_y", "_z"}) d.vertex_scalars[std::string("n") + c] = g.V.col(0) * 0.5;
  return d;
}

std::string float_bytes(int n) {
  std::string s(static_cast<std::size_t>(n) * 4, '\0');
  for (int k = 0; k < n; ++k) {
    const float x = static_cast<float>(k) - 3.5f;
    std::memcpy(s.data() + 4 * k, &x, 4);
  }
  return s;
}

// NIfTI-1, 2 x 3 x 2 float voxels, sform and qform both set (the header byte by byte,
// as the NIfTI-1 standard lays it out).
[[maybe_unused]] std::string nifti() {
  std::string h(352, '\0');
  auto at = [&](std::size_t offset, auto value) { std::memcpy(h.data() + offset, &value, sizeof(value)); };
  at(0, std::int32_t{348});
  const std::int16_t dim[8] = {3, 2, 3, 2, 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) at(40 + 2 * i, dim[i]);
  at(70, std::int16_t{16});  // DT_FLOAT32
  at(72, std::int16_t{32});
  const float pixdim[8] = {1, 0.5f, 0.7f, 1.2f, 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) at(76 + 4 * i, pixdim[i]);
  at(108, float{352});
  at(112, float{2});
  at(123, std::uint8_t{10});
  at(252, std::int16_t{1});
  at(254, std::int16_t{1});
  for (int r = 0; r < 3; ++r) {
    at(280 + 16 * r + 4 * r, pixdim[1 + r]);
    at(280 + 16 * r + 12, float(10 * r));
  }
  std::memcpy(h.data() + 344, "n+1\0", 4);
  return h + float_bytes(12);
}

// A DICOM Part 10 file composed element by element (dicom.h reads it): a CT slice of
// `cols` x `rows` signed 16-bit pixels, in the transfer syntax asked for. With `frames` > 1 an
// enhanced multi-frame file whose frames carry their positions in functional groups.
class DicomComposer {
 public:
  DicomComposer(bool implicit, bool big) : implicit_(implicit), big_(big) {}
  void element(std::uint16_t group, std::uint16_t elem, const char* vr, const std::string& value) {
    std::string v = value;
    if (v.size() % 2) v += (std::strcmp(vr, "UI") == 0 || std::strcmp(vr, "OB") == 0) ? '\0' : ' ';
    out_ += u16(group) + u16(elem);
    const bool long_form = std::strchr("OSU", vr[0]) && (vr[1] == 'B' || vr[1] == 'W' || vr[1] == 'Q' || vr[1] == 'N');
    if (implicit_) {
      out_ += u32(static_cast<std::uint32_t>(v.size()));
    } else if (long_form) {
      out_ += std::string(vr, 2) + std::string(2, '\0') + u32(static_cast<std::uint32_t>(v.size()));
    } else {
      out_ += std::string(vr, 2) + u16(static_cast<std::uint16_t>(v.size()));
    }
    out_ += v;
  }
  void us(std::uint16_t group, std::uint16_t elem, std::uint16_t value) { element(group, elem, "US", u16(value)); }
  // A sequence of one item holding `item` (elements composed alike), undefined lengths.
  void sequence(std::uint16_t group, std::uint16_t elem, const std::vector<std::string>& items) {
    out_ += u16(group) + u16(elem);
    if (!implicit_) out_ += std::string("SQ") + std::string(2, '\0');
    out_ += u32(0xffffffffu);
    for (const auto& item : items)
      out_ += u16(0xfffe) + u16(0xe000) + u32(0xffffffffu) + item + u16(0xfffe) + u16(0xe00d) + u32(0);
    out_ += u16(0xfffe) + u16(0xe0dd) + u32(0);
  }
  const std::string& bytes() const { return out_; }
  std::string u16(std::uint16_t x) const {
    return big_ ? std::string{char(x >> 8), char(x & 0xff)} : std::string{char(x & 0xff), char(x >> 8)};
  }
  std::string u32(std::uint32_t x) const {
    return big_ ? u16(std::uint16_t(x >> 16)) + u16(std::uint16_t(x))
                : u16(std::uint16_t(x)) + u16(std::uint16_t(x >> 16));
  }

 private:
  bool implicit_, big_;
  std::string out_;
};

std::string dicom(const std::string& syntax, int frames = 1, int rows = 2, int cols = 3) {
  const bool implicit = syntax == "1.2.840.10008.1.2", big = syntax == "1.2.840.10008.1.2.2";
  DicomComposer meta(false, false);
  meta.element(0x0002, 0x0001, "OB", std::string("\0\1", 2));
  meta.element(0x0002, 0x0002, "UI", frames > 1 ? "1.2.840.10008.5.1.4.1.1.2.1" : "1.2.840.10008.5.1.4.1.1.2");
  meta.element(0x0002, 0x0003, "UI", "1.2.3.4.5.6.7");
  meta.element(0x0002, 0x0010, "UI", syntax);
  DicomComposer group_length(false, false);
  group_length.element(0x0002, 0x0000, "UL", group_length.u32(static_cast<std::uint32_t>(meta.bytes().size())));
  DicomComposer d(implicit, big);
  d.element(0x0008, 0x0060, "CS", "CT");
  d.element(0x0020, 0x000e, "UI", "1.2.3.4.5.6.8");
  d.element(0x0020, 0x0011, "IS", "4");
  d.element(0x0020, 0x0032, "DS", "-10.5\\20\\3.25");
  d.element(0x0020, 0x0037, "DS", "1\\0\\0\\0\\0.6\\-0.8");
  d.us(0x0028, 0x0002, 1);
  d.element(0x0028, 0x0004, "CS", "MONOCHROME2");
  if (frames > 1) {
    d.element(0x0028, 0x0008, "IS", std::to_string(frames));
    DicomComposer shared(implicit, big), measures(implicit, big);
    measures.element(0x0028, 0x0030, "DS", "0.5\\0.7");
    shared.sequence(0x0028, 0x9110, {measures.bytes()});
    d.sequence(0x5200, 0x9229, {shared.bytes()});
    std::vector<std::string> per;
    for (int f = 0; f < frames; ++f) {
      DicomComposer position(implicit, big), item(implicit, big);
      const double t = 1.5 * (frames - 1 - f);  // frames stored against the slice order, along the normal (0, .8, .6)
      position.element(0x0020, 0x0032, "DS", fmt::format("-10.5\\{}\\{}", 20 + 0.8 * t, 3.25 + 0.6 * t));
      item.sequence(0x0020, 0x9113, {position.bytes()});
      per.push_back(item.bytes());
    }
    d.sequence(0x5200, 0x9230, per);
  }
  d.us(0x0028, 0x0010, static_cast<std::uint16_t>(rows));
  d.us(0x0028, 0x0011, static_cast<std::uint16_t>(cols));
  d.element(0x0028, 0x0030, "DS", "0.5\\0.7");
  d.us(0x0028, 0x0100, 16);
  d.us(0x0028, 0x0101, 16);
  d.us(0x0028, 0x0102, 15);
  d.us(0x0028, 0x0103, 1);
  d.element(0x0028, 0x1052, "DS", "-1024");
  d.element(0x0028, 0x1053, "DS", "2");
  std::string pixels;
  for (int k = 0; k < rows * cols * frames; ++k) pixels += d.u16(static_cast<std::uint16_t>(k * 37 - 50));
  d.element(0x7fe0, 0x0010, "OW", pixels);
  return std::string(128, '\0') + "DICM" + group_length.bytes() + meta.bytes() + d.bytes();
}

}  // namespace

int write_seeds(const fs::path& root) {
  int count = 0;
  const MeshData m = small_mesh();
  put(root / "obj", "icosphere.obj", write_mesh_to_memory(m, MeshFormat::Obj), count);
  put(root / "obj", "quads.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 4/1/1\n",
      count);
  put(root / "off", "icosphere.off", write_mesh_to_memory(m, MeshFormat::Off), count);
  put(root / "off", "quad.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", count);
  put(root / "ply", "binary.ply", write_mesh_to_memory(m, MeshFormat::Ply), count);
  put(root / "ply", "ascii.ply", write_mesh_to_memory(m, MeshFormat::Ply, {.binary = false}), count);
  put(root / "ply", "big-endian.ply",
      std::string("ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n") +
          std::string(36, '\0') + std::string("\x03\0\0\0\0\0\0\0\x01\0\0\0\x02", 13),
      count);
  put(root / "ply", "tristrips.ply",
      "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n0 1 0\n0 0 0\n1 1 0\n1 0 0\n"
      "5 1 0\n5 0 0\n6 1 0\n6 0 0\n11 0 1 2 3 -1 3 4 4 5 6 7\n",
      count);
  put(root / "stl", "binary.stl", write_mesh_to_memory(m, MeshFormat::Stl), count);
  put(root / "stl", "ascii.stl", write_mesh_to_memory(m, MeshFormat::Stl, {.binary = false}), count);
  put(root / "constraints", "scalar.csv", "vertex,value\n0,1\n5, -2.5 # a comment\n", count);
  put(root / "constraints", "vector.csv", "3,0,0.1,0\n7,1e-3,2,3\n", count);
  put(root / "constraints", "list.json",
      R"({"constraints": [{"vertex": 0, "value": [0, 0.1, 0]}, {"vertex": "@0.5,0.5,0", "value": 1}]})", count);
  put(root / "constraints", "bare.json", R"([{"vertex": 4, "value": 2}])", count);
  put(root / "probe_path", "press.csv", "t,dx,dy,dz\n0,0,0,0\n0.5,0,0,-0.05 # pressed\n0.7 0 0 -0.05\n", count);
  put(root / "selection", "list.txt", "# vertices\n1, 2 3\n40\n", count);
  for (const char* spec :
       {"rings:@0.5,0.5,0:2", "radius:20:0.3", "halfspace:1,0,0:0.25", "field:h>0.5", "boundary", "all"})
    put(root / "selection", std::string(spec).substr(0, std::string(spec).find(':')) + ".txt", std::string(spec) + "\n",
        count);
  // The editor: message sequences (one a line) and uploads (a format byte, the file).
  const std::vector<std::pair<std::string, std::vector<std::string>>> sequences{
      {"correct.txt",
       {R"({"type": "correct", "vertex": 5, "move": [0, 0, 1], "radius": 4})", R"({"type": "undo"})",
        R"({"type": "redo"})"}},
      {"poke.txt",
       {R"({"type": "poke_begin", "vertex": 3, "influence": 2})", R"({"type": "poke_move", "offset": [0, 0, -0.5]})",
        R"({"type": "poke_end"})"}},
      {"drag.txt",
       {R"({"type": "brush", "vertex": 1, "radius": 3, "value": 5})",
        R"({"type": "drag_begin", "vertex": 1, "radius": 5})", R"({"type": "drag_move", "offset": [0.5, 0, 0]})",
        R"({"type": "drag_end"})"}},
      {"tissue.txt",
       {R"({"type": "brush", "property": "mass", "vertex": 2, "radius": 3, "value": 0.9})",
        R"({"type": "brush", "property": "elasticity", "vertex": 4, "radius": 2, "value": 0.3})",
        R"({"type": "correct", "vertex": 3, "move": [0, 0, 1], "radius": 4, "dynamic": true})"}},
      {"paint.txt",
       {R"({"type": "paint", "vertex": 7, "value": 2, "g1": 0, "g2": 1})",
        R"({"type": "paint_vector", "vertex": 9, "vector": [1, 0, 0]})", R"({"type": "clear_paint"})"}},
      {"slices.txt",
       {R"({"type": "slice", "axis": "axial", "position": 0, "window": 10, "level": 0, "seq": 1})",
        R"({"type": "slice", "axis": "sagittal", "position": 4.5, "window": 0.001, "level": 2, "seq": 2})",
        R"({"type": "slice", "axis": "coronal", "position": -30, "seq": 3})",
        R"({"type": "correct", "vertex": 5, "move": [0, 0, 1], "radius": 4, "image": true})",
        R"x({"type": "colour", "field": "image pull (mm)"})x", R"x({"type": "colour", "field": "moved (mm)"})x",
        R"({"type": "colour", "field": "paint"})"}},
      {"heat.txt",
       {R"({"type": "source", "vertex": 0})", R"({"type": "play", "kind": "heat"})",
        R"({"type": "play", "kind": "wave"})", R"({"type": "clear_sources"})", R"({"type": "ping"})"}},
      {"point.txt",
       {R"({"type": "drag_begin", "vertex": 1, "point": [0.1, 0.2, 0.3], "radius": 5})",
        R"({"type": "drag_move", "offset": [0.5, 0, 0]})",
        R"({"type": "correct", "vertex": 1, "point": [0.1, 0.2, 0.3], "move": [0.5, 0, 0], "radius": 5})",
        R"({"type": "correct", "vertex": 2, "point": [9, -3, 1e9], "move": [0, 0, 1], "radius": 1e-30})"}},
      {"rim.txt",
       {R"({"type": "rim", "point": [0.1, 0.2, 0.3], "radius": 5, "seq": 1})",
        R"({"type": "rim", "point": [0.1, 0.2, 0.3], "triangle": 3, "radius": 0.5, "seq": 2})",
        R"({"type": "rim", "point": [1e300, 0, 0], "triangle": -1, "radius": 1e300, "seq": 3})",
        R"({"type": "drag_begin", "vertex": 1, "point": [0.1, 0.2, 0.3], "triangle": 2, "radius": 5})",
        R"({"type": "correct", "vertex": 1, "point": [0.1, 0.2, 0.3], "triangle": 2, "move": [0.5, 0, 0]})"}},
      {"springs.txt",
       {R"({"type": "correct", "vertex": 2, "move": [1, 1, 0], "radius": 3, "method": "springs", "image": false})"}},
  };
  for (const auto& [name, messages] : sequences) {
    std::string text;
    for (const std::string& message : messages) text += message + "\n";
    put(root / "editor_message", name, text, count);
  }
  {
    const char* formats[] = {"obj", "off", "ply", "stl"};
    const MeshFormat f[] = {MeshFormat::Obj, MeshFormat::Off, MeshFormat::Ply, MeshFormat::Stl};
    for (int k = 0; k < 4; ++k)
      put(root / "editor_upload", std::string("upload-") + formats[k] + ".bin",
          std::string(1, static_cast<char>(k)) + write_mesh_to_memory(m, f[k]), count);
  }
#ifdef MESHPDE_FUZZ_MEDICAL
  put(root / "editor_upload", "upload-vtp.bin", std::string(1, '\x04') + write_vtk_mesh_to_memory(m, "vtp"), count);
  put(root / "editor_upload", "upload-vtk.bin", std::string(1, '\x05') + write_vtk_mesh_to_memory(m, "vtk"), count);
  put(root / "vtp", "appended-zlib.vtp", write_vtk_mesh_to_memory(m, "vtp"), count);
  {
    MeshData framed = m;  // 3D Slicer's frame tag: a field-data string array SPACE
    framed.space = "RAS";
    put(root / "vtp", "space-field-data.vtp", write_vtk_mesh_to_memory(framed, "vtp"), count);
  }
  put(root / "vtp", "ascii.vtp",
      R"(<?xml version="1.0"?>
<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian" header_type="UInt32">
<PolyData><Piece NumberOfPoints="3" NumberOfPolys="1">
<PointData Scalars="s"><DataArray type="Float32" Name="s" format="ascii">1 2 3</DataArray></PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0</DataArray></Points>
<Polys><DataArray type="Int64" Name="connectivity" format="ascii">0 1 2</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">3</DataArray></Polys>
</Piece></PolyData></VTKFile>
)",
      count);
  put(root / "vtk", "binary.vtk", write_vtk_mesh_to_memory(m, "vtk"), count);
#ifdef MESHPDE_FUZZ_EDITOR
  {
    // A saved session: a correction made, another undone, a tissue brush, no image.
    editor::EditorPage page(editor::PageSink{.text = [](std::string) {}, .binary = [](std::string) {}}, nullptr,
                            Space::RAS);
    editor::Loaded l;
    l.data = m;
    l.name = "small.vtp";
    page.load(l);
    for (const char* message :
         {R"({"type": "brush", "vertex": 1, "radius": 3, "value": 5})",
          R"({"type": "correct", "vertex": 2, "move": [0, 0, 0.1], "radius": 4})",
          R"({"type": "correct", "vertex": 3, "move": [0.1, 0, 0], "radius": 4})", R"({"type": "undo"})"})
      page.handle(message, false);
    put(root / "editor_upload", "upload-session.bin",
        std::string(1, '\x07') + page.save_session(R"({"tool": "correct"})").first, count);
  }
#endif
  put(root / "vtk", "ascii.vtk",
      "# vtk DataFile Version 3.0\nSPACE=RAS\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 1 1 0 0 1 0\n"
      "POLYGONS 1 5\n4 0 1 2 3\nPOINT_DATA 4\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3 4\n",
      count);
  put(root / "metaimage", "float.mha",
      "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nCompressedData = False\n"
      "TransformMatrix = -1 0 0 0 -1 0 0 0 1\nOffset = 1 2 3\nElementSpacing = 0.5 0.7 1.2\nDimSize = 2 3 2\n"
      "ElementType = MET_FLOAT\nElementDataFile = LOCAL\n" +
          float_bytes(12),
      count);
  put(root / "metaimage", "short.mha",
      "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
          std::string(16, '\x01'),
      count);
  put(root / "nifti", "float.nii", nifti(), count);
  put(root / "nrrd", "raw.nrrd",
      "NRRD0004\ntype: float\ndimension: 3\nspace: right-anterior-superior\nsizes: 2 3 2\n"
      "space directions: (0.5,0,0) (0,0.7,0) (0,0,1.2)\nkinds: domain domain domain\nendian: little\n"
      "encoding: raw\nspace origin: (1,2,3)\n\n" +
          float_bytes(12),
      count);
  put(root / "nrrd", "ascii.nrrd",
      "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 2\nencoding: ascii\n\n1 2 3 4 5 6 7 8\n",
      count);
  // nifti_gz: scripts/fuzz gzips the .nii seed (gzip, not a library of ours).
  put(root / "dicom", "explicit-little.dcm", dicom("1.2.840.10008.1.2.1"), count);
  put(root / "dicom", "implicit-little.dcm", dicom("1.2.840.10008.1.2"), count);
  put(root / "dicom", "explicit-big.dcm", dicom("1.2.840.10008.1.2.2"), count);
  put(root / "dicom", "enhanced-multiframe.dcm", dicom("1.2.840.10008.1.2.1", 3), count);
  // Large enough for every codec (scripts/fuzz compresses it with gdcmconv).
  put(root / "dicom", "explicit-little-16x16.dcm", dicom("1.2.840.10008.1.2.1", 1, 16, 16), count);
#endif
  return count;
}

}  // namespace meshpde::fuzz
