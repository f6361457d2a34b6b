// NRRD (.nrrd with its data attached, .nhdr with a detached data file), read by meshpde
// itself: Teem 1.11's nrrdLoad leaked memory on damaged headers, and VTK 9.1's reader
// ignores the space directions. The header is "field: value" lines after a NRRD000N
// magic, up to an empty line; then the data: raw, gzip, ascii or hex.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

std::string clip(const std::string& s) {
  return s.size() > 60 ? s.substr(0, 60) + "..." : s;
}

double number(const std::string& tok, const std::string& field, const std::string& name, bool nan_ok = false) {
  char* end = nullptr;
  const double x = std::strtod(tok.c_str(), &end);
  if (tok.empty() || *end != '\0' || (!std::isfinite(x) && !(nan_ok && std::isnan(x))))
    throw InputError(fmt::format("{}: {}: '{}' is not a number", name, field, clip(tok)));
  return x;
}

// "(x,y,z)" vectors of a space directions or origin line.
std::vector<Eigen::Vector3d> vectors(const std::string& value, const std::string& field, const std::string& name) {
  std::vector<Eigen::Vector3d> out;
  std::size_t pos = 0;
  while ((pos = value.find_first_not_of(" \t", pos)) != std::string::npos) {
    if (value.compare(pos, 4, "none") == 0)
      throw InputError(
          fmt::format("{}: {}: an axis without a direction ('none'): a 3D scalar image is needed", name, field));
    const auto close = value.find(')', pos);
    if (value[pos] != '(' || close == std::string::npos)
      throw InputError(fmt::format("{}: {}: '{}' is not a list of (x,y,z) vectors", name, field, clip(value)));
    std::stringstream ss(value.substr(pos + 1, close - pos - 1));
    std::string tok;
    std::vector<double> c;
    while (std::getline(ss, tok, ',')) c.push_back(number(trim(tok), field, name));
    if (c.size() != 3)
      throw InputError(fmt::format("{}: {}: a vector has {} components, not 3", name, field, c.size()));
    out.emplace_back(c[0], c[1], c[2]);
    pos = close + 1;
  }
  return out;
}

Element nrrd_type(const std::string& value, const std::string& name) {
  static const std::map<std::string, Element> types{{"signed char", Element::I8},
                                                    {"int8", Element::I8},
                                                    {"int8_t", Element::I8},
                                                    {"uchar", Element::U8},
                                                    {"unsigned char", Element::U8},
                                                    {"uint8", Element::U8},
                                                    {"uint8_t", Element::U8},
                                                    {"short", Element::I16},
                                                    {"short int", Element::I16},
                                                    {"signed short", Element::I16},
                                                    {"signed short int", Element::I16},
                                                    {"int16", Element::I16},
                                                    {"int16_t", Element::I16},
                                                    {"ushort", Element::U16},
                                                    {"unsigned short", Element::U16},
                                                    {"unsigned short int", Element::U16},
                                                    {"uint16", Element::U16},
                                                    {"uint16_t", Element::U16},
                                                    {"int", Element::I32},
                                                    {"signed int", Element::I32},
                                                    {"int32", Element::I32},
                                                    {"int32_t", Element::I32},
                                                    {"uint", Element::U32},
                                                    {"unsigned int", Element::U32},
                                                    {"uint32", Element::U32},
                                                    {"uint32_t", Element::U32},
                                                    {"longlong", Element::I64},
                                                    {"long long", Element::I64},
                                                    {"long long int", Element::I64},
                                                    {"signed long long", Element::I64},
                                                    {"signed long long int", Element::I64},
                                                    {"int64", Element::I64},
                                                    {"int64_t", Element::I64},
                                                    {"ulonglong", Element::U64},
                                                    {"unsigned long long", Element::U64},
                                                    {"unsigned long long int", Element::U64},
                                                    {"uint64", Element::U64},
                                                    {"uint64_t", Element::U64},
                                                    {"float", Element::F32},
                                                    {"double", Element::F64}};
  const auto it = types.find(lower(value));
  if (it == types.end())
    throw InputError(fmt::format("{}: type '{}' is not a scalar type meshpde reads", name, clip(value)));
  return it->second;
}

}  // namespace

