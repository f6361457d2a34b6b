#include "editor_page.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume_slice.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/units.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/apps/segment_surface.h"
#include "meshpde/io/dicom.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/segmentation_io.h"
#include "meshpde/io/zip_archive.h"
#endif

namespace meshpde::editor {

namespace fs = std::filesystem;

namespace {

std::string lower_ext(const std::string& name) {
  std::string ext = fs::path(name).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string lower_name(const std::string& name) {
  std::string s = fs::path(name).filename().string();
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

template <class T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

Eigen::Vector3d vec3(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw InputError(fmt::format("'{}' must be an array of three numbers", key));
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!j[key][k].is_number()) throw InputError(fmt::format("'{}' must hold numbers", key));
    v[k] = j[key][k].get<double>();
  }
  if (!v.allFinite()) throw InputError(fmt::format("'{}' is not finite", key));
  return v;
}
// The surface point nearest to the message's "point" [x, y, z] (mm, the page's frame):
// on its "triangle" when the message names the one the page picked (no search over
// the mesh, which a hover on a large mesh could not afford), else anywhere.
SurfacePoint surface_point_of(const Mesh& mesh, const nlohmann::json& j) {
  const Eigen::Vector3d x = vec3(j, "point");
  if (!j.contains("triangle")) return closest_surface_points(mesh, std::span<const Eigen::Vector3d>(&x, 1))[0];
  if (!j["triangle"].is_number_integer()) throw InputError("'triangle' must be an integer");
  const int f = j["triangle"].get<int>();
  if (f < 0 || f >= mesh.num_faces())
    throw InputError(fmt::format("triangle {} does not exist (the mesh has {} triangles)", f, mesh.num_faces()));
  const auto corner = [&](int k) -> Eigen::Vector3d { return mesh.positions().row(mesh.triangles()(f, k)); };
  return {f, closest_point_on_triangle(x, corner(0), corner(1), corner(2))};
}

int vertex_of(const nlohmann::json& j) {
  if (!j.contains("vertex") || !j["vertex"].is_number_integer()) throw InputError("'vertex' must be an integer");
  return j["vertex"].get<int>();
}
double number(const nlohmann::json& j, const char* key, double fallback) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number()) throw InputError(fmt::format("'{}' must be a number", key));
  return j[key].get<double>();
}

// A session file's binary entries, read with every length checked.
struct Reader {
  const std::string& bytes;
  std::string what;
  std::size_t at = 0;
  template <class T>
  T take() {
    if (bytes.size() - at < sizeof(T)) throw InputError(fmt::format("{}: ends early (byte {})", what, at));
    T v;
    std::memcpy(&v, bytes.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  void magic(const char* m) {
    if (bytes.compare(0, 4, m) != 0) throw InputError(fmt::format("{}: does not start with {}", what, m));
    at = 4;
  }
  void end() const {
    if (at != bytes.size())
      throw InputError(fmt::format("{}: {} bytes more than it declares", what, bytes.size() - at));
  }
};

// history.bin: "MPH1", u32 vertices, u32 steps, u32 current; the original positions (f64
// x, y, z a vertex, mm); then for each later step u32 n and n times (u32 vertex, f64 x,
// y, z): the vertices whose position differs from the step before, where they are.
std::string encode_history(const std::vector<Positions>& h, std::size_t current) {
  std::string b = "MPH1";
  const auto nv = static_cast<std::uint32_t>(h.front().rows());
  put<std::uint32_t>(b, nv);
  put<std::uint32_t>(b, static_cast<std::uint32_t>(h.size()));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(current));
  for (std::uint32_t v = 0; v < nv; ++v)
    for (int c = 0; c < 3; ++c) put<double>(b, h.front()(v, c));
  for (std::size_t k = 1; k < h.size(); ++k) {
    std::vector<std::uint32_t> changed;
    for (std::uint32_t v = 0; v < nv; ++v)
      if (h[k].row(v) != h[k - 1].row(v)) changed.push_back(v);
    put<std::uint32_t>(b, static_cast<std::uint32_t>(changed.size()));
    for (const std::uint32_t v : changed) {
      put<std::uint32_t>(b, v);
      for (int c = 0; c < 3; ++c) put<double>(b, h[k](v, c));
    }
  }
  return b;
}

std::pair<std::vector<Positions>, std::size_t> decode_history(const std::string& bytes, const std::string& what,
                                                              Eigen::Index vertices) {
  Reader r{bytes, what};
  r.magic("MPH1");
  const auto nv = r.take<std::uint32_t>(), steps = r.take<std::uint32_t>(), current = r.take<std::uint32_t>();
  if (nv != vertices) throw InputError(fmt::format("{}: for {} vertices, the mesh has {}", what, nv, vertices));
  if (steps < 1 || current >= steps) throw InputError(fmt::format("{}: {} steps, at step {}", what, steps, current));
  // Each step takes at least 4 bytes: a count that cannot be met is refused before
  // anything is allocated for it.
  if (steps > bytes.size() / 4) throw InputError(fmt::format("{}: {} steps in {} bytes", what, steps, bytes.size()));
  std::vector<Positions> h;
  h.emplace_back(static_cast<Eigen::Index>(nv), 3);
  for (std::uint32_t v = 0; v < nv; ++v)
    for (int c = 0; c < 3; ++c) h.back()(v, c) = r.take<double>();
  for (std::uint32_t k = 1; k < steps; ++k) {
    h.push_back(h.back());
    const auto n = r.take<std::uint32_t>();
    for (std::uint32_t i = 0; i < n; ++i) {
      const auto v = r.take<std::uint32_t>();
      if (v >= nv) throw InputError(fmt::format("{}: step {} moves vertex {} of {}", what, k, v, nv));
      for (int c = 0; c < 3; ++c) h.back()(v, c) = r.take<double>();
    }
  }
  r.end();
  return {std::move(h), current};
}

// tissue.bin: "MPT1", then the stiffness, mass, elasticity and viscosity fields, each
// u32 n (0: none, else one a vertex) and n f64.
std::string encode_tissue(const CorrectionParams& t) {
  std::string b = "MPT1";
  for (const Eigen::VectorXd* f :
       {&t.stiffness, &t.tissue.mass_field, &t.tissue.elasticity_field, &t.tissue.viscosity_field}) {
    put<std::uint32_t>(b, static_cast<std::uint32_t>(f->size()));
    for (Eigen::Index i = 0; i < f->size(); ++i) put<double>(b, (*f)[i]);
  }
  return b;
}

CorrectionParams decode_tissue(const std::string& bytes, const std::string& what, Eigen::Index vertices) {
  Reader r{bytes, what};
  r.magic("MPT1");
  CorrectionParams t;
  for (Eigen::VectorXd* f :
       {&t.stiffness, &t.tissue.mass_field, &t.tissue.elasticity_field, &t.tissue.viscosity_field}) {
    const auto n = r.take<std::uint32_t>();
    if (n != 0 && n != vertices)
      throw InputError(fmt::format("{}: a field of {} values for {} vertices", what, n, vertices));
    f->resize(n);
    for (std::uint32_t i = 0; i < n; ++i) (*f)[i] = r.take<double>();
    if (!f->allFinite()) throw InputError(fmt::format("{}: a value is not finite", what));
  }
  r.end();
  return t;
}

}  // namespace

