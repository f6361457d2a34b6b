#include "meshpde/io/mesh_io.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <random>
#include <sstream>

#include "io_detail.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {
namespace {

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace

MeshFormat format_from_path(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".off") return MeshFormat::Off;
  if (ext == ".ply") return MeshFormat::Ply;
  if (ext == ".stl") return MeshFormat::Stl;
  throw InputError(fmt::format("{}: unknown mesh format '{}' (supported: .obj .off .ply .stl)", path.string(), ext));
}

namespace {

// The registered format of a mesh file's name, or an InputError that says what the
// name is instead (a volume) and which extensions this build reads.
const MeshFileFormat& mesh_format_of(const std::filesystem::path& path) {
  if (const MeshFileFormat* f = find_mesh_format(path)) return *f;
  if (is_volume_path(path))
    throw InputError(fmt::format("{}: a volume, not a mesh (read_volume reads it; it guides a correction as its image)",
                                 path.string()));
  const std::string ext = lower_extension(path);
  const std::string known = mesh_extensions();
  if (ext == ".vtp" || ext == ".vtk")
    throw InputError(fmt::format("{}: {} meshes need meshpde built with meshpde::medical (this build reads {})",
                                 path.string(), ext, known));
  throw InputError(fmt::format("{}: unknown mesh format '{}' (supported: {})", path.string(), ext, known));
}

}  // namespace

MeshData read_mesh_from_memory(const std::string& bytes, const std::string& name) {
  const MeshFileFormat& f = mesh_format_of(name);
  const std::string ext = lower_extension(name);
  return f.read(bytes, ext, name);
}

std::string write_mesh_to_memory(const MeshData& data, const std::string& name, const WriteOptions& options) {
  const MeshFileFormat& f = mesh_format_of(name);
  const std::string ext = lower_extension(name);
  return f.write(data, ext, options);
}

MeshData read_mesh_from_memory(const std::string& bytes, MeshFormat format, const std::string& name) {
  MeshData d;
  switch (format) {
    case MeshFormat::Obj:
      d = detail::read_obj(bytes, name);
      break;
    case MeshFormat::Off:
      d = detail::read_off(bytes, name);
      break;
    case MeshFormat::Ply:
      d = detail::read_ply(bytes, name);
      break;
    case MeshFormat::Stl:
      d = detail::read_stl(bytes, name);
      break;
  }
  if (d.V.rows() == 0) throw InputError(fmt::format("{}: contains no vertices", name));
  detail::check_indices(name, d.F, static_cast<int>(d.V.rows()));
  return d;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", path.string()));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(fmt::format("{}: read error", path.string()));
  return ss.str();
}

MeshData read_mesh(const std::filesystem::path& path) {
  if (std::error_code ec; std::filesystem::is_directory(path, ec))
    throw InputError(fmt::format("{}: is a directory, not a mesh file", path.string()));
  mesh_format_of(path);  // an unknown name is refused before the file is read
  return read_mesh_from_memory(read_file(path), path.string());
}

std::string write_mesh_to_memory(const MeshData& data, MeshFormat format, const WriteOptions& options) {
  switch (format) {
    case MeshFormat::Obj:
      return detail::write_obj(data);
    case MeshFormat::Off:
      return detail::write_off(data);
    case MeshFormat::Ply:
      return detail::write_ply(data, options.binary);
    case MeshFormat::Stl:
      return detail::write_stl(data, options.binary);
  }
  return {};
}

std::vector<std::string> write_mesh(const std::filesystem::path& path, const MeshData& data,
                                    const WriteOptions& options) {
  const MeshFileFormat& format = mesh_format_of(path);
  std::vector<std::string> warnings;
  if (!data.vertex_scalars.empty() && !format.keeps_vertex_fields)
    warnings.push_back(fmt::format("{}: this format cannot store vertex fields; {} field(s) dropped (use .ply or .vtp)",
                                   path.string(), data.vertex_scalars.size()));
  if ((!data.point_arrays.empty() || !data.cell_arrays.empty()) && !format.keeps_data_arrays)
    warnings.push_back(fmt::format("{}: {} point and {} cell data array(s) dropped (only .vtp and .vtk keep them)",
                                   path.string(), data.point_arrays.size(), data.cell_arrays.size()));
  if ((!data.field_strings.empty() || !data.field_arrays.empty()) && !format.keeps_field_data)
    warnings.push_back(fmt::format("{}: {} field data array(s) dropped (only .vtp keeps them)", path.string(),
                                   data.field_strings.size() + data.field_arrays.size()));
  for (const auto& [key, field] : data.vertex_scalars)
    if (field.size() != data.V.rows())
      throw InputError(fmt::format("field '{}' has {} values for {} vertices", key, field.size(), data.V.rows()));
  write_file_atomically(path, write_mesh_to_memory(data, path.string(), options));
  return warnings;
}

