#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "meshpde/core/errors.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/io/text_records.h"
#include "meshpde/mesh/generators.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
namespace fs = std::filesystem;

namespace {

MeshData sample() {
  const GeneratedMesh g = icosphere(1, 2.5);
  MeshData d;
  d.V = g.V;
  d.F = g.F;
  return d;
}

void expect_same(const MeshData& a, const MeshData& b, double tol) {
  ASSERT_EQ(a.V.rows(), b.V.rows());
  ASSERT_EQ(a.F.rows(), b.F.rows());
  EXPECT_LE((a.V - b.V).cwiseAbs().maxCoeff(), tol);
  EXPECT_EQ(a.F, b.F);
}

/// Expects an InputError whose message contains every fragment.
void expect_error(const std::string& bytes, MeshFormat fmt, std::initializer_list<const char*> fragments) {
  try {
    read_mesh_from_memory(bytes, fmt, "bad.mesh");
    ADD_FAILURE() << "accepted malformed input: " << bytes.substr(0, 80);
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("bad.mesh"), std::string::npos) << msg;
    for (const char* f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << f << "' not in: " << msg;
  }
}

fs::path scratch(const std::string& name) {
  return test::scratch_path(name);
}

}  // namespace

TEST(Io, RoundTripEveryFormat) {
  const MeshData d = sample();
  for (const auto fmt : {MeshFormat::Obj, MeshFormat::Off, MeshFormat::Ply}) {
    for (const bool binary : {false, true}) {
      const std::string bytes = write_mesh_to_memory(d, fmt, WriteOptions{.binary = binary});
      expect_same(d, read_mesh_from_memory(bytes, fmt, "rt"), 0.0);  // shortest round-trip text / raw doubles
    }
  }
  for (const bool binary : {false, true}) {
    // STL stores float corners; the welded mesh has the same vertex count and faces
    // up to vertex renumbering, so compare positions per face corner.
    const MeshData s =
        read_mesh_from_memory(write_mesh_to_memory(d, MeshFormat::Stl, {.binary = binary}), MeshFormat::Stl, "rt.stl");
    ASSERT_EQ(s.V.rows(), d.V.rows());
    ASSERT_EQ(s.F.rows(), d.F.rows());
    for (Eigen::Index f = 0; f < d.F.rows(); ++f)
      for (int c = 0; c < 3; ++c) {
        EXPECT_LE((s.V.row(s.F(f, c)) - d.V.row(d.F(f, c))).norm(), 1e-6);
      }
  }
}

TEST(Io, PlyKeepsVertexScalars) {
  MeshData d = sample();
  d.vertex_scalars["temperature"] = Eigen::VectorXd::LinSpaced(d.V.rows(), -1, 7);
  for (const bool binary : {false, true}) {
    const MeshData r =
        read_mesh_from_memory(write_mesh_to_memory(d, MeshFormat::Ply, {.binary = binary}), MeshFormat::Ply, "s.ply");
    ASSERT_TRUE(r.vertex_scalars.count("temperature"));
    EXPECT_EQ(r.vertex_scalars.at("temperature"), d.vertex_scalars.at("temperature"));
  }
}

TEST(Io, PlyBigEndianAndFloatAndQuads) {
  // Hand-built big-endian PLY: float positions, a uchar/uint face list with one quad.
  std::string h =
      "ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar quality\nelement face 1\nproperty list uchar uint vertex_indices\n"
      "end_header\n";
  auto be32 = [&](uint32_t v) {
    for (int k = 3; k >= 0; --k) h.push_back(static_cast<char>((v >> (8 * k)) & 0xff));
  };
  const float pts[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int i = 0; i < 4; ++i) {
    for (float x : pts[i]) {
      uint32_t b;
      std::memcpy(&b, &x, 4);
      be32(b);
    }
    h.push_back(static_cast<char>(10 * i));
  }
  h.push_back(4);
  for (uint32_t k = 0; k < 4; ++k) be32(k);
  const MeshData d = read_mesh_from_memory(h, MeshFormat::Ply, "be.ply");
  ASSERT_EQ(d.V.rows(), 4);
  EXPECT_EQ(d.V(2, 0), 1.0);
  EXPECT_EQ(d.V(2, 1), 1.0);
  EXPECT_EQ(d.F.rows(), 2);
  EXPECT_EQ(d.vertex_scalars.at("quality")(3), 30.0);
  ASSERT_EQ(d.warnings.size(), 1u);
  EXPECT_NE(d.warnings[0].find("triangulated 1 polygons"), std::string::npos);
}