bool is_session_file(const std::string& name) {
  return lower_name(name).ends_with(".meshpde");
}

Loaded parse_mesh_bytes(const std::string& bytes, const std::string& name) {
  Loaded l;
  l.name = fs::path(name).filename().string();
  if (!find_mesh_format(l.name)) {
    // Everything the page opens, meshes and volumes: the upload is either.
    const std::string volumes = volume_extensions();
    throw InputError(
        fmt::format("{}: the editor opens meshes ({}), {} and sessions it saved (.meshpde)", l.name, mesh_extensions(),
                    volumes.empty() ? "volumes with meshpde built with meshpde::medical"
                                    : "volumes (" + volumes + ", or a DICOM series zipped into one .zip)"));
  }
  l.data = read_mesh_from_memory(bytes, l.name);
  return l;
}

std::string mesh_bytes(const MeshData& d, const std::string& name) {
  return write_mesh_to_memory(d, name);
}

Loaded generated(const std::string& requested) {
  Loaded l;
  const std::string kind = requested == "dented" ? "bifurcation" : requested == "sphere" ? "icosphere" : requested;
  GeneratorParams p;
  p.bifurcation = BifurcationParams{};
  p.bifurcation.dent = requested == "dented";
  p.level = 4;  // icosphere: 2,562 vertices
  p.radius = kind == "tube" ? 4.0 : 10.0;
  p.length = 40.0;
  p.rings = 60;
  p.segments = 40;
  p.nx = p.ny = 60;
  p.size = 30.0;
  const GeneratedMesh g = generate(kind, p);
  l.name = (requested == "dented" ? "dented-" : "") + kind + ".ply";
  l.data.V = g.V;
  l.data.F = g.F;
  return l;
}

std::shared_ptr<const EditorImage> prepare_editor_image(Volume volume, const std::string& name) {
  auto image = std::make_shared<EditorImage>();
  image->volume = std::make_shared<const Volume>(std::move(volume));
  image->edges = edge_map(*image->volume);
  const auto q = volume_quantiles(*image->volume, {0.0, 0.01, 0.99, 1.0});
  image->min = q[0];
  image->low = q[1];
  image->high = q[2] > q[1] ? q[2] : q[1] + 1;
  image->max = std::max(q[3], image->high);
  image->name = name;
  return image;
}

std::shared_ptr<const EditorImage> load_editor_image(const std::string& path, const std::string& series) {
#ifdef MESHPDE_HAVE_MEDICAL
  VolumeReadOptions options;
  options.series = series;
  return prepare_editor_image(read_volume(path, options), fs::path(path).filename().string());
#else
  (void)series;
  throw InputError(fmt::format("{}: --image needs meshpde built with meshpde::medical", path));
#endif
}