Eigen::VectorXi face_labels(const MeshData& d, std::string* name) {
  for (const char* key : {"ModelFaceID", "CellEntityIds", "MaterialIds"}) {
    const auto it = d.cell_arrays.find(key);
    if (it == d.cell_arrays.end() || it->second.values.cols() != 1 || it->second.values.rows() != d.F.rows()) continue;
    const Eigen::VectorXd& v = it->second.values.col(0);
    if (!(v.array() == v.array().round()).all() || v.cwiseAbs().maxCoeff() > 2e9) continue;
    if (name) *name = key;
    return v.cast<int>();
  }
  return {};
}

std::vector<std::string> refresh_normal_fields(MeshData& d) {
  std::vector<std::string> refreshed;
  std::vector<std::string> bases;
  for (const auto& [key, values] : d.vertex_scalars) {
    if (key.size() < 3 || key.compare(key.size() - 2, 2, "_x") != 0) continue;
    const std::string base = key.substr(0, key.size() - 2);
    std::string lower = base;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    if (lower.find("normal") != std::string::npos && d.vertex_scalars.count(base + "_y") &&
        d.vertex_scalars.count(base + "_z"))
      bases.push_back(base);
  }
  // Cell normals (SimVascular writes them as cell data): each triangle's unit normal.
  for (auto& [name, array] : d.cell_arrays) {
    std::string lower = name;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    if (lower.find("normal") == std::string::npos || array.values.cols() != 3 || array.values.rows() != d.F.rows())
      continue;
    Eigen::MatrixXd N(d.F.rows(), 3);
    double agree = 0;
    for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
      const Eigen::Vector3d a = d.V.row(d.F(f, 0)), b = d.V.row(d.F(f, 1)), c = d.V.row(d.F(f, 2));
      const Eigen::Vector3d n = (b - a).cross(c - a);
      N.row(f) = (n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero()).transpose();
      agree += N.row(f).dot(array.values.row(f));
    }
    array.values = agree < 0 ? Eigen::MatrixXd(-N) : N;
    refreshed.push_back(name);
  }
  if (bases.empty()) return refreshed;
  const Eigen::MatrixX3d N = vertex_normals(Mesh(d.V, d.F));
  for (const std::string& base : bases) {
    const Eigen::VectorXd &x = d.vertex_scalars.at(base + "_x"), &y = d.vertex_scalars.at(base + "_y"),
                          &z = d.vertex_scalars.at(base + "_z");
    double agree = 0;
    for (Eigen::Index i = 0; i < N.rows(); ++i) agree += N(i, 0) * x[i] + N(i, 1) * y[i] + N(i, 2) * z[i];
    const double s = agree < 0 ? -1 : 1;
    d.vertex_scalars[base + "_x"] = s * N.col(0);
    d.vertex_scalars[base + "_y"] = s * N.col(1);
    d.vertex_scalars[base + "_z"] = s * N.col(2);
    refreshed.push_back(base);
  }
  return refreshed;
}

TemporaryPath::TemporaryPath(std::string_view prefix, std::string_view suffix) {
  static std::atomic<unsigned> serial{0};
  path_ = std::filesystem::temp_directory_path() / fmt::format("{}-{}-{}{}", prefix, ::getpid(), ++serial, suffix);
}

TemporaryPath::~TemporaryPath() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

void write_file_atomically(const std::filesystem::path& path, const std::string& contents) {
  namespace fs = std::filesystem;
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (std::error_code ec; fs::is_directory(path, ec))
    throw InputError(fmt::format("{}: is a directory, not a file to write", path.string()));
  std::random_device rd;
  const fs::path tmp = dir / fmt::format(".{}.tmp{:08x}", path.filename().string(), rd());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(fmt::format("{}: cannot write (directory missing or not writable?)", path.string()));
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw Error(fmt::format("{}: write failed (disk full?)", path.string()));
    }
  }
  std::error_code renamed;
  fs::rename(tmp, path, renamed);
  if (renamed) {
    std::error_code ignored;  // (the rename's error is the one to report)
    fs::remove(tmp, ignored);
    throw Error(fmt::format("{}: cannot replace the file: {}", path.string(), renamed.message()));
  }
}

}  // namespace meshpde
