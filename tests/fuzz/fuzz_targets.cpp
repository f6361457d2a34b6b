#include "fuzz_targets.h"

#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>

#include "meshpde/apps/haptics.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/selection.h"
#ifdef MESHPDE_FUZZ_EDITOR
#include <nlohmann/json.hpp>

#include "editor_page.h"
#endif
#include "meshpde/core/errors.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#ifdef MESHPDE_FUZZ_MEDICAL
#include "meshpde/io/dicom.h"
#include "meshpde/io/medical_io.h"
#endif

namespace meshpde::fuzz {

namespace {

// A broken promise: report it and abort, which libFuzzer and the replay count as a crash.
[[noreturn]] void broken(const std::string& what) {
  std::fprintf(stderr, "fuzz: broken promise: %s\n", what.c_str());
  std::abort();
}

// Runs `read`, accepting meshpde's errors (the input was refused in words) and
// nothing else: a std::exception of another kind escapes its reader without a message
// that names the file, which is a bug too.
std::string refusal;

template <class F>
int guarded(F&& read) {
  refusal.clear();
  try {
    read();
  } catch (const Error& e) {
    refusal = e.what();
    if (refusal.empty()) broken("an error without a message");
  } catch (const std::bad_alloc&) {
    broken("std::bad_alloc: a size taken from the input was not checked");
  } catch (const std::exception& e) {
    broken(std::string("an exception that is not meshpde's: ") + e.what());
  }
  return 0;
}

std::string bytes(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// What every mesh reader promises of what it returns.
void check_mesh(const MeshData& d) {
  if (!d.V.allFinite()) broken("a non-finite coordinate was accepted");
  const auto n = d.V.rows();
  if (d.F.rows() > 0 && (d.F.minCoeff() < 0 || d.F.maxCoeff() >= n)) broken("a triangle index out of range");
  for (const auto& [name, f] : d.vertex_scalars)
    if (f.size() != n) broken("vertex field '" + name + "' has the wrong length");
  for (const auto& [name, a] : d.point_arrays)
    if (a.values.rows() != n) broken("point array '" + name + "' has the wrong length");
  for (const auto& [name, a] : d.cell_arrays)
    if (a.values.rows() != d.F.rows()) broken("cell array '" + name + "' has the wrong length");
  // What the tool does next with a mesh it read: connectivity and the shape report,
  // which must refuse in words or succeed.
  const Mesh mesh(d.V, d.F);
  const MeshReport r = analyze(mesh);
  if (r.vertices != mesh.num_vertices()) broken("the report counts other vertices than the mesh has");
}

int mesh_format(const std::uint8_t* data, std::size_t size, MeshFormat format) {
  return guarded([&] { check_mesh(read_mesh_from_memory(bytes(data, size), format, "fuzz")); });
}

// A small mesh for the parsers that name vertices (by index or by position).
const Mesh& grid() {
  static const Mesh m = [] {
    const GeneratedMesh g = plane_grid(6, 6);
    return Mesh(g.V, g.F);
  }();
  return m;
}

int constraints(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    const std::string text = bytes(data, size);
    for (const int m : {1, 3}) try {
        for (const auto& c : parse_constraints(grid(), text, m, "fuzz.csv")) {
          if (c.vertex < 0 || c.vertex >= grid().num_vertices()) broken("a constraint on a vertex out of range");
          if (c.value.size() != m || !c.value.allFinite()) broken("a constraint with a bad value");
        }
      } catch (const InputError&) {
      }
  });
}

int probe_path(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    const auto p = parse_probe_path(bytes(data, size), "fuzz.csv");
    for (std::size_t k = 0; k < p.size(); ++k) {
      if (!std::isfinite(p[k].t) || !p[k].offset.allFinite()) broken("a non-finite path point");
      if (k > 0 && !(p[k].t > p[k - 1].t)) broken("path times that do not increase");
    }
    if (!probe_path_at(p, 0.5 * (p.front().t + p.back().t)).allFinite()) broken("a non-finite probe offset");
  });
}

int selection(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    // The text as a vertex list (a file: selection), and its first line as a spec.
    const std::string text = bytes(data, size);
    try {
      for (const int v : parse_vertex_list(grid(), text, "fuzz.txt"))
        if (v < 0 || v >= grid().num_vertices()) broken("a listed vertex out of range");
    } catch (const InputError&) {
    }
    const std::string spec = text.substr(0, text.find('\n'));
    if (spec.rfind("file:", 0) == 0) return;  // no files from the fuzzer
    for (const int v : select_vertices(grid(), spec, {{"h", grid().positions().col(1)}}))
      if (v < 0 || v >= grid().num_vertices()) broken("a selected vertex out of range");
  });
}

