#include "meshpde/io/file_formats.h"

#include <algorithm>
#include <deque>
#include <mutex>

#include "meshpde/io/mesh_io.h"

namespace meshpde {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

MeshFileFormat core_format(const char* name, const char* extension, MeshFormat format, bool keeps_vertex_fields) {
  MeshFileFormat f;
  f.name = name;
  f.extensions = {extension};
  f.read = [format](const std::string& bytes, const std::string&, const std::string& file) {
    return read_mesh_from_memory(bytes, format, file);
  };
  f.write = [format](const MeshData& data, const std::string&, const WriteOptions& options) {
    return write_mesh_to_memory(data, format, options);
  };
  f.keeps_vertex_fields = keeps_vertex_fields;
  return f;
}

// Registration happens before main() (the medical component's static registrar) and
// lookups after it; the lock covers a program that registers a format of its own later.
// A deque keeps the addresses find_* hand out valid while formats are added.
struct Registry {
  std::mutex mutex;
  std::deque<MeshFileFormat> meshes;
  std::deque<VolumeFileFormat> volumes;
  Registry() {
    meshes.push_back(core_format("Wavefront OBJ", ".obj", MeshFormat::Obj, false));
    meshes.push_back(core_format("OFF", ".off", MeshFormat::Off, false));
    meshes.push_back(core_format("PLY", ".ply", MeshFormat::Ply, true));
    meshes.push_back(core_format("STL", ".stl", MeshFormat::Stl, false));
  }
};

Registry& registry() {
  static Registry r;  // constructed on first use, so a registrar in another library may run first
  return r;
}

}  // namespace

void register_mesh_format(MeshFileFormat format) {
  for (auto& e : format.extensions) e = lower(e);
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  r.meshes.push_back(std::move(format));
}

void register_volume_format(VolumeFileFormat format) {
  for (auto& s : format.suffixes) s = lower(s);
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  r.volumes.push_back(std::move(format));
}

const MeshFileFormat* find_mesh_format(const std::filesystem::path& path) {
  const std::string ext = lower(path.extension().string());
  if (ext.empty()) return nullptr;
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  for (auto it = r.meshes.rbegin(); it != r.meshes.rend(); ++it)
    if (std::find(it->extensions.begin(), it->extensions.end(), ext) != it->extensions.end()) return &*it;
  return nullptr;
}

const VolumeFileFormat* find_volume_format(const std::filesystem::path& path) {
  const std::string name = lower(path.filename().string());
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  for (auto it = r.volumes.rbegin(); it != r.volumes.rend(); ++it)
    for (const auto& suffix : it->suffixes)
      if (name.ends_with(suffix)) return &*it;
  for (auto it = r.volumes.rbegin(); it != r.volumes.rend(); ++it)
    if (it->recognizes && it->recognizes(path)) return &*it;
  return nullptr;
}

namespace {

// "a b c": every entry of every format's `list`, once, in registration order.
template <class Formats, class List>
std::string joined(Formats& formats, List list) {
  std::vector<std::string> all;
  for (const auto& f : formats)
    for (const auto& e : f.*list)
      if (std::find(all.begin(), all.end(), e) == all.end()) all.push_back(e);
  std::string out;
  for (const auto& e : all) out += (out.empty() ? "" : " ") + e;
  return out;
}

}  // namespace

bool is_volume_path(const std::filesystem::path& path) {
  const std::string name = lower(path.filename().string());
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  for (const auto& f : r.volumes)
    for (const auto& suffix : f.suffixes)
      if (name.ends_with(suffix)) return true;
  return false;
}

std::string mesh_extensions() {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  return joined(r.meshes, &MeshFileFormat::extensions);
}

std::string volume_extensions() {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  return joined(r.volumes, &VolumeFileFormat::suffixes);
}

}  // namespace meshpde