#ifdef MESHPDE_HAVE_MEDICAL
struct EditorSegmentation {
  Segmentation segmentation;
  Segment segment;
  std::string input, output;
};

std::shared_ptr<const EditorSegmentation> load_editor_segmentation(const std::string& path, const std::string& segment,
                                                                   bool overwrite) {
  auto s = std::make_shared<EditorSegmentation>();
  s->segmentation = read_segmentation(path);
  s->segment = find_segment(s->segmentation, segment);
  s->input = path;
  if (overwrite) {
    s->output = path;
  } else {
    // NAME-corrected with the input's whole extension (.seg.nrrd, .nii.gz kept), beside it;
    // a header with a detached data file is written with its data attached.
    const fs::path p(path);
    const std::string file = p.filename().string(), lower = lower_name(file);
    std::string ext;
    for (const char* e : {".seg.nrrd", ".nii.gz", ".nrrd", ".nii", ".mha", ".nhdr", ".mhd"})
      if (lower.ends_with(e)) {
        ext = e;
        break;
      }
    const std::string stem = file.substr(0, file.size() - ext.size());
    const std::string out_ext = ext == ".nhdr" ? ".nrrd" : ext == ".mhd" ? ".mha" : file.substr(stem.size());
    s->output = (p.parent_path() / (stem + "-corrected" + out_ext)).string();
  }
  return s;
}

Loaded segmentation_surface(const EditorSegmentation& s) {
  Loaded l;
  l.data = extract_surface(s.segmentation, s.segment);
  l.name = fs::path(s.input).stem().stem().string() + "-" + s.segment.name + ".vtp";
  l.from_segmentation = true;
  return l;
}
#else
struct EditorSegmentation {};
std::shared_ptr<const EditorSegmentation> load_editor_segmentation(const std::string& path, const std::string&, bool) {
  throw InputError(fmt::format("{}: segmentations need meshpde built with meshpde::medical", path));
}
Loaded segmentation_surface(const EditorSegmentation&) {
  throw InputError("segmentations need meshpde built with meshpde::medical");
}
#endif

bool is_volume_upload(const std::string& name) {
  return is_volume_path(fs::path(name).filename()) || lower_name(name).ends_with(".zip");
}

EditorPage::EditorPage(PageSink sink, std::shared_ptr<const EditorImage> image, Space space, LaplacianKind laplacian,
                       std::shared_ptr<const EditorSegmentation> segmentation, LengthUnit upload_units)
    : sink_(std::move(sink)),
      image_(std::move(image)),
      space_(space),
      laplacian_(laplacian),
      segmentation_(std::move(segmentation)),
      upload_units_(upload_units) {}

// Names in messages come from the user's files (field and file names) and need not be
// UTF-8; they are sent with U+FFFD in place of the bad bytes rather than thrown on.
void EditorPage::send_json(const nlohmann::json& j) {
  sink_.text(j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
}
void EditorPage::send_binary(std::string bytes) {
  sink_.binary(std::move(bytes));
}

void EditorPage::load(Loaded l) {
  // The session works in millimetres (the image's unit and the unit of every radius
  // and displacement typed); save() scales back.
  MeshData mm = l.data;
  mm.V *= millimetres_per(l.units);
  auto session = std::make_unique<EditorSession>(mm, image_ ? image_->edges : nullptr, space_, laplacian_);
  open(std::move(l), std::move(session), nullptr);
}

void EditorPage::open(Loaded l, std::unique_ptr<EditorSession> session, const nlohmann::json& page) {
  session_ = std::move(session);
  source_ = std::move(l);
  tissue_ = CorrectionParams{};
  intersections_ = session_->self_intersections();
  const Mesh& m = session_->mesh();
  nlohmann::json segmentation = nullptr;
#ifdef MESHPDE_HAVE_MEDICAL
  if (segmentation_ && source_.from_segmentation)
    segmentation = {{"input", fs::path(segmentation_->input).filename().string()},
                    {"segment", segmentation_->segment.name},
                    {"output", fs::path(segmentation_->output).filename().string()}};
#endif
  // Checked in the unit the mesh came in, so that the advice names the right option.
  const std::string units =
      source_.units == LengthUnit::Millimetre
          ? units_warning(m, LengthUnit::Millimetre, source_.name, "meshpde serve --units ")
          : units_warning(Mesh(source_.data.V, source_.data.F), source_.units, source_.name, "meshpde serve --units ");
  send_json({{"type", "mesh"},
             {"name", source_.name},
             {"vertices", m.num_vertices()},
             {"faces", m.num_faces()},
             {"mean_edge", session_->mean_edge_length()},
             {"has_image", session_->has_image()},
             {"image", image_json()},
             {"segmentation", segmentation},
             {"held_vertices", session_->held_vertices().size()},
             {"units", to_string(source_.units)},
             {"space", to_string(space_)},  // the patient frame of the coordinates: the page's standard views
             {"units_warning", units.empty() ? nlohmann::json() : nlohmann::json(units)},
             {"page", page},  // a reopened session's page settings (null otherwise)
             {"history_step", session_->history_step()},
             {"fields", [&] {
                std::vector<std::string> names;
                for (const auto& [k, v] : source_.data.vertex_scalars) names.push_back(k);
                return names;
              }()}});
  std::string b = "MESH";
  put<std::uint32_t>(b, static_cast<std::uint32_t>(m.num_vertices()));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(m.num_faces()));
  for (int i = 0; i < m.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(m.positions()(i, k)));
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) put<std::uint32_t>(b, static_cast<std::uint32_t>(m.triangles()(f, k)));
  send_binary(b);
  sent_ = m.positions();
  sent_vectors_.resize(0, 3);
  sent_field_.resize(0);
  sent_field_name_.clear();
}