#ifdef MESHPDE_FUZZ_MEDICAL
int vtk_mesh(const std::uint8_t* data, std::size_t size, const char* kind) {
  return guarded([&] { check_mesh(read_vtk_mesh_from_memory(bytes(data, size), kind, "fuzz")); });
}

// The volume readers read files (by name: a .mhd or .nhdr names its data file): the bytes go to a
// file of this process's own, then read_volume reads it.
int volume(const std::uint8_t* data, std::size_t size, const std::string& suffix) {
  // A folder of this process's own, removed when the process ends.
  static const struct Scratch {
    std::filesystem::path dir;
    Scratch() {
      const char* tmp = std::getenv("TMPDIR");
      dir = std::filesystem::path(tmp && *tmp ? tmp : "/tmp") / ("meshpde-fuzz-" + std::to_string(getpid()));
      std::filesystem::create_directories(dir);
    }
    ~Scratch() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } scratch;
  const std::filesystem::path& dir = scratch.dir;
  const auto path = dir / ("input" + suffix);
  std::filesystem::create_directories(dir);  // again, should something have removed it
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  return guarded([&] {
    const Volume v = read_volume(path);
    if (v.values.size() != v.num_voxels()) broken("a volume with another number of values than voxels");
    if (!v.spacing.allFinite() || !v.origin.allFinite() || !v.direction.allFinite())
      broken("a volume with a non-finite geometry");
  });
}

// One DICOM file, as a series of that one file (its header, its structure checked
// before GDCM sees it, then its pixels decoded).
int dicom(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    const Volume v = read_dicom_file_from_memory(bytes(data, size), "fuzz.dcm");
    if (v.values.size() != v.num_voxels()) broken("a volume with another number of values than voxels");
    if (!v.spacing.allFinite() || !v.origin.allFinite() || !v.direction.allFinite())
      broken("a volume with a non-finite geometry");
  });
}
#endif

#ifdef MESHPDE_FUZZ_EDITOR
// A page's sink that checks every frame: text frames are JSON objects with a "type",
// errors carry a message and none is an internal error (an exception that is not
// meshpde's, which the page reports instead of crashing); binary frames have a tag.
editor::PageSink checking_sink() {
  return {.text =
              [](std::string s) {
                const auto j = nlohmann::json::parse(s, nullptr, false);
                if (j.is_discarded() || !j.is_object() || !j.contains("type")) broken("a reply that is not a message");
                if (j["type"] == "error") {
                  const std::string m = j.value("message", std::string());
                  if (m.empty()) broken("an error reply without a message");
                  if (m.rfind("internal error", 0) == 0) broken(m);
                }
              },
          .binary =
              [](std::string s) {
                if (s.size() < 8) broken("a binary frame without a tag and a count");
              }};
}

// A small sphere, the page's mesh at the start of every input.
const editor::Loaded& small_sphere() {
  static const editor::Loaded l = [] {
    editor::Loaded out;
    const GeneratedMesh g = icosphere(2, 10.0);
    out.data.V = g.V;
    out.data.F = g.F;
    out.name = "sphere.ply";
    return out;
  }();
  return l;
}

// A small oblique volume around the sphere (its signed distance), so that slices and
// image-guided corrections are fuzzed too.
std::shared_ptr<const editor::EditorImage> small_image() {
  static const auto image = [] {
    Volume v;
    v.dims = {9, 7, 5};
    v.spacing = Eigen::Vector3d(3.0, 3.5, 5.0);
    v.origin = Eigen::Vector3d(-12, -11, -10);
    v.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    for (int k = 0; k < v.dims[2]; ++k)
      for (int j = 0; j < v.dims[1]; ++j)
        for (int i = 0; i < v.dims[0]; ++i)
          v.values.push_back(static_cast<float>(v.index_to_lps(Eigen::Vector3d(i, j, k)).norm() - 10.0));
    auto out = std::make_shared<editor::EditorImage>();
    out->volume = std::make_shared<const Volume>(v);
    out->edges = std::make_shared<const Volume>(gradient_magnitude(v, 1.0));
    out->low = -5;
    out->high = 5;
    out->name = "sphere-distance";
    return out;
  }();
  return image;
}