TEST(Io, PlyElementWithoutPropertiesReadsNothingWhateverItsCount) {
  // Found by the fuzzer: an element with no properties holds no bytes, so its count
  // (here 10^15) is not checked against the data; the reader looped that often.
  std::string h =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement junk 1000000000000000\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  const float pts[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  h.append(reinterpret_cast<const char*>(pts), sizeof(pts));
  h.push_back(3);
  for (const int32_t k : {0, 1, 2}) h.append(reinterpret_cast<const char*>(&k), 4);
  const MeshData d = read_mesh_from_memory(h, MeshFormat::Ply, "junk.ply");
  ASSERT_EQ(d.V.rows(), 3);
  ASSERT_EQ(d.F.rows(), 1);
  EXPECT_EQ(d.V(1, 0), 1.0);
  EXPECT_EQ(d.F(0, 2), 2);
}

TEST(Io, PlyVertexElementWithoutPropertiesIsRefusedBeforeAnyAllocation) {
  // Found by CI's fuzzing: a binary vertex element without properties has a count no
  // byte bounds (10^15 here), and the reader reserved 3 * count coordinates before it
  // noticed x, y and z were missing (ASan: allocation size too big).
  expect_error("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000000\nend_header\n", MeshFormat::Ply,
               {"line 3", "lacks x, y or z"});
}

/// A (cols+1) x (rows+1) grid of the unit spacing in the xy-plane as PLY triangle
/// strips, one strip per row of squares: top0 bottom0 top1 bottom1 ... (ascending x),
/// which the strip rule turns into counter-clockwise triangles (normal +z). `joined`
/// puts every row in one list separated by -1; otherwise each row is its own entry.
std::string grid_strips_ply(int cols, int rows, bool joined, bool binary) {
  const int n = (cols + 1) * (rows + 1);
  std::vector<std::vector<int32_t>> strips;
  for (int r = 0; r < rows; ++r) {
    std::vector<int32_t> s;
    for (int c = 0; c <= cols; ++c) {
      s.push_back((r + 1) * (cols + 1) + c);
      s.push_back(r * (cols + 1) + c);
    }
    if (joined && !strips.empty()) {
      strips.back().push_back(-1);
      strips.back().insert(strips.back().end(), s.begin(), s.end());
    } else {
      strips.push_back(s);
    }
  }
  std::string out = fmt::format(
      "ply\nformat {} 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips {}\nproperty list int int vertex_indices\nend_header\n",
      binary ? "binary_little_endian" : "ascii", n, strips.size());
  auto put = [&](auto v) { out.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  for (int k = 0; k < n; ++k) {
    const float x = static_cast<float>(k % (cols + 1)), y = static_cast<float>(k / (cols + 1));
    if (binary) {
      put(x), put(y), put(0.0f);
    } else {
      out += fmt::format("{} {} 0\n", x, y);
    }
  }
  for (const auto& s : strips) {
    if (binary) {
      put(static_cast<int32_t>(s.size()));
      for (const int32_t v : s) put(v);
    } else {
      fmt::format_to(std::back_inserter(out), "{}", s.size());
      for (const int32_t v : s) fmt::format_to(std::back_inserter(out), " {}", v);
      out += '\n';
    }
  }
  return out;
}

TEST(Io, PlyTriangleStripsBecomeConsistentlyOrientedTriangles) {
  // Independent check: the strips of a grid must give exactly the grid's 2 * cols * rows
  // unit-square halves, each once, every one counter-clockwise (signed area +1/2).
  const int cols = 5, rows = 3;
  for (const bool joined : {true, false})
    for (const bool binary : {true, false}) {
      SCOPED_TRACE(fmt::format("joined {} binary {}", joined, binary));
      const MeshData d = read_mesh_from_memory(grid_strips_ply(cols, rows, joined, binary), MeshFormat::Ply, "s.ply");
      ASSERT_EQ(d.V.rows(), (cols + 1) * (rows + 1));
      ASSERT_EQ(d.F.rows(), 2 * cols * rows);
      EXPECT_TRUE(d.warnings.empty());
      std::set<std::array<int, 3>> seen;
      for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
        const Eigen::RowVector3d a = d.V.row(d.F(f, 0)), b = d.V.row(d.F(f, 1)), c = d.V.row(d.F(f, 2));
        EXPECT_DOUBLE_EQ(0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x()), 0.5) << "face " << f;
        std::array<int, 3> key{d.F(f, 0), d.F(f, 1), d.F(f, 2)};
        std::sort(key.begin(), key.end());
        EXPECT_TRUE(seen.insert(key).second) << "face " << f << " repeats a triangle";
      }
    }
}