void EditorPage::upload_image(const std::string& bytes, const std::string& name) {
#ifdef MESHPDE_HAVE_MEDICAL
  const std::string base = fs::path(name).filename().string(), lower = lower_name(name);
  if (lower.ends_with(".mhd") || lower.ends_with(".nhdr"))
    throw InputError(fmt::format(
        "{}: its voxels are in another file; upload one file: .mha, .nii, .nii.gz or .nrrd, or a DICOM series as .zip",
        base));
  // The readers take a path: the bytes go to a private temporary file, removed at once.
  const TemporaryPath temporary("meshpde-upload", lower.ends_with(".nii.gz") ? ".nii.gz" : lower_ext(base));
  const fs::path& tmp = temporary.path();
  Volume v;
  try {
    if (lower.ends_with(".zip")) {
      v = read_dicom_zip(bytes, base, "", kMaxUploadedVoxels, 4 * kMaxUploadedVoxels);
    } else {
      write_file_atomically(tmp, bytes);
      v = read_volume(tmp, kMaxUploadedVoxels);
    }
  } catch (const InputError& e) {
    // Name the upload, not the temporary file.
    std::string what = e.what();
    for (std::size_t at; (at = what.find(tmp.string())) != std::string::npos;)
      what.replace(at, tmp.string().size(), base);
    throw InputError(what);
  }
  v.name = base;
  image_ = prepare_editor_image(std::move(v), base);
  if (session_) session_->set_image_edges(image_->edges);
  send_json({{"type", "image"}, {"image", image_json()}, {"has_image", true}});
#else
  (void)bytes;
  throw InputError(fmt::format("{}: volumes need meshpde built with meshpde::medical", name));
#endif
}

int EditorPage::upload(const std::string& bytes, const std::string& name) {
  if (is_session_file(name)) return open_session(bytes, name);
  Loaded l = parse_mesh_bytes(bytes, name);
  l.units = upload_units_;
  const Mesh check(l.data.V, l.data.F);  // validates before the page's mesh is replaced
  load(std::move(l));
  return session_->mesh().num_vertices();
}

std::pair<std::string, std::string> EditorPage::save(const SaveOptions& options) const {
  if (!session_) throw InputError("no mesh loaded");
  const fs::path n(source_.name);
  std::string ext = n.extension().string();
  if (!options.format.empty()) {
    static const std::vector<std::string> kFormats = {"vtp", "vtk", "stl", "ply", "obj", "off"};
    if (std::find(kFormats.begin(), kFormats.end(), options.format) == kFormats.end())
      throw InputError(
          fmt::format("cannot save as '{}': the editor saves .vtp .vtk .stl .ply .obj .off", options.format));
    ext = "." + options.format;
  }
  const std::string name = n.stem().string() + "-edited" + ext;
  MeshData d = session_->snapshot();
  const double per_unit = millimetres_per(source_.units);
  d.V /= per_unit;  // back in the unit it came in
  const Positions D = (session_->mesh().positions() - session_->original_positions()) / per_unit;
  if (options.displacement) {
    for (int c = 0; c < 3; ++c) {
      const std::string key = std::string("displacement_") + "xyz"[c];
      d.vertex_scalars[key] = D.col(c);
      d.scalar_types[key] = "Float64";
    }
  }
  // Normals read with the file are stale once vertices moved: recomputed on the
  // surface saved (mesh_io.h, refresh_normal_fields).
  if (D.size() > 0 && D.cwiseAbs().maxCoeff() > 0) refresh_normal_fields(d);
  // The frame the page worked in (--space, else the file's tag, else LPS).
  d.space = to_string(space_);
  return {mesh_bytes(d, name), name};
}

