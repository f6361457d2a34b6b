// Volume reading: MetaImage and NIfTI-1 through VTK 9, NRRD through Teem. The
// MetaImage direction matrix comes from the header, which vtkMetaImageReader
// (VTK 9.1) reads but does not pass on.
#include <fmt/format.h>
#include <teem/nrrd.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkImageReader2.h>
#include <vtkMatrix4x4.h>
#include <vtkMetaImageReader.h>
#include <vtkNIFTIImageReader.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "vtk_capture.h"

namespace meshpde {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// A MetaImage header: "Key = Value" lines, keys lower-cased, up to ElementDataFile.
std::map<std::string, std::string> read_metaimage_header(const std::filesystem::path& path,
                                                         std::size_t max_bytes = 1 << 20) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", path.string()));
  std::map<std::string, std::string> h;
  std::string line;
  std::size_t read = 0;
  while (read < max_bytes && std::getline(in, line)) {
    read += line.size() + 1;
    const auto at = line.find('=');
    if (at == std::string::npos) continue;
    const std::string key = lower(trim(line.substr(0, at)));
    h[key] = trim(line.substr(at + 1));
    if (key == "elementdatafile") break;
  }
  return h;
}

std::vector<double> numbers(const std::string& text) {
  std::vector<double> v;
  std::string cleaned = text;
  for (char& c : cleaned)
    if (c == '(' || c == ')' || c == ',') c = ' ';
  std::istringstream ss(cleaned);
  std::string tok;
  while (ss >> tok) {
    try {
      v.push_back(std::stod(tok));
    } catch (...) {
      v.push_back(std::nan(""));
    }
  }
  return v;
}

// Copies VTK's scalars (component 0) into the volume, converting to float.
void take_values(vtkImageData* img, Volume& v, const std::string& name, double slope = 1, double inter = 0) {
  int* d = img->GetDimensions();
  v.dims = {d[0], d[1], d[2]};
  vtkDataArray* s = img->GetPointData()->GetScalars();
  if (!s) throw InputError(fmt::format("{}: holds no scalar values", name));
  if (s->GetNumberOfComponents() != 1)
    throw InputError(
        fmt::format("{}: has {} components per voxel; a scalar image is needed", name, s->GetNumberOfComponents()));
  const vtkIdType n = s->GetNumberOfTuples();
  if (static_cast<std::size_t>(n) != v.num_voxels())
    throw InputError(fmt::format("{}: {} values for {} voxels (truncated data?)", name, n, v.num_voxels()));
  v.values.resize(static_cast<std::size_t>(n));
  for (vtkIdType i = 0; i < n; ++i) {
    const double x = s->GetComponent(i, 0) * slope + inter;
    v.values[static_cast<std::size_t>(i)] = static_cast<float>(x);
  }
}

template <class Reader>
vtkSmartPointer<Reader> run_reader(const std::filesystem::path& path, detail::VtkErrorCapture& capture) {
  auto r = vtkSmartPointer<Reader>::New();
  capture.watch(r);
  r->SetFileName(path.string().c_str());
  r->Update();
  if (const auto e = capture.error(); !e.empty()) throw InputError(fmt::format("{}: {}", path.string(), e));
  return r;
}

Volume read_metaimage(const std::filesystem::path& path) {
  const auto h = read_metaimage_header(path);
  if (!h.count("ndims") || !h.count("dimsize"))
    throw InputError(fmt::format("{}: not a MetaImage header (NDims and DimSize missing)", path.string()));
  if (numbers(h.at("ndims")) != std::vector<double>{3})
    throw InputError(fmt::format("{}: NDims = {} (only 3D images are read)", path.string(), h.at("ndims")));
  detail::VtkErrorCapture capture;
  // MetaIO reports short or corrupt data on std::cerr and carries on; catch it.
  std::ostringstream metaio_messages;
  vtkSmartPointer<vtkMetaImageReader> r;
  {
    std::streambuf* previous = std::cerr.rdbuf(metaio_messages.rdbuf());
    try {
      r = run_reader<vtkMetaImageReader>(path, capture);
    } catch (...) {
      std::cerr.rdbuf(previous);
      throw;
    }
    std::cerr.rdbuf(previous);
  }
  if (std::string m = metaio_messages.str(); !m.empty()) {
    while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
    for (char& c : m)
      if (c == '\n') c = ' ';
    throw InputError(fmt::format("{}: {}", path.string(), m));
  }
  Volume v;
  v.name = path.string();
  take_values(r->GetOutput(), v, v.name);
  // Each quantity has synonyms in the MetaIO format; the first present wins.
  auto values = [&](std::initializer_list<const char*> keys, std::size_t count) -> std::optional<std::vector<double>> {
    for (const char* key : keys)
      if (h.count(key)) {
        auto x = numbers(h.at(key));
        if (x.size() != count) throw InputError(fmt::format("{}: {} needs {} values", v.name, key, count));
        return x;
      }
    return std::nullopt;
  };
  if (const auto s = values({"elementspacing", "elementsize"}, 3)) v.spacing = Eigen::Vector3d(s->data());
  if (const auto o = values({"offset", "position", "origin"}, 3)) v.origin = Eigen::Vector3d(o->data());
  if (const auto m = values({"transformmatrix", "rotation", "orientation"}, 9))
    // ITK writes the direction matrix column by column: the first three numbers
    // are the LPS direction of the i axis.
    v.direction = Eigen::Map<const Eigen::Matrix3d>(m->data());
  v.validate();
  return v;
}