NrrdImage read_nrrd_image(const std::filesystem::path& path, std::size_t max_voxels) {
  const std::string name = path.string();
  const std::string bytes = read_file_bytes(path);
  if (bytes.compare(0, 7, "NRRD000") != 0 || bytes.size() < 8 || bytes[7] < '1' || bytes[7] > '5')
    throw InputError(fmt::format("{}: not a NRRD file (it does not start with NRRD0001 to NRRD0005)", name));
  NrrdImage image;
  std::map<std::string, std::string>& h = image.fields;
  std::size_t pos = bytes.find('\n');
  image.lines.push_back(trim(bytes.substr(0, pos)));  // the magic
  pos = pos == std::string::npos ? bytes.size() : pos + 1;
  bool blank = false;
  while (pos < bytes.size()) {
    const std::size_t eol = bytes.find('\n', pos);
    std::string line = bytes.substr(pos, eol == std::string::npos ? std::string::npos : eol - pos);
    pos = eol == std::string::npos ? bytes.size() : eol + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string t = trim(line);
    if (t.empty()) {
      blank = true;
      break;
    }
    image.lines.push_back(line);
    if (t[0] == '#') continue;
    if (const auto kv = line.find(":="); kv != std::string::npos) {  // key/value pairs (3D Slicer's Segment fields)
      image.key_values.emplace_back(line.substr(0, kv), line.substr(kv + 2));
      continue;
    }
    const auto colon = line.find(": ");
    if (colon == std::string::npos)
      throw InputError(fmt::format("{}: header line '{}' is not 'field: value'", name, clip(t)));
    h[lower(trim(line.substr(0, colon)))] = trim(line.substr(colon + 2));
  }
  auto field = [&](const char* key) -> const std::string& {
    const auto it = h.find(key);
    if (it == h.end()) throw InputError(fmt::format("{}: the header has no '{}' field", name, key));
    return it->second;
  };
  // Three spatial axes, after one "list" axis of values per voxel when the image has
  // four (a 3D Slicer segmentation's layers: the list axis's space direction is none).
  const double dimension = number(field("dimension"), "dimension", name);
  if (dimension != 3 && dimension != 4)
    throw InputError(fmt::format("{}: has {} axes; a 3D image is needed", name, clip(field("dimension"))));
  const int axes_count = static_cast<int>(dimension);
  const Element type = nrrd_type(field("type"), name);
  image.type = type;
  std::array<long long, 3> dims{};
  long long components = 1;
  {
    std::istringstream ss(field("sizes"));
    std::string tok;
    int a = 0;
    while (ss >> tok) {
      if (a == axes_count) throw InputError(fmt::format("{}: sizes: more than {} values", name, axes_count));
      const double x = number(tok, "sizes", name);
      if (x != std::floor(x) || x < 1 || x > 1e9)
        throw InputError(fmt::format("{}: sizes: '{}' is not a positive whole number", name, clip(tok)));
      if (axes_count == 4 && a == 0)
        components = static_cast<long long>(x);
      else
        dims[a - (axes_count - 3)] = static_cast<long long>(x);
      ++a;
    }
    if (a != axes_count) throw InputError(fmt::format("{}: sizes: {} values for {} axes", name, a, axes_count));
  }
  if (axes_count == 4) {
    if (h.count("kinds")) {
      std::istringstream ks(lower(h.at("kinds")));
      std::string first;
      ks >> first;
      if (first == "domain" || first == "space")
        throw InputError(
            fmt::format("{}: a 4D image whose first axis is '{}' (only a leading list axis of values "
                        "per voxel is read)",
                        name, clip(first)));
    }
    if (components > 4096) throw InputError(fmt::format("{}: {} values per voxel", name, components));
  }
  image.components = static_cast<int>(components);
  const std::size_t voxels =
      checked_voxels({dims[0] * components, dims[1], dims[2]}, name, max_voxels ? max_voxels * components : 0) /
      static_cast<std::size_t>(components);
  const std::string encoding = lower(field("encoding"));
  const bool big = h.count("endian") && lower(h.at("endian")) == "big";
  if (element_size(type) > 1 && h.count("endian") && !big && lower(h.at("endian")) != "little")
    throw InputError(fmt::format("{}: endian '{}' is neither little nor big", name, clip(h.at("endian"))));

  // The data: after the blank line, or in one detached file (relative to the header).
  std::string detached;
  const std::string* data = &bytes;
  std::size_t offset = pos;
  if (h.count("data file") || h.count("datafile")) {
    const std::string file = h.count("data file") ? h.at("data file") : h.at("datafile");
    if (!is_single_data_file(file))
      throw InputError(fmt::format("{}: data file '{}': only one detached data file is read", name, clip(file)));
    detached = read_file_bytes(path.parent_path() / file);
    data = &detached;
    offset = 0;
  } else if (!blank) {
    throw InputError(fmt::format("{}: the header does not end with an empty line before the data", name));
  }
  // line skip, then byte skip (-1 for raw: the data are the file's last bytes).
  if (h.count("line skip") || h.count("lineskip")) {
    const double lines = number(h.count("line skip") ? h.at("line skip") : h.at("lineskip"), "line skip", name);
    if (lines < 0 || lines != std::floor(lines))
      throw InputError(fmt::format("{}: line skip {} is invalid", name, lines));
    for (double k = 0; k < lines && offset < data->size(); ++k) {
      const auto eol = data->find('\n', offset);
      offset = eol == std::string::npos ? data->size() : eol + 1;
    }
  }
  const VoxelLayout layout{
      {dims[0] * components, dims[1], dims[2]}, voxels * static_cast<std::size_t>(components), type, big};
  image.big_endian = big;
  image.encoding = encoding;
  if (h.count("byte skip") || h.count("byteskip")) {
    const double skip = number(h.count("byte skip") ? h.at("byte skip") : h.at("byteskip"), "byte skip", name);
    if (skip < -1 || skip != std::floor(skip)) throw InputError(fmt::format("{}: byte skip {} is invalid", name, skip));
    if (skip == -1) {
      if (encoding != "raw") throw InputError(fmt::format("{}: byte skip -1 needs raw encoding", name));
      offset = data->size() >= layout.bytes() ? data->size() - layout.bytes() : offset;
    } else {
      offset += static_cast<std::size_t>(std::min<double>(skip, static_cast<double>(data->size())));
    }
  }
  offset = std::min(offset, data->size());

  Volume& v = image.geometry;
  v.name = name;
  v.dims = {static_cast<int>(dims[0]), static_cast<int>(dims[1]), static_cast<int>(dims[2])};
  std::vector<float>& values = image.values;
  const std::size_t count = layout.voxels;
  if (encoding == "raw") {
    values = raw_voxels(*data, offset, layout, name);
  } else if (encoding == "gzip" || encoding == "gz") {
    Inflater inflater(*data, offset, name);
    values = inflated_voxels(inflater, 0, layout, name);
  } else if (encoding == "ascii" || encoding == "text" || encoding == "txt") {
    // At least one byte a value: a count the text cannot hold is refused before allocating.
    if (data->size() - offset < count)
      throw InputError(fmt::format("{}: {} bytes of text cannot hold {} values", name, data->size() - offset, count));
    values.resize(count);
    const char* p = data->data() + offset;
    const char* end = data->data() + data->size();
    for (std::size_t i = 0; i < count; ++i) {
      while (p < end && (std::isspace(static_cast<unsigned char>(*p)) || *p == ',')) ++p;
      const char* q = p;
      while (q < end && !std::isspace(static_cast<unsigned char>(*q)) && *q != ',') ++q;
      if (p == q) throw InputError(fmt::format("{}: the text data end after {} of {} values", name, i, count));
      values[i] = static_cast<float>(number(std::string(p, q), "data", name, true));
      p = q;
    }
  } else if (encoding == "hex") {
    std::string raw;
    raw.reserve(std::min(layout.bytes(), (data->size() - offset) / 2 + 1));
    int high = -1;
    for (std::size_t k = offset; k < data->size() && raw.size() < layout.bytes(); ++k) {
      const int c = static_cast<unsigned char>((*data)[k]);
      if (std::isspace(c)) continue;
      if (!std::isxdigit(c)) throw InputError(fmt::format("{}: hex data byte {} is not a hex digit", name, k));
      const int d = std::isdigit(c) ? c - '0' : std::tolower(c) - 'a' + 10;
      if (high < 0) {
        high = d;
      } else {
        raw += static_cast<char>(high * 16 + d);
        high = -1;
      }
    }
    if (raw.size() < layout.bytes())
      throw InputError(fmt::format("{}: {} hex bytes for {} bytes of voxels", name, raw.size(), layout.bytes()));
    convert_elements(raw.data(), count, type, big, 1, 0, values);
  } else {
    throw InputError(fmt::format("{}: encoding '{}' is not read (raw, gzip, ascii or hex)", name, clip(encoding)));
  }

  // Geometry: the space's directions and origin, in the file's space, turned into LPS.
  Eigen::Matrix3d L = Eigen::Matrix3d::Identity();  // the file's space -> LPS
  bool spatial = h.count("space dimension") && number(h.at("space dimension"), "space dimension", name) == 3;
  if (h.count("space")) {
    const std::string s = lower(h.at("space"));
    spatial = true;
    if (s == "right-anterior-superior" || s == "ras" || s == "scanner-xyz")
      L = Eigen::Vector3d(-1, -1, 1).asDiagonal();
    else if (s == "left-anterior-superior" || s == "las")
      L = Eigen::Vector3d(1, -1, 1).asDiagonal();
    else if (!(s == "left-posterior-superior" || s == "lps" || s == "3d-right-handed"))
      throw InputError(fmt::format("{}: unsupported NRRD space '{}'", name, clip(h.at("space"))));
  }
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  if (spatial && h.count("space directions")) {
    std::string directions = h.at("space directions");
    if (axes_count == 4) {  // the list axis has no direction: "none (x,y,z) (x,y,z) (x,y,z)"
      const auto first = directions.find_first_not_of(" \t");
      if (first == std::string::npos || directions.compare(first, 4, "none") != 0)
        throw InputError(fmt::format("{}: space directions: the list axis needs 'none'", name));
      directions = directions.substr(first + 4);
    }
    const auto d = vectors(directions, "space directions", name);
    if (d.size() != 3) throw InputError(fmt::format("{}: space directions: {} vectors for 3 axes", name, d.size()));
    for (int c = 0; c < 3; ++c) axes.col(c) = d[static_cast<std::size_t>(c)];
    if (h.count("space origin")) {
      const auto o = vectors(h.at("space origin"), "space origin", name);
      if (o.size() != 1) throw InputError(fmt::format("{}: space origin: {} vectors, not 1", name, o.size()));
      origin = o[0];
    }
  } else if (h.count("spacings")) {
    std::istringstream ss(h.at("spacings"));
    std::string tok;
    for (int c = 0; c < 3 && ss >> tok; ++c) {
      const double x = number(tok, "spacings", name, true);
      axes(c, c) = std::isfinite(x) ? x : 1.0;
    }
  }
  set_geometry_from_axes(v, L * axes, L * origin);
  if (components == 1) {
    v.values = values;
    v.validate();
  }
  return image;
}

Volume read_nrrd(const std::filesystem::path& path, std::size_t max_voxels) {
  NrrdImage image = read_nrrd_image(path, max_voxels);
  if (image.components != 1)
    throw InputError(
        fmt::format("{}: {} values per voxel; a scalar image is needed (a segmentation's layers are read "
                    "by read_segmentation)",
                    path.string(), image.components));
  return std::move(image.geometry);
}

}  // namespace meshpde::detail