// A session file: a zip archive of session.json (what is where, the frame, the page's
// settings), mesh.vtp (the mesh as it was opened, in its own unit, every array kept),
// history.bin, tissue.bin and image.mha (the volume as read, when the page has one).
std::pair<std::string, std::string> EditorPage::save_session(const std::string& page) const {
#ifdef MESHPDE_HAVE_MEDICAL
  if (!session_) throw InputError("no mesh loaded");
  const auto settings = nlohmann::json::parse(page.empty() ? std::string("{}") : page, nullptr, false);
  if (settings.is_discarded() || !settings.is_object())
    throw InputError("session: the page's settings are not a JSON object");
  const bool tissue = tissue_.stiffness.size() || tissue_.tissue.mass_field.size() ||
                      tissue_.tissue.elasticity_field.size() || tissue_.tissue.viscosity_field.size();
  nlohmann::json j = {
      {"format", "meshpde-session"},
      {"version", 1},
      {"mesh", {{"file", "mesh.vtp"}, {"name", source_.name}, {"units", to_string(source_.units)}}},
      {"space", to_string(space_)},
      {"history",
       {{"file", "history.bin"}, {"steps", session_->history().size()}, {"current", session_->history_step()}}},
      {"tissue", tissue ? nlohmann::json{{"file", "tissue.bin"}} : nlohmann::json()},
      {"image", image_ ? nlohmann::json{{"file", "image.mha"}, {"name", image_->name}} : nlohmann::json()},
      {"page", settings}};
  std::vector<std::pair<std::string, std::string>> entries;
  entries.emplace_back("session.json", j.dump(1));
  entries.emplace_back("mesh.vtp", write_vtk_mesh_to_memory(source_.data, "vtp"));
  entries.emplace_back("history.bin", encode_history(session_->history(), session_->history_step()));
  if (tissue) entries.emplace_back("tissue.bin", encode_tissue(tissue_));
  if (image_) entries.emplace_back("image.mha", write_metaimage_to_memory(*image_->volume));
  return {write_zip(entries), fs::path(source_.name).stem().string() + "-session.meshpde"};
#else
  (void)page;
  throw InputError("session files need meshpde built with meshpde::medical");
#endif
}

int EditorPage::open_session(const std::string& bytes, const std::string& name) {
#ifdef MESHPDE_HAVE_MEDICAL
  const std::string base = fs::path(name).filename().string();
  // The image as float voxels, the mesh and the history: bounded like an upload.
  const auto entries = read_zip_entries(bytes, base, 4 * kMaxUploadedVoxels + (std::size_t{1} << 30));
  const auto entry = [&](const std::string& e) -> const std::string& {
    const auto it = entries.find(e);
    if (it == entries.end()) throw InputError(fmt::format("{}: the session has no {}", base, e));
    return it->second;
  };
  const auto j = nlohmann::json::parse(entry("session.json"), nullptr, false);
  if (j.is_discarded() || !j.is_object() || j.value("format", std::string()) != "meshpde-session")
    throw InputError(
        fmt::format("{}: not a meshpde session (session.json names no \"format\": \"meshpde-session\")", base));
  if (j.value("version", 0) != 1)
    throw InputError(
        fmt::format("{}: a session of version {}; this meshpde reads version 1", base, j.value("version", 0)));
  const auto text = [&](const nlohmann::json& o, const char* key) {
    if (!o.is_object() || !o.contains(key) || !o[key].is_string())
      throw InputError(fmt::format("{}: session.json has no \"{}\"", base, key));
    return o[key].get<std::string>();
  };
  Loaded l;
  l.name = fs::path(text(j["mesh"], "name")).filename().string();
  l.units = parse_length_unit(text(j["mesh"], "units"));
  const std::string mesh_file = text(j["mesh"], "file");
  l.data = read_vtk_mesh_from_memory(entry(mesh_file), "vtp", base + ": " + mesh_file);
  const Space space = parse_space(text(j, "space"));
  auto [history, current] = decode_history(entry(text(j["history"], "file")), base + ": history", l.data.V.rows());
  CorrectionParams tissue;
  if (j.contains("tissue") && !j["tissue"].is_null())
    tissue = decode_tissue(entry(text(j["tissue"], "file")), base + ": tissue", l.data.V.rows());
  std::shared_ptr<const EditorImage> image = image_;
  if (j.contains("image") && !j["image"].is_null()) {
    const std::string image_file = text(j["image"], "file"), image_name = text(j["image"], "name");
    const TemporaryPath tmp("meshpde-session", ".mha");
    write_file_atomically(tmp.path(), entry(image_file));
    Volume v = read_volume(tmp.path(), kMaxUploadedVoxels);
    v.name = image_name;
    image = prepare_editor_image(std::move(v), image_name);
  }
  // The whole session is built before anything of the page changes: a damaged file
  // leaves the page as it was.
  MeshData mm = l.data;
  mm.V = history.front();  // the original positions in mm, exactly as saved
  auto session = std::make_unique<EditorSession>(mm, image ? image->edges : nullptr, space, laplacian_);
  session->restore_history(std::move(history), current);
  const nlohmann::json page = j.contains("page") && j["page"].is_object() ? j["page"] : nlohmann::json::object();
  image_ = image;
  space_ = space;
  open(std::move(l), std::move(session), page);
  tissue_ = std::move(tissue);
  return session_->mesh().num_vertices();
#else
  (void)bytes;
  throw InputError(fmt::format("{}: session files need meshpde built with meshpde::medical", name));
#endif
}