// Splits A = L M S into spacing (column norms) and a unit-column direction.
void set_geometry_from_axes(Volume& v, const Eigen::Matrix3d& axes, const Eigen::Vector3d& origin_lps) {
  for (int c = 0; c < 3; ++c) {
    const double len = axes.col(c).norm();
    if (!(len > 0) || !std::isfinite(len))
      throw InputError(fmt::format("{}: the direction of axis {} has length {}", v.name, c, len));
    v.spacing[c] = len;
    v.direction.col(c) = axes.col(c) / len;
  }
  v.origin = origin_lps;
}

Volume read_nifti(const std::filesystem::path& path) {
  detail::VtkErrorCapture capture;
  auto r = run_reader<vtkNIFTIImageReader>(path, capture);
  Volume v;
  v.name = path.string();
  double slope = r->GetRescaleSlope(), inter = r->GetRescaleIntercept();
  if (slope == 0 || !std::isfinite(slope)) slope = 1, inter = 0;  // NIfTI: scl_slope 0 means unscaled
  if (!std::isfinite(inter)) inter = 0;
  vtkImageData* img = r->GetOutput();
  take_values(img, v, v.name, slope, inter);
  // VTK's data coordinates x = o + s o ijk map to NIfTI's RAS world by the sform
  // (preferred when present) or the qform; without either, world = x (NIfTI method 1).
  double o[3], s[3];
  img->GetOrigin(o);
  img->GetSpacing(s);
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  vtkMatrix4x4* m = r->GetSFormMatrix() ? r->GetSFormMatrix() : r->GetQFormMatrix();
  if (m)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) M(i, j) = m->GetElement(i, j);
  const Eigen::Matrix3d L = Eigen::Vector3d(-1, -1, 1).asDiagonal();  // RAS -> LPS
  const Eigen::Matrix3d axes = L * M.topLeftCorner<3, 3>() * Eigen::Vector3d(s[0], s[1], s[2]).asDiagonal();
  const Eigen::Vector3d origin =
      L * (M.topLeftCorner<3, 3>() * Eigen::Vector3d(o[0], o[1], o[2]) + M.topRightCorner<3, 1>());
  set_geometry_from_axes(v, axes, origin);
  v.validate();
  return v;
}

// NRRD through Teem, the format's reference library: VTK 9.1's vtkNrrdReader
// ignores the space directions and guesses that a first axis of 9 or fewer samples
// holds vector components.
Volume read_nrrd(const std::filesystem::path& path) {
  Nrrd* nrrd = nrrdNew();
  struct Free {
    Nrrd* n;
    ~Free() { nrrdNuke(n); }
  } guard{nrrd};
  if (nrrdLoad(nrrd, path.string().c_str(), nullptr)) {
    char* err = biffGetDone(NRRD);
    std::string message = err ? err : "unreadable";
    free(err);
    while (!message.empty() && message.back() == '\n') message.pop_back();
    for (char& c : message)
      if (c == '\n') c = ' ';
    throw InputError(fmt::format("{}: {}", path.string(), message));
  }
  Volume v;
  v.name = path.string();
  if (nrrd->dim != 3) throw InputError(fmt::format("{}: has {} axes; a 3D scalar image is needed", v.name, nrrd->dim));
  for (int a = 0; a < 3; ++a) v.dims[a] = static_cast<int>(nrrd->axis[a].size);
  const std::size_t n = v.num_voxels();
  v.values.resize(n);
  for (std::size_t i = 0; i < n; ++i) v.values[i] = static_cast<float>(nrrdDLookup[nrrd->type](nrrd->data, i));

  Eigen::Matrix3d L = Eigen::Matrix3d::Identity();  // the file's space -> LPS
  switch (nrrd->space) {
    case nrrdSpaceRightAnteriorSuperior:
    case nrrdSpaceScannerXYZ:
      L = Eigen::Vector3d(-1, -1, 1).asDiagonal();
      break;
    case nrrdSpaceLeftAnteriorSuperior:
      L = Eigen::Vector3d(1, -1, 1).asDiagonal();
      break;
    case nrrdSpaceUnknown:
    case nrrdSpaceLeftPosteriorSuperior:
    case nrrdSpace3DRightHanded:
      break;
    default:
      throw InputError(fmt::format("{}: unsupported NRRD space '{}'", v.name, airEnumStr(nrrdSpace, nrrd->space)));
  }
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  if (nrrd->spaceDim == 3) {
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) axes(r, c) = nrrd->axis[c].spaceDirection[r];
    for (int r = 0; r < 3; ++r) origin[r] = std::isfinite(nrrd->spaceOrigin[r]) ? nrrd->spaceOrigin[r] : 0.0;
  } else {
    for (int c = 0; c < 3; ++c) axes(c, c) = std::isfinite(nrrd->axis[c].spacing) ? nrrd->axis[c].spacing : 1.0;
  }
  set_geometry_from_axes(v, L * axes, L * origin);
  v.validate();
  return v;
}

}  // namespace

namespace {

bool name_ends(const std::filesystem::path& path, const std::string& suffix) {
  const std::string name = lower(path.filename().string());
  return name.size() >= suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

bool is_volume_path(const std::filesystem::path& path) {
  for (const char* e : {".mha", ".mhd", ".nii", ".nii.gz", ".nrrd", ".nhdr"})
    if (name_ends(path, e)) return true;
  return false;
}

Volume read_volume(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("{}: no such file", path.string()));
  auto ends = [&](const std::string& s) { return name_ends(path, s); };
  if (ends(".mha") || ends(".mhd")) return read_metaimage(path);
  if (ends(".nii") || ends(".nii.gz")) return read_nifti(path);
  if (ends(".nrrd") || ends(".nhdr")) return read_nrrd(path);
  throw InputError(
      fmt::format("{}: unknown volume format (supported: .mha .mhd .nii .nii.gz .nrrd .nhdr)", path.string()));
}

}  // namespace meshpde