// The editor's WebSocket requests, in process: up to eight messages, one a line, to a
// fresh page on a small sphere with a volume beside it, a frame after each.
int editor_message(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    editor::EditorPage page(checking_sink(), small_image(), Space::LPS);
    page.load(small_sphere());
    const std::string text = bytes(data, size);
    std::size_t at = 0;
    for (int k = 0; k < 8 && at <= text.size(); ++k) {
      const std::size_t end = std::min(text.find('\n', at), text.size());
      page.handle(text.substr(at, end - at), false);
      page.frame();
      at = end + 1;
    }
  });
}

// The editor's upload handler: the first byte picks the file's extension (a mesh format,
// or a .zip of a DICOM series), the rest is the file, opened by a page as an upload is.
int editor_upload(const std::uint8_t* data, std::size_t size) {
  return guarded([&] {
    if (size == 0) return;
    static const char* kNames[] = {"up.obj", "up.off", "up.ply",     "up.stl",
                                   "up.vtp", "up.vtk", "series.zip", "session.meshpde"};
    editor::EditorPage page(checking_sink(), nullptr, Space::LPS);
    const char* name = kNames[data[0] % 8];
    if (editor::is_volume_upload(name)) {  // a DICOM series zipped
      page.upload_image(bytes(data + 1, size - 1), name);
      return;
    }
    const int n = page.upload(bytes(data + 1, size - 1), name);
    if (n <= 0) broken("an upload opened with no vertices");
    page.frame();
  });
}
#endif

}  // namespace

const std::vector<Target>& targets() {
  static const std::vector<Target> all = [] {
    std::vector<Target> t{
        {"obj", "Wavefront OBJ meshes", ".obj",
         [](const std::uint8_t* d, std::size_t n) { return mesh_format(d, n, MeshFormat::Obj); }},
        {"off", "OFF meshes", ".off",
         [](const std::uint8_t* d, std::size_t n) { return mesh_format(d, n, MeshFormat::Off); }},
        {"ply", "PLY meshes (ascii, binary little and big endian)", ".ply",
         [](const std::uint8_t* d, std::size_t n) { return mesh_format(d, n, MeshFormat::Ply); }},
        {"stl", "STL meshes (ascii and binary)", ".stl",
         [](const std::uint8_t* d, std::size_t n) { return mesh_format(d, n, MeshFormat::Stl); }},
        {"constraints", "interpolation constraints (CSV and JSON)", ".csv", constraints},
        {"probe_path", "haptic probe paths (CSV)", ".csv", probe_path},
        {"selection", "vertex lists and selection specs", ".txt", selection},
    };
#ifdef MESHPDE_FUZZ_EDITOR
    t.push_back({"editor_message", "the editor's WebSocket requests (JSON, one a line)", ".txt", editor_message});
    t.push_back({"editor_upload", "the editor's upload handler (a format byte, then the file)", ".bin", editor_upload});
#endif
#ifdef MESHPDE_FUZZ_MEDICAL
    t.push_back({"vtp", "VTK XML PolyData", ".vtp",
                 [](const std::uint8_t* d, std::size_t n) { return vtk_mesh(d, n, "vtp"); }});
    t.push_back({"vtk", "legacy VTK PolyData", ".vtk",
                 [](const std::uint8_t* d, std::size_t n) { return vtk_mesh(d, n, "vtk"); }});
    t.push_back({"metaimage", "MetaImage volumes (.mha)", ".mha",
                 [](const std::uint8_t* d, std::size_t n) { return volume(d, n, ".mha"); }});
    t.push_back({"nifti", "NIfTI-1 volumes (.nii)", ".nii",
                 [](const std::uint8_t* d, std::size_t n) { return volume(d, n, ".nii"); }});
    t.push_back({"nifti_gz", "gzipped NIfTI-1 volumes (.nii.gz)", ".nii.gz",
                 [](const std::uint8_t* d, std::size_t n) { return volume(d, n, ".nii.gz"); }});
    t.push_back({"nrrd", "NRRD volumes (.nrrd)", ".nrrd",
                 [](const std::uint8_t* d, std::size_t n) { return volume(d, n, ".nrrd"); }});
    t.push_back({"dicom", "DICOM files (Part 10, any transfer syntax; read with GDCM)", ".dcm", dicom});
#endif
    return t;
  }();
  return all;
}

const std::string& last_refusal() {
  return refusal;
}

const Target* find_target(const std::string& name) {
  for (const Target& t : targets())
    if (t.name == name) return &t;
  return nullptr;
}

}  // namespace meshpde::fuzz