void EditorPage::handle(const std::string& payload, bool binary) {
  std::string type = "?";
  try {
    if (binary) throw InputError("expected a JSON text message");
    const auto j = nlohmann::json::parse(payload, nullptr, false);
    if (j.is_discarded() || !j.is_object()) throw InputError("malformed message: not a JSON object");
    if (!j.contains("type") || !j["type"].is_string()) throw InputError("malformed message: no \"type\"");
    type = j["type"].get<std::string>();
    if (!session_ && type != "generate") throw InputError("no mesh loaded");
    nlohmann::json reply = {{"type", "ok"}, {"request", type}};
    EditorSession& s = *session_;
    if (type == "generate") {
      const std::string kind = j.value("kind", std::string("dented"));
      load(generated(kind));
    } else if (type == "poke_begin") {
      s.poke_begin(vertex_of(j), number(j, "influence", 0));
    } else if (type == "poke_move") {
      s.poke_move(vec3(j, "offset"));
      return;  // many a second: no acknowledgement
    } else if (type == "poke_end") {
      s.poke_end();
    } else if (type == "brush") {
      const TissueProperty property = parse_tissue_property(j.value("property", std::string("stiffness")));
      s.end_poke();  // a new tool ends the probe's relaxation at once
      paint_tissue(s.mesh(), tissue_, property, Brush{vertex_of(j), number(j, "radius", 3), number(j, "value", 5)});
      reply["brushed"] = to_string(property);
    } else if (type == "drag_begin") {
      const double radius = number(j, "radius", 8);
      // At the picked surface point (the page sends it), else at the vertex; the
      // correction's default rule either way.
      reply["setup_ms"] = j.contains("point")
                              ? s.drag_begin(surface_point_of(s.mesh(), j), radius, tissue_.stiffness, tissue_.tissue)
                              : s.drag_begin(vertex_of(j), radius, tissue_.stiffness, tissue_.tissue);
      reply["region_vertices"] = s.drag_region_vertices();
      const std::vector<int>& moving = s.drag_moving_vertices();
      std::string b = "REG ";
      put<std::uint32_t>(b, static_cast<std::uint32_t>(moving.size()));
      for (int v : moving) put<std::uint32_t>(b, static_cast<std::uint32_t>(v));
      send_binary(std::move(b));
    } else if (type == "drag_move") {
      // Moves after a refused drag_begin (a region too large to preview) are dropped
      // quietly: the page already showed why, and releasing still corrects.
      const Eigen::Vector3d offset = vec3(j, "offset");
      if (s.dragging()) s.drag_move(offset);
      return;  // many a second: no acknowledgement
    } else if (type == "drag_end") {
      s.drag_end();
    } else if (type == "correct") {
      CorrectionParams p;
      p.radius = number(j, "radius", 8);
      // The rule of the drag preview (EditorSession::drag_begin, the correction's
      // default), so that the release equals what the page showed.
      if (j.contains("point"))
        p.handles = {CorrectionHandle(s.mesh(), surface_point_of(s.mesh(), j), vec3(j, "move"))};
      else
        p.handles = {{vertex_of(j), vec3(j, "move")}};
      if (!(p.radius > 0)) throw InputError("radius must be > 0");
      p.method = parse_correction_method(j.value("method", std::string("fem")));
      if (p.method == CorrectionMethod::Springs) {
        p.rings = rings_for_radius(s.mesh(), p.radius);
        p.radius = 0;
      }
      p.stiffness = tissue_.stiffness;
      p.tissue = tissue_.tissue;
      p.dynamic = j.value("dynamic", false) && p.method == CorrectionMethod::Fem;
      if (!j.value("image", true) || p.method == CorrectionMethod::Springs) p.image.weight = 0;
      const CorrectionResult r = s.correct(p);
      intersections_ = s.self_intersections();
      reply.update({{"moved_vertices", r.moved_vertices},
                    {"max_displacement", r.max_displacement},
                    {"region_vertices", r.region.size()},
                    {"new_self_intersections", r.new_self_intersections},
                    {"intersection_action", r.intersection_action},
                    {"applied_fraction", r.applied_fraction},
                    {"region_warning", r.region_warning},
                    {"time_ms", r.time_ms},
                    {"boundary", to_string(p.boundary)},
                    {"handle_radius", r.handle_radius}});
      if (s.image_pull().size() > 0) reply["image_pull_max"] = s.image_pull().maxCoeff();
      if (const auto& h = p.handles.front(); h.point) {
        nlohmann::json reading = nlohmann::json::array();  // where the handle's motion is read: [vertex, weight] pairs
        if (!r.handle_reading.empty())
          for (const auto& [v, w] : r.handle_reading.front()) reading.push_back({v, w});
        reply["handle_point"] = {{"triangle", h.point->face},
                                 {"barycentric", {h.point->bary.x(), h.point->bary.y(), h.point->bary.z()}},
                                 {"reading", reading}};
      }
    } else if (type == "colour") {
      s.show_correction_field(j.value("field", std::string("moved (mm)")));
    } else if (type == "undo" || type == "redo") {
      type == "undo" ? s.undo() : s.redo();
      intersections_ = s.self_intersections();
    } else if (type == "paint") {
      s.paint(vertex_of(j), number(j, "value", 1), number(j, "g1", 0), number(j, "g2", 1));
    } else if (type == "paint_vector") {
      s.paint_vector(vertex_of(j), vec3(j, "vector"), number(j, "g1", 0), number(j, "g2", 1));
    } else if (type == "clear_paint") {
      s.clear_paint();
    } else if (type == "source") {
      s.add_source(vertex_of(j));
    } else if (type == "clear_sources") {
      s.clear_sources();
    } else if (type == "play") {
      s.play(j.value("kind", std::string("heat")));
    } else if (type == "pause") {
      s.pause();
    } else if (type == "slice") {
      send_slice(j);
      return;  // the SLC frame is the answer
    } else if (type == "rim") {
      send_rim(j);
      return;  // the RIM frame is the answer
    } else if (type == "save_segmentation") {
      reply.update(save_segmentation());
    } else if (type == "ping") {
    } else {
      throw InputError(fmt::format("unknown request '{}'", type));
    }
    send_json(reply);
    send_stats(true);
  } catch (const Error& e) {
    // The session stays usable: a bad request changes nothing.
    send_json({{"type", "error"}, {"request", type}, {"message", e.what()}});
  } catch (const nlohmann::json::exception& e) {  // a field of the wrong JSON type
    send_json({{"type", "error"}, {"request", type}, {"message", std::string("malformed request: ") + e.what()}});
  } catch (const std::exception& e) {
    // Not a refusal in words but a bug: said so (the fuzz target editor_message looks
    // for it), and the page goes on.
    send_json({{"type", "error"}, {"request", type}, {"message", std::string("internal error: ") + e.what()}});
  }
}