TEST(Io, PlyTriangleStripsDropRepeatedCornersAndKeepTheirParity) {
  // Two strips stitched into one by repeating a corner (0 1 2 3 | 3 3 | 4 5 6 ...): the
  // stitch's triangles have a repeated corner and are dropped (and counted), while the
  // parity keeps running, so the second strip keeps its orientation.
  const std::string h =
      "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
      "0 1 0\n0 0 0\n1 1 0\n1 0 0\n5 1 0\n5 0 0\n6 1 0\n6 0 0\n"
      "10 0 1 2 3 3 4 4 5 6 7\n";
  const MeshData d = read_mesh_from_memory(h, MeshFormat::Ply, "stitched.ply");
  ASSERT_EQ(d.F.rows(), 4);
  for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
    const Eigen::RowVector3d a = d.V.row(d.F(f, 0)), b = d.V.row(d.F(f, 1)), c = d.V.row(d.F(f, 2));
    EXPECT_GT((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x(), 0) << "face " << f;
  }
  ASSERT_EQ(d.warnings.size(), 1u);
  EXPECT_NE(d.warnings[0].find("dropped 4 triangles"), std::string::npos) << d.warnings[0];
}

TEST(Io, PlyListCountsAndIndicesThatAreNotIntegersAreErrors) {
  // Found by fuzzing: a float list count or index of NaN passed the range checks (every
  // comparison with NaN is false) and was converted to an integer (undefined behaviour).
  const std::string verts =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\n";
  auto floats = [](std::initializer_list<float> v) {
    std::string b;
    for (const float x : v) b.append(reinterpret_cast<const char*>(&x), 4);
    return b;
  };
  const std::string xyz = floats({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  expect_error(
      verts + "property list float int vertex_indices\nend_header\n" + xyz + floats({nan}) + std::string(12, '\0'),
      MeshFormat::Ply, {"face 0", "list length nan is invalid"});
  expect_error(
      verts + "property list float int vertex_indices\nend_header\n" + xyz + floats({2.5f}) + std::string(12, '\0'),
      MeshFormat::Ply, {"face 0", "list length 2.5 is invalid"});
  std::string idx = "\x03" + floats({0, nan, 2});
  expect_error(verts + "property list uchar float vertex_indices\nend_header\n" + xyz + idx, MeshFormat::Ply,
               {"face 0", "vertex index nan outside"});
}

TEST(Io, ObjNegativeIndicesSlashesAndPolygons) {
  const std::string obj =
      "# comment\nmtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n"
      "s off\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -2 -1\n";
  const MeshData d = read_mesh_from_memory(obj, MeshFormat::Obj, "q.obj");
  EXPECT_EQ(d.V.rows(), 4);
  EXPECT_EQ(d.F.rows(), 3);
  EXPECT_EQ(d.F(2, 0), 0);
  EXPECT_EQ(d.F(2, 2), 3);
  EXPECT_EQ(d.warnings.size(), 1u);
}

TEST(Io, StlWeldsIdenticalCorners) {
  const std::string stl =
      "solid t\nfacet normal 0 0 1\n outer loop\n vertex 0 0 0\n vertex 1 0 0\n vertex 0 1 0\n endloop\nendfacet\n"
      "facet normal 0 0 1\n outer loop\n vertex 1 0 0\n vertex 1 1 0\n vertex 0 1 0\n endloop\nendfacet\nendsolid t\n";
  const MeshData d = read_mesh_from_memory(stl, MeshFormat::Stl, "w.stl");
  EXPECT_EQ(d.V.rows(), 4);
  EXPECT_EQ(d.F.rows(), 2);
}

TEST(Io, MalformedInputGivesClearErrors) {
  // Empty files.
  expect_error("", MeshFormat::Off, {"empty"});
  expect_error("", MeshFormat::Obj, {"no vertices"});
  expect_error("", MeshFormat::Ply, {"not a PLY"});
  expect_error("", MeshFormat::Stl, {"empty"});
  // OFF: truncated, negative and absurd counts, index out of range, NaN, Inf, junk.
  expect_error("OFF\n3 1 0\n0 0 0\n1 0 0\n", MeshFormat::Off, {"vertex 2", "file ends"});
  expect_error("OFF\n-3 1 0\n", MeshFormat::Off, {"line 2", "negative"});
  expect_error("OFF\n2000000000 2000000000 0\n0 0 0\n", MeshFormat::Off, {"line 2", "claims"});
  expect_error("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", MeshFormat::Off, {"line 6", "outside"});
  expect_error("OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", MeshFormat::Off, {"line 4", "not finite"});
  expect_error("OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", MeshFormat::Off, {"line 4", "not finite"});
  expect_error("OFF\n3 1 0\n0 0 0\n1 0 zz\n0 1 0\n3 0 1 2\n", MeshFormat::Off, {"line 4", "'zz'"});
  expect_error(std::string("\x7f\x45\x4c\x46\x02\x01\x01\0\0\0", 10), MeshFormat::Off, {"expected 'OFF'"});
  // OBJ.
  expect_error("v 0 0 0\nv 1 0 0\nf 1 2 3\n", MeshFormat::Obj, {"line 3", "face index 3"});
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", MeshFormat::Obj, {"line 4"});
  expect_error("v 0 0 0\nv 1 0\n", MeshFormat::Obj, {"line 2", "line ends"});
  expect_error("v 0 0 0\nxyz 1 2\n", MeshFormat::Obj, {"line 2", "unknown OBJ statement"});
  expect_error("v 0 0 1e999\n", MeshFormat::Obj, {"line 1"});
  // PLY: truncated binary, absurd counts, tristrips, bad index.
  const std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  expect_error(head + std::string(30, '\0'), MeshFormat::Ply, {"line 3", "claims 3 entries"});
  expect_error(head + std::string(72, '\0') + "\x03" + std::string(5, '\0'), MeshFormat::Ply, {"face 0", "file ends"});
  expect_error("ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n0\n", MeshFormat::Ply,
               {"line 3", "claims"});
  expect_error(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n4 0 1 -2 2\n",
      MeshFormat::Ply, {"tristrips 0", "vertex index -2 outside"});
  expect_error(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_index_list\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
      MeshFormat::Ply, {"line 7", "tristrips element lacks vertex_indices"});
  expect_error(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n",
      MeshFormat::Ply, {"face 0", "outside"});
  expect_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", MeshFormat::Ply, {"end_header"});
  // STL: binary header claiming more triangles than present; ascii without endsolid.
  std::string bin(84, '\0');
  const uint32_t n = 1000000;
  std::memcpy(bin.data() + 80, &n, 4);
  expect_error(bin + std::string(100, '\0'), MeshFormat::Stl, {"claims 1000000 triangles"});
  expect_error("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", MeshFormat::Stl, {"endsolid"});
}

TEST(Io, UnknownExtensionAndMissingFile) {
  EXPECT_THROW(format_from_path("mesh.xyz"), InputError);
  EXPECT_THROW(read_mesh(scratch("does-not-exist.obj")), InputError);
}

TEST(Io, AtomicWriteNeverLeavesHalfAFile) {
  const fs::path target = scratch("atomic.off");
  write_mesh(target, sample());
  const auto before = fs::file_size(target);
  // A directory in the way of the rename: the write fails and the old file stays.
  const fs::path blocked = scratch("blocked.off");
  fs::create_directories(blocked / "child");
  EXPECT_THROW(write_mesh(blocked, sample()), Error);
  EXPECT_TRUE(fs::is_directory(blocked));
  for (const auto& e : fs::directory_iterator(blocked.parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".blocked.off.tmp"), std::string::npos) << "temporary left behind";
  EXPECT_THROW(write_mesh(scratch("no-such-dir") / "x" / "y.off", sample()), Error);
  EXPECT_EQ(fs::file_size(target), before);
}

TEST(Io, ReadsEveryRealFormat) {
  for (const char* name : {"bunny-3k.off", "bunny-36k.obj", "igea-134k.ply", "aorta-open-6k.stl",
                           "coronary-phantom-7k.stl", "nonmanifold-vierbein.obj"}) {
    Mesh m;
    if (!test::load_data(name, m)) continue;  // (every missing file reported)
    EXPECT_GT(m.num_faces(), 0) << name;
  }
}

TEST(Io, AFormatRegisteredByAProgramIsReadAndWrittenByReadMeshAndWriteMesh) {
  // OBJ under a made-up extension, as a program would register a format of its own.
  MeshFileFormat f;
  f.name = "test format";
  f.extensions = {".TestMesh"};  // registered lower case; matched in any case
  f.read = [](const std::string& bytes, const std::string& ext, const std::string& name) {
    EXPECT_EQ(ext, ".testmesh");
    return read_mesh_from_memory(bytes, MeshFormat::Obj, name);
  };
  f.write = [](const MeshData& d, const std::string&, const WriteOptions&) {
    return write_mesh_to_memory(d, MeshFormat::Obj);
  };
  register_mesh_format(f);
  EXPECT_NE(mesh_extensions().find(".testmesh"), std::string::npos);
  ASSERT_NE(find_mesh_format("a/b/SPHERE.TESTMESH"), nullptr);
  EXPECT_EQ(find_mesh_format("a/b/SPHERE.TESTMESH")->name, "test format");

  const auto g = latlong_sphere(5);
  MeshData d;
  d.V = g.V;
  d.F = g.F;
  d.vertex_scalars["u"] = Eigen::VectorXd::Ones(g.V.rows());
  const auto path = test::scratch_path("registered.TestMesh");
  const auto warnings = write_mesh(path, d);
  ASSERT_EQ(warnings.size(), 1u);  // the format keeps no vertex fields, and says so
  EXPECT_NE(warnings[0].find("1 field(s) dropped"), std::string::npos) << warnings[0];
  const MeshData back = read_mesh(path);
  EXPECT_EQ(back.F, d.F);
  EXPECT_LT((back.V - d.V).cwiseAbs().maxCoeff(), 1e-12);
  std::filesystem::remove(path);
}

TEST(Io, AnUnknownExtensionIsRefusedWithEveryExtensionThisBuildReads) {
  try {
    read_mesh_from_memory("v 0 0 0\n", "mesh.xyz");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("mesh.xyz: unknown mesh format '.xyz'"), std::string::npos) << what;
    for (const char* ext : {".obj", ".off", ".ply", ".stl"}) EXPECT_NE(what.find(ext), std::string::npos) << what;
  }
  EXPECT_THROW(write_mesh_to_memory(MeshData{}, "mesh"), InputError);  // no extension at all
}

TEST(Io, TextRecordsSplitAsHandWrittenTablesAreWritten) {
  // Comments, blank lines, CRLF line ends, and the two separators; line numbers count
  // every line, so that messages name the line a user sees.
  const std::string text = "# header comment\r\nv, value\r\n\r\n  1, 2.5 # one\n2,,3\n4 5,6\n7,8,\n   \n";
  std::vector<std::pair<int, std::vector<std::string>>> commas, spaces;
  for_each_text_record(text, FieldSeparator::Comma,
                       [&](int line, const std::vector<std::string>& f) { commas.emplace_back(line, f); });
  for_each_text_record(text, FieldSeparator::CommaOrSpace,
                       [&](int line, const std::vector<std::string>& f) { spaces.emplace_back(line, f); });
  using R = std::vector<std::pair<int, std::vector<std::string>>>;
  EXPECT_EQ(commas,
            (R{{2, {"v", "value"}}, {4, {"1", "2.5"}}, {5, {"2", "", "3"}}, {6, {"4 5", "6"}}, {7, {"7", "8"}}}));
  EXPECT_EQ(spaces,
            (R{{2, {"v", "value"}}, {4, {"1", "2.5"}}, {5, {"2", "3"}}, {6, {"4", "5", "6"}}, {7, {"7", "8"}}}));
  int calls = 0;
  for_each_text_record("", FieldSeparator::Comma, [&](int, const std::vector<std::string>&) { ++calls; });
  for_each_text_record("# only a comment", FieldSeparator::CommaOrSpace,
                       [&](int, const std::vector<std::string>&) { ++calls; });
  // Separators only: no record (fuzzing found a reader indexing the empty fields).
  for_each_text_record(",\n , ,\n", FieldSeparator::CommaOrSpace,
                       [&](int, const std::vector<std::string>&) { ++calls; });
  EXPECT_EQ(calls, 0);
  for_each_text_record(",", FieldSeparator::Comma, [&](int, const std::vector<std::string>& f) {
    ++calls;
    EXPECT_EQ(f, std::vector<std::string>{""});  // a field, empty: the reader names it
  });
  EXPECT_EQ(calls, 1);
  calls = 0;
  // The last line needs no line end.
  for_each_text_record("1\n2", FieldSeparator::Comma, [&](int line, const std::vector<std::string>& f) {
    ++calls;
    EXPECT_EQ(f, std::vector<std::string>{std::to_string(line)});
  });
  EXPECT_EQ(calls, 2);
}

TEST(Io, ATemporaryPathIsPrivateAndGoesWithItsScopeWhateverIsUnderIt) {
  std::filesystem::path file, folder;
  {
    const TemporaryPath a("meshpde-test", ".bin"), b("meshpde-test", ".bin"), dir("meshpde-test-dir");
    EXPECT_NE(a.path(), b.path());
    EXPECT_EQ(a.path().extension(), ".bin");
    EXPECT_FALSE(std::filesystem::exists(a.path()));  // a name, nothing created
    write_file_atomically(a.path(), "bytes");
    std::filesystem::create_directories(dir.path() / "inner");
    write_file_atomically(dir.path() / "inner" / "x.dcm", "bytes");
    file = a.path();
    folder = dir.path();
    EXPECT_TRUE(std::filesystem::exists(file) && std::filesystem::exists(folder / "inner" / "x.dcm"));
  }
  EXPECT_FALSE(std::filesystem::exists(file));
  EXPECT_FALSE(std::filesystem::exists(folder));
  // Left by an exception too.
  try {
    const TemporaryPath t("meshpde-test");
    file = t.path();
    write_file_atomically(file, "bytes");
    throw InputError("on purpose");
  } catch (const InputError&) {
  }
  EXPECT_FALSE(std::filesystem::exists(file));
}