// The edited surface back into a copy of the server's segmentation, written where it
// says (apps/segment_surface.h: only the voxels the edits swept change).
nlohmann::json EditorPage::save_segmentation() {
#ifdef MESHPDE_HAVE_MEDICAL
  if (!segmentation_) throw InputError("no segmentation: start meshpde serve with --segmentation FILE");
  if (!source_.from_segmentation)
    throw InputError(fmt::format("the page holds {}, not the segment of {}: open it again to save into it",
                                 source_.name, fs::path(segmentation_->input).filename().string()));
  const Mesh& m = session_->mesh();
  const Field moved = m.positions() - session_->original_positions();
  Segmentation copy = segmentation_->segmentation;
  const VoxelizeReport r = voxelize_into(copy, segmentation_->segment, m.positions(), m.triangles(), moved);
  write_segmentation(segmentation_->output, copy);
  return {{"path", segmentation_->output},   {"file", fs::path(segmentation_->output).filename().string()},
          {"added", r.change.added},         {"removed", r.change.removed},
          {"conflicts", r.change.conflicts}, {"moved_vertices", r.moved_vertices}};
#else
  throw InputError("segmentations need meshpde built with meshpde::medical");
#endif
}

// What the page needs to show the image: null without one.
nlohmann::json EditorPage::image_json() const {
  if (!image_) return nullptr;
  const Volume& v = *image_->volume;
  const auto [lo, hi] = volume_bounds(v, space_);
  return {{"name", image_->name},
          {"dims", v.dims},
          {"spacing", {v.spacing.x(), v.spacing.y(), v.spacing.z()}},
          {"space", to_string(space_)},
          {"bounds", {{lo.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), hi.z()}}},
          {"range", {image_->min, image_->max}},
          {"window", image_->high - image_->low},
          {"level", (image_->high + image_->low) / 2}};
}

// A slice of the image, as the page's sliders ask for it: the pixels after
// window/level, never the volume itself.
void EditorPage::send_slice(const nlohmann::json& j) {
  if (!image_) throw InputError("no image: start meshpde serve with --image VOLUME");
  SliceParams p;
  p.axis = parse_slice_axis(j.value("axis", std::string("axial")));
  p.position = number(j, "position", 0);
  p.window = number(j, "window", image_->high - image_->low);
  p.level = number(j, "level", (image_->high + image_->low) / 2);
  if (!(p.window > 0)) throw InputError("window must be > 0");
  const double seq = number(j, "seq", 0);
  const Slice s = slice_volume(*image_->volume, space_, p);
  std::string b = "SLC ";
  b.reserve(60 + s.pixels.size());
  put<std::uint32_t>(b, static_cast<std::uint32_t>(s.axis));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(s.width));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(s.height));
  put<std::uint32_t>(b, seq >= 0 && seq < 4294967296.0 ? static_cast<std::uint32_t>(seq) : 0u);
  put<float>(b, static_cast<float>(s.position));
  for (const Eigen::Vector3d* x : {&s.origin, &s.u, &s.v})
    for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>((*x)[k]));
  b.append(reinterpret_cast<const char*>(s.pixels.data()), s.pixels.size());
  send_binary(std::move(b));
}

// What a drag at the hovered point would touch: the region's rim and the handle's, as
// line segments on the surface (EditorSession::region_rim).
void EditorPage::send_rim(const nlohmann::json& j) {
  const double radius = number(j, "radius", 8);
  const double seq = number(j, "seq", 0);
  const RegionRim r = session_->region_rim(surface_point_of(session_->mesh(), j), radius);
  std::string b = "RIM ";
  b.reserve(28 + 24 * (r.rim.size() + r.handle.size()));
  put<std::uint32_t>(b, seq >= 0 && seq < 4294967296.0 ? static_cast<std::uint32_t>(seq) : 0u);
  put<std::uint32_t>(b, static_cast<std::uint32_t>(r.region_vertices));
  put<float>(b, static_cast<float>(radius));
  put<float>(b, static_cast<float>(r.handle_radius));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(r.rim.size()));
  put<std::uint32_t>(b, static_cast<std::uint32_t>(r.handle.size()));
  for (const auto* list : {&r.rim, &r.handle})
    for (const LevelSetSegment& s : *list)
      for (const Eigen::Vector3d* x : {&s.a, &s.b})
        for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>((*x)[k]));
  send_binary(std::move(b));
}

void EditorPage::send_stats(bool now) {
  const auto t = std::chrono::steady_clock::now();
  if (!now && t - last_stats_ < std::chrono::milliseconds(100)) return;
  last_stats_ = t;
  const EditorSession& s = *session_;
  const Eigen::Vector3d f = s.poke_force();
  send_json({{"type", "stats"},
             {"force", {f.x(), f.y(), f.z()}},
             {"contact", s.poke_contact()},
             {"poking", s.poking()},
             {"active", s.poking() || !s.playing() ? s.poke_active_vertices() : s.simulation_active_vertices()},
             {"p99_us", s.poke_p99_us()},
             {"misses", s.poke_misses()},
             {"intersections", intersections_},
             {"can_undo", s.can_undo()},
             {"can_redo", s.can_redo()},
             {"playing", s.playing()},
             {"solve_ms", s.last_solve_ms()},
             {"frame_ms", frame_ms_},
             {"info", s.last_solve_info()}});
}

// One frame for one page: the vertices that moved and the field if it changed.
void EditorPage::frame() {
  if (!session_) return;
  const auto t0 = std::chrono::steady_clock::now();
  EditorSession& s = *session_;
  if (s.playing()) s.advance(2);
  const Positions V = s.display_positions();
  const double tol = 1e-6 * s.mean_edge_length();
  std::vector<int> moved;
  if (sent_.rows() == V.rows())
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if ((V.row(i) - sent_.row(i)).cwiseAbs().maxCoeff() > tol) moved.push_back(static_cast<int>(i));
  if (!moved.empty()) {
    std::string b = "POS ";
    put<std::uint32_t>(b, static_cast<std::uint32_t>(moved.size()));
    for (int i : moved) put<std::uint32_t>(b, static_cast<std::uint32_t>(i));
    for (int i : moved) {
      for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(V(i, k)));
      sent_.row(i) = V.row(i);
    }
    send_binary(b);
  }
  const Eigen::VectorXd& field = s.field();
  if (field.size() == V.rows() &&
      (field.size() != sent_field_.size() || s.field_name() != sent_field_name_ || field != sent_field_)) {
    send_json({{"type", "field"}, {"name", s.field_name()}, {"min", field.minCoeff()}, {"max", field.maxCoeff()}});
    std::string b = "FLD ";
    put<std::uint32_t>(b, static_cast<std::uint32_t>(field.size()));
    for (Eigen::Index i = 0; i < field.size(); ++i) put<float>(b, static_cast<float>(field[i]));
    send_binary(b);
    sent_field_ = field;
    sent_field_name_ = s.field_name();
  } else if (field.size() == 0 && sent_field_.size() != 0) {
    send_json({{"type", "field"}, {"name", ""}});
    sent_field_.resize(0);
    sent_field_name_.clear();
  }
  // Vectors as arrows: at most about 600 of them, evenly spread over the vertex ids.
  const Eigen::MatrixX3d& vec = s.vectors();
  if (vec.rows() != sent_vectors_.rows() || (vec.rows() && vec != sent_vectors_)) {
    std::string b = "VEC ";
    const int n = static_cast<int>(vec.rows()), stride = std::max(1, n / 600);
    std::vector<int> ids;
    for (int i = 0; i < n; i += stride)
      if (vec.row(i).squaredNorm() > 0) ids.push_back(i);
    put<std::uint32_t>(b, static_cast<std::uint32_t>(ids.size()));
    for (int i : ids) put<std::uint32_t>(b, static_cast<std::uint32_t>(i));
    for (int i : ids)
      for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(vec(i, k)));
    send_binary(b);
    sent_vectors_ = vec;
  }
  frame_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  send_stats(false);
}

}  // namespace meshpde::editor
