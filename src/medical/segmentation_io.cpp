// Segmentations: 3D Slicer's .seg.nrrd and label maps, read through the volume readers
// (nrrd.cpp, nifti.cpp, metaimage.cpp) and written back keeping what they were.
#include "meshpde/io/segmentation_io.h"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

#include "meshpde/core/errors.h"
#include "meshpde/io/mesh_io.h"
#include "volume_formats.h"

namespace meshpde {

const char* to_string(SegmentationFormat format) {
  switch (format) {
    case SegmentationFormat::SlicerNrrd:
      return "seg.nrrd";
    case SegmentationFormat::Nrrd:
      return "nrrd";
    case SegmentationFormat::Nifti:
      return "nifti";
    case SegmentationFormat::MetaImage:
      return "metaimage";
  }
  return "nrrd";
}

namespace {

using detail::Element;

bool ends_with(const std::filesystem::path& path, const std::string& suffix) {
  return detail::lower(path.filename().string()).ends_with(suffix);
}

struct ElementName {
  Element element;
  const char* name;  // ours
  const char* nrrd;  // NRRD's type field
  const char* met;   // MetaImage's ElementType
  int nifti;         // NIfTI's datatype
};
constexpr ElementName kElements[] = {
    {Element::U8, "uint8", "unsigned char", "MET_UCHAR", 2},
    {Element::I8, "int8", "signed char", "MET_CHAR", 256},
    {Element::U16, "uint16", "unsigned short", "MET_USHORT", 512},
    {Element::I16, "int16", "short", "MET_SHORT", 4},
    {Element::U32, "uint32", "unsigned int", "MET_UINT", 768},
    {Element::I32, "int32", "int", "MET_INT", 8},
    {Element::U64, "uint64", "unsigned long long", "MET_ULONG_LONG", 1280},
    {Element::I64, "int64", "long long", "MET_LONG_LONG", 1024},
    {Element::F32, "float32", "float", "MET_FLOAT", 16},
    {Element::F64, "float64", "double", "MET_DOUBLE", 64},
};

const ElementName& element_info(Element e) {
  for (const auto& x : kElements)
    if (x.element == e) return x;
  return kElements[0];
}

const ElementName& element_named(const std::string& name) {
  for (const auto& x : kElements)
    if (name == x.name) return x;
  throw InputError(fmt::format("unknown voxel type '{}'", name));
}

double lowest(Element e) {
  switch (e) {
    case Element::U8:
    case Element::U16:
    case Element::U32:
    case Element::U64:
      return 0;
    case Element::I8:
      return -128;
    case Element::I16:
      return -32768;
    case Element::I32:
      return std::numeric_limits<std::int32_t>::min();
    default:
      return -std::numeric_limits<double>::infinity();
  }
}

double highest(Element e) {
  switch (e) {
    case Element::U8:
      return 255;
    case Element::I8:
      return 127;
    case Element::U16:
      return 65535;
    case Element::I16:
      return 32767;
    case Element::U32:
      return 4294967295.0;
    case Element::I32:
      return std::numeric_limits<std::int32_t>::max();
    default:
      return std::numeric_limits<double>::infinity();
  }
}

// The smallest unsigned (or signed, for negative labels) integer type holding the labels.
Element smallest_element(const std::vector<std::int32_t>& labels) {
  const auto [lo, hi] = std::minmax_element(labels.begin(), labels.end());
  const std::int32_t a = labels.empty() ? 0 : *lo, b = labels.empty() ? 0 : *hi;
  if (a >= 0) return b <= 255 ? Element::U8 : b <= 65535 ? Element::U16 : Element::I32;
  return a >= -32768 && b <= 32767 ? Element::I16 : Element::I32;
}

template <class T>
void put(std::string& out, std::size_t at, T value, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  std::memcpy(out.data() + at, b, sizeof(T));
}

// The labels as stored values of `e`: (label - intercept) / slope, which must be whole
// numbers within the type's range.
std::string encode(const std::vector<std::int32_t>& labels, Element e, bool big, double slope, double intercept,
                   const std::string& name) {
  const std::size_t size = detail::element_size(e);
  std::string out(labels.size() * size, '\0');
  for (std::size_t k = 0; k < labels.size(); ++k) {
    const double x = (labels[k] - intercept) / slope;
    const double r = std::round(x);
    if (std::abs(x - r) > 1e-6 || r < lowest(e) || r > highest(e))
      throw InputError(fmt::format("{}: label {} does not fit its voxel type {} (scaled by {} + {})", name, labels[k],
                                   element_info(e).name, slope, intercept));
    const std::size_t at = k * size;
    switch (e) {
      case Element::U8:
        put(out, at, static_cast<std::uint8_t>(r), big);
        break;
      case Element::I8:
        put(out, at, static_cast<std::int8_t>(r), big);
        break;
      case Element::U16:
        put(out, at, static_cast<std::uint16_t>(r), big);
        break;
      case Element::I16:
        put(out, at, static_cast<std::int16_t>(r), big);
        break;
      case Element::U32:
        put(out, at, static_cast<std::uint32_t>(r), big);
        break;
      case Element::I32:
        put(out, at, static_cast<std::int32_t>(r), big);
        break;
      case Element::U64:
        put(out, at, static_cast<std::uint64_t>(r), big);
        break;
      case Element::I64:
        put(out, at, static_cast<std::int64_t>(r), big);
        break;
      case Element::F32:
        put(out, at, static_cast<float>(r), big);
        break;
      case Element::F64:
        put(out, at, r, big);
        break;
    }
  }
  return out;
}

// zlib's deflate with a gzip header (NRRD's gzip encoding, .nii.gz) or a zlib header
// (MetaImage's CompressedData).
std::string deflate(const std::string& data, bool gzip) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error("cannot start zlib");
  std::string out(deflateBound(&z, static_cast<uLong>(data.size())) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (rc != Z_STREAM_END) throw Error("zlib could not compress the voxels");
  return out;
}

std::vector<std::int32_t> to_labels(const std::vector<float>& values, const std::string& name, int layers,
                                    const std::array<int, 3>& dims) {
  std::vector<std::int32_t> labels(values.size());
  for (std::size_t k = 0; k < values.size(); ++k) {
    const float x = values[k];
    if (!(x == std::floor(x)) || std::abs(x) > 2e9) {
      const std::size_t voxel = k / static_cast<std::size_t>(layers);
      const std::size_t i = voxel % static_cast<std::size_t>(dims[0]);
      const std::size_t j = voxel / static_cast<std::size_t>(dims[0]) % static_cast<std::size_t>(dims[1]);
      const std::size_t kk = voxel / static_cast<std::size_t>(dims[0]) / static_cast<std::size_t>(dims[1]);
      throw InputError(
          fmt::format("{}: not a label map: voxel ({}, {}, {}) holds {}, not a whole number", name, i, j, kk, x));
    }
    labels[k] = static_cast<std::int32_t>(x);
  }
  return labels;
}

// A segment for each non-zero label of a one-layer label map.
std::vector<Segment> label_table(const std::vector<std::int32_t>& labels) {
  std::set<std::int32_t> present(labels.begin(), labels.end());
  present.erase(0);
  std::vector<Segment> out;
  for (const std::int32_t l : present) {
    Segment s;
    s.index = static_cast<int>(out.size());
    s.id = fmt::format("label_{}", l);
    s.name = fmt::format("label {}", l);
    s.label = l;
    out.push_back(s);
  }
  return out;
}

std::vector<double> numbers_in(const std::string& text, const std::string& what, const std::string& name) {
  std::vector<double> v;
  std::istringstream ss(text);
  std::string tok;
  while (ss >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (*end != '\0' || !std::isfinite(x))
      throw InputError(fmt::format("{}: {}: '{}' is not a number", name, what, tok.substr(0, 40)));
    v.push_back(x);
  }
  return v;
}

// A key SegmentN_FIELD (N of 1 to 6 digits, FIELD letters, digits and underscores):
// its N and FIELD. (Hand-parsed: std::regex costs a compile per pattern and trips
// GCC 12's maybe-uninitialized warnings in the sanitizer build.)
bool segment_key(const std::string& key, int& index, std::string& field) {
  constexpr std::string_view prefix = "Segment";
  if (key.size() <= prefix.size() || key.compare(0, prefix.size(), prefix) != 0) return false;
  std::size_t i = prefix.size();
  const std::size_t digits = i;
  while (i < key.size() && std::isdigit(static_cast<unsigned char>(key[i]))) ++i;
  if (i == digits || i - digits > 6 || i >= key.size() || key[i] != '_' || i + 1 == key.size()) return false;
  for (std::size_t j = i + 1; j < key.size(); ++j)
    if (!std::isalnum(static_cast<unsigned char>(key[j])) && key[j] != '_') return false;
  index = std::stoi(key.substr(digits, i - digits));
  field = key.substr(i + 1);
  return true;
}

// The SegmentN_* key/value pairs of a .seg.nrrd header: the segment table.
std::vector<Segment> slicer_table(const std::vector<std::pair<std::string, std::string>>& key_values, int layers,
                                  const std::string& name) {
  std::map<int, std::map<std::string, std::string>> by_index;
  for (const auto& [key, value] : key_values) {
    int index = 0;
    std::string field;
    if (segment_key(key, index, field)) by_index[index][field] = value;
  }
  std::vector<Segment> out;
  for (const auto& entry : by_index) {
    const int n = entry.first;  // a plain variable: lambdas below capture it
    const auto& f = entry.second;
    Segment s;
    s.index = n;
    s.id = f.count("ID") ? f.at("ID") : "";
    s.name = f.count("Name") ? f.at("Name") : (s.id.empty() ? fmt::format("Segment_{}", n) : s.id);
    auto integer = [&](const char* key, int fallback) {
      if (!f.count(key)) return fallback;
      const auto v = numbers_in(f.at(key), fmt::format("Segment{}_{}", n, key), name);
      if (v.size() != 1 || v[0] != std::floor(v[0]) || std::abs(v[0]) > 2e9)
        throw InputError(fmt::format("{}: Segment{}_{} is '{}', not a whole number", name, n, key, f.at(key)));
      return static_cast<int>(v[0]);
    };
    // A file without Layer holds each segment in a layer of its own (3D Slicer's reading).
    s.layer = integer("Layer", layers == 1 ? 0 : n);
    s.label = integer("LabelValue", 1);
    if (s.layer < 0 || s.layer >= layers)
      throw InputError(fmt::format("{}: segment {} ('{}') is in layer {}, but the file has {} layer{}", name, n, s.name,
                                   s.layer, layers, layers == 1 ? "" : "s"));
    const char* color_key = f.count("Color") ? "Color" : f.count("DefaultColor") ? "DefaultColor" : nullptr;
    if (color_key) {
      const auto c = numbers_in(f.at(color_key), fmt::format("Segment{}_{}", n, color_key), name);
      if (c.size() == 3) {
        s.color = Eigen::Vector3d(c[0], c[1], c[2]);
        s.has_color = true;
      }
    }
    out.push_back(s);
  }
  return out;
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream ss(text);
  std::string line;
  while (std::getline(ss, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  return lines;
}

}  // namespace

bool is_slicer_segmentation_path(const std::filesystem::path& path) {
  return ends_with(path, ".seg.nrrd");
}

bool holds_segments(const std::filesystem::path& path) {
  if (is_slicer_segmentation_path(path)) return true;
  if (!ends_with(path, ".nrrd") && !ends_with(path, ".nhdr")) return false;
  std::ifstream in(path, std::ios::binary);
  std::string head(1 << 16, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  const auto end = head.find("\n\n");
  std::istringstream lines(head.substr(0, end));
  int index = 0;
  std::string line, field;
  while (std::getline(lines, line))
    if (const auto kv = line.find(":="); kv != std::string::npos && segment_key(line.substr(0, kv), index, field))
      return true;
  return false;
}

Segmentation read_segmentation(const std::filesystem::path& path) {
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("{}: no such file", name));
  Segmentation seg;
  seg.name = name;
  if (ends_with(path, ".nrrd") || ends_with(path, ".nhdr")) {
    detail::NrrdImage image = detail::read_nrrd_image(path, 0);
    seg.geometry = std::move(image.geometry);
    seg.geometry.values.clear();
    seg.layers = image.components;
    seg.labels = to_labels(image.values, name, seg.layers, seg.geometry.dims);
    seg.segments = slicer_table(image.key_values, seg.layers, name);
    const bool slicer = !seg.segments.empty() || is_slicer_segmentation_path(path);
    seg.format = slicer ? SegmentationFormat::SlicerNrrd : SegmentationFormat::Nrrd;
    if (seg.segments.empty()) {
      if (seg.layers != 1)
        throw InputError(
            fmt::format("{}: {} layers but no SegmentN_ fields that say what they hold", name, seg.layers));
      seg.segments = label_table(seg.labels);
    }
    seg.source.header_lines = image.lines;
    seg.source.element = element_info(image.type).name;
    seg.source.compressed = image.encoding == "gzip" || image.encoding == "gz";
    return seg;
  }
  detail::StoredVoxels stored;
  Volume v;
  if (ends_with(path, ".nii") || ends_with(path, ".nii.gz")) {
    v = detail::read_nifti(path, 0, &stored);
    seg.format = SegmentationFormat::Nifti;
    seg.source.header_bytes = stored.header;
    seg.source.slope = stored.slope;
    seg.source.intercept = stored.intercept;
  } else if (ends_with(path, ".mha") || ends_with(path, ".mhd")) {
    v = detail::read_metaimage(path, 0, &stored);
    seg.format = SegmentationFormat::MetaImage;
    seg.source.header_lines = split_lines(stored.header);
  } else {
    throw InputError(
        fmt::format("{}: unknown segmentation format (supported: .seg.nrrd .nrrd .nhdr .nii .nii.gz .mha .mhd)", name));
  }
  seg.labels = to_labels(v.values, name, 1, v.dims);
  seg.geometry = std::move(v);
  seg.geometry.values.clear();
  seg.segments = label_table(seg.labels);
  seg.source.element = element_info(stored.type).name;
  seg.source.compressed = stored.compressed;
  return seg;
}

const Segment& find_segment(const Segmentation& seg, const std::string& choice) {
  auto list = [&] {
    std::string s;
    for (const auto& x : seg.segments)
      s += fmt::format("\n  '{}' (ID {}, label {}, layer {})", x.name, x.id.empty() ? "none" : x.id, x.label, x.layer);
    return s.empty() ? std::string(" none") : s;
  };
  if (choice.empty()) {
    if (seg.segments.size() == 1) return seg.segments.front();
    throw InputError(fmt::format("{} holds {} segments; choose one by name, ID or label value:{}", seg.name,
                                 seg.segments.size(), list()));
  }
  for (const auto& s : seg.segments)
    if (s.name == choice) return s;
  for (const auto& s : seg.segments)
    if (!s.id.empty() && s.id == choice) return s;
  for (const auto& s : seg.segments)
    if (std::to_string(s.label) == choice) {
      for (const auto& t : seg.segments)
        if (&t != &s && t.label == s.label)
          throw InputError(
              fmt::format("{}: label {} is held by several segments (in different layers); choose by name "
                          "or ID:{}",
                          seg.name, s.label, list()));
      return s;
    }
  throw InputError(fmt::format("{}: no segment '{}'; the segments are:{}", seg.name, choice, list()));
}

std::vector<std::uint8_t> segment_mask(const Segmentation& seg, const Segment& segment) {
  const std::size_t n = seg.num_voxels();
  std::vector<std::uint8_t> mask(n);
  for (std::size_t v = 0; v < n; ++v) mask[v] = seg.at(v, segment.layer) == segment.label;
  return mask;
}

SegmentChange set_segment(Segmentation& seg, const Segment& segment, const std::vector<std::uint8_t>& mask,
                          const std::vector<std::uint8_t>& decide) {
  const std::size_t n = seg.num_voxels();
  if (mask.size() != n || (!decide.empty() && decide.size() != n))
    throw InputError(fmt::format("{}: a mask of {} voxels for a grid of {}", seg.name, mask.size(), n));
  SegmentChange c;
  const auto L = static_cast<std::size_t>(seg.layers);
  for (std::size_t v = 0; v < n; ++v) {
    if (!decide.empty() && !decide[v]) continue;
    std::int32_t& x = seg.labels[v * L + static_cast<std::size_t>(segment.layer)];
    if (mask[v]) {
      if (x == segment.label) continue;
      if (x != 0) {
        ++c.conflicts;
        continue;
      }
      x = segment.label;
      ++c.added;
    } else if (x == segment.label) {
      x = 0;
      ++c.removed;
    }
  }
  return c;
}

namespace {

Eigen::Matrix3d axes_of(const Volume& g) {
  return g.direction * g.spacing.asDiagonal();
}

std::string vec(const Eigen::Vector3d& v) {
  return fmt::format("({:.17g},{:.17g},{:.17g})", v.x(), v.y(), v.z());
}

// The extent (i0 i1 j0 j1 k0 k1) of a layer's non-zero voxels, or nullopt when it has none.
std::optional<std::array<int, 6>> layer_extent(const Segmentation& seg, int layer) {
  std::array<int, 6> e{std::numeric_limits<int>::max(), -1, std::numeric_limits<int>::max(), -1,
                       std::numeric_limits<int>::max(), -1};
  const auto& d = seg.geometry.dims;
  std::size_t v = 0;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i, ++v)
        if (seg.at(v, layer) != 0) {
          e[0] = std::min(e[0], i), e[1] = std::max(e[1], i);
          e[2] = std::min(e[2], j), e[3] = std::max(e[3], j);
          e[4] = std::min(e[4], k), e[5] = std::max(e[5], k);
        }
  if (e[1] < 0) return std::nullopt;
  return e;
}

// The Extent a .seg.nrrd gives each segment after an edit: 3D Slicer reads a layer's
// voxels within the extent of its first segment, so every segment of a layer gets the
// union of the layer's old extents and the box of its non-zero voxels.
std::map<int, std::string> widened_extents(const Segmentation& seg,
                                           const std::vector<std::pair<std::string, std::string>>& key_values) {
  std::map<int, std::array<int, 6>> old;  // by segment index
  for (const auto& [key, value] : key_values) {
    int index = 0;
    std::string field;
    if (!segment_key(key, index, field) || field != "Extent") continue;
    std::istringstream ss(value);
    std::array<int, 6> e{};
    bool ok = true;
    for (int& x : e) ok = ok && static_cast<bool>(ss >> x);
    if (ok) old[index] = e;
  }
  std::map<int, std::string> out;
  for (int layer = 0; layer < seg.layers; ++layer) {
    std::optional<std::array<int, 6>> e = layer_extent(seg, layer);
    for (const auto& s : seg.segments)
      if (s.layer == layer && old.count(s.index) && old[s.index][0] <= old[s.index][1]) {
        const auto& o = old[s.index];
        if (!e) {
          e = o;
          continue;
        }
        for (int a = 0; a < 3; ++a) {
          (*e)[2 * a] = std::min((*e)[2 * a], o[2 * a]);
          (*e)[2 * a + 1] = std::max((*e)[2 * a + 1], o[2 * a + 1]);
        }
      }
    if (!e) continue;
    for (const auto& s : seg.segments)
      if (s.layer == layer)
        out[s.index] = fmt::format("{} {} {} {} {} {}", (*e)[0], (*e)[1], (*e)[2], (*e)[3], (*e)[4], (*e)[5]);
  }
  return out;
}

std::string nrrd_file(const Segmentation& seg, bool slicer_fields) {
  const auto& g = seg.geometry;
  const bool keep = !seg.source.header_lines.empty() &&
                    (seg.format == SegmentationFormat::SlicerNrrd || seg.format == SegmentationFormat::Nrrd);
  // The voxels go out gzip-compressed whatever the encoding was (raw, ascii and hex too).
  const Element type = keep ? element_named(seg.source.element).element : smallest_element(seg.labels);
  std::vector<std::string> lines;
  if (keep) {
    std::vector<std::pair<std::string, std::string>> key_values;
    for (const auto& line : seg.source.header_lines)
      if (const auto kv = line.find(":="); kv != std::string::npos && line[0] != '#')
        key_values.emplace_back(line.substr(0, kv), line.substr(kv + 2));
    const std::map<int, std::string> extents = widened_extents(seg, key_values);
    bool endian = false;
    for (const auto& line : seg.source.header_lines) {
      const auto colon = line.find(": ");
      const std::string field = colon == std::string::npos ? "" : detail::lower(detail::trim(line.substr(0, colon)));
      if (line.find(":=") != std::string::npos && line[0] != '#') {
        const std::string key = line.substr(0, line.find(":="));
        int index = 0;
        std::string name;
        if (segment_key(key, index, name) && name == "Extent" && extents.count(index)) {
          lines.push_back(key + ":=" + extents.at(index));
          continue;
        }
        lines.push_back(line);
        continue;
      }
      // Attached data now: no data file or skips; the voxels go out little-endian, compressed.
      if (field == "data file" || field == "datafile" || field == "line skip" || field == "lineskip" ||
          field == "byte skip" || field == "byteskip")
        continue;
      if (field == "encoding") {
        lines.push_back("encoding: gzip");
        continue;
      }
      if (field == "endian") {
        lines.push_back("endian: little");
        endian = true;
        continue;
      }
      lines.push_back(line);
    }
    if (!endian && detail::element_size(type) > 1) lines.insert(lines.begin() + 1, "endian: little");
  } else {
    const Eigen::Matrix3d A = axes_of(g);
    const bool layered = seg.layers > 1;
    lines = {"NRRD0004",
             "# written by meshpde",
             fmt::format("type: {}", element_info(type).nrrd),
             fmt::format("dimension: {}", layered ? 4 : 3),
             "space: left-posterior-superior",
             layered ? fmt::format("sizes: {} {} {} {}", seg.layers, g.dims[0], g.dims[1], g.dims[2])
                     : fmt::format("sizes: {} {} {}", g.dims[0], g.dims[1], g.dims[2]),
             fmt::format("space directions: {}{} {} {}", layered ? "none " : "", vec(A.col(0)), vec(A.col(1)),
                         vec(A.col(2))),
             layered ? "kinds: list domain domain domain" : "kinds: domain domain domain",
             "endian: little",
             "encoding: gzip",
             fmt::format("space origin: {}", vec(g.origin))};
    if (slicer_fields) {
      for (const auto& s : seg.segments) {
        const auto e = layer_extent(seg, s.layer);
        lines.push_back(
            fmt::format("Segment{}_Color:={:.6g} {:.6g} {:.6g}", s.index, s.color.x(), s.color.y(), s.color.z()));
        if (e)
          lines.push_back(fmt::format("Segment{}_Extent:={} {} {} {} {} {}", s.index, (*e)[0], (*e)[1], (*e)[2],
                                      (*e)[3], (*e)[4], (*e)[5]));
        lines.push_back(
            fmt::format("Segment{}_ID:={}", s.index, s.id.empty() ? fmt::format("Segment_{}", s.index) : s.id));
        lines.push_back(fmt::format("Segment{}_LabelValue:={}", s.index, s.label));
        lines.push_back(fmt::format("Segment{}_Layer:={}", s.index, s.layer));
        lines.push_back(fmt::format("Segment{}_Name:={}", s.index, s.name));
      }
      lines.push_back("Segmentation_MasterRepresentation:=Binary labelmap");
      lines.push_back("Segmentation_ContainedRepresentationNames:=Binary labelmap|");
      lines.push_back("Segmentation_ReferenceImageExtentOffset:=0 0 0");
    }
  }
  std::string header;
  for (const auto& l : lines) header += l + "\n";
  header += "\n";
  return header + deflate(encode(seg.labels, type, false, 1, 0, seg.name), true);
}

// A NIfTI-1 header made from the geometry: the sform (RAS) holds it exactly, in floats.
std::string nifti_header(const Segmentation& seg, Element type) {
  std::string h(352, '\0');
  const auto& g = seg.geometry;
  auto at = [&](std::size_t offset, auto value) { std::memcpy(h.data() + offset, &value, sizeof(value)); };
  at(0, std::int32_t{348});
  const std::int16_t dim[8] = {3,
                               static_cast<std::int16_t>(g.dims[0]),
                               static_cast<std::int16_t>(g.dims[1]),
                               static_cast<std::int16_t>(g.dims[2]),
                               1,
                               1,
                               1,
                               1};
  for (int i = 0; i < 8; ++i) at(40 + 2 * i, dim[i]);
  const int code = element_info(type).nifti;
  at(70, static_cast<std::int16_t>(code));
  at(72, static_cast<std::int16_t>(8 * detail::element_size(type)));
  const float pixdim[8] = {
      1, static_cast<float>(g.spacing[0]), static_cast<float>(g.spacing[1]), static_cast<float>(g.spacing[2]), 1, 1, 1,
      1};
  for (int i = 0; i < 8; ++i) at(76 + 4 * i, pixdim[i]);
  at(108, float{352});
  at(112, float{1});
  at(123, std::uint8_t{2});                                           // xyzt_units: millimetres
  at(252, std::int16_t{0});                                           // qform_code
  at(254, std::int16_t{1});                                           // sform_code: scanner
  const Eigen::Matrix3d L = Eigen::Vector3d(-1, -1, 1).asDiagonal();  // LPS -> RAS
  const Eigen::Matrix3d A = L * axes_of(g);
  const Eigen::Vector3d t = L * g.origin;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) at(280 + 16 * r + 4 * c, static_cast<float>(A(r, c)));
    at(280 + 16 * r + 12, static_cast<float>(t[r]));
  }
  std::memcpy(h.data() + 344, "n+1\0", 4);
  return h;
}

std::string nifti_file(const Segmentation& seg, bool gz) {
  const bool keep = seg.format == SegmentationFormat::Nifti && !seg.source.header_bytes.empty();
  std::string out;
  if (keep) {
    // The header as it was, and the voxels in its type, byte order and scaling.
    const std::string& h = seg.source.header_bytes;
    std::int32_t sizeof_hdr = 0;
    std::memcpy(&sizeof_hdr, h.data(), 4);
    const bool big = (sizeof_hdr != 348) != (std::endian::native == std::endian::big);
    out = h + encode(seg.labels, element_named(seg.source.element).element, big, seg.source.slope, seg.source.intercept,
                     seg.name);
  } else {
    const Element type = smallest_element(seg.labels);
    out = nifti_header(seg, type) + encode(seg.labels, type, false, 1, 0, seg.name);
  }
  return gz ? deflate(out, true) : out;
}

std::string metaimage_file(const Segmentation& seg) {
  const bool keep = seg.format == SegmentationFormat::MetaImage && !seg.source.header_lines.empty();
  const Element type = keep ? element_named(seg.source.element).element : smallest_element(seg.labels);
  const bool compressed = keep ? seg.source.compressed : true;
  const std::string raw = encode(seg.labels, type, false, 1, 0, seg.name);
  const std::string data = compressed ? deflate(raw, false) : raw;
  std::vector<std::string> lines;
  if (keep) {
    for (const auto& line : seg.source.header_lines) {
      const std::string key = detail::lower(detail::trim(line.substr(0, line.find('='))));
      if (key == "compresseddatasize" || key == "headersize" || key == "elementdatafile") continue;
      if (key == "binarydatabyteordermsb" || key == "elementbyteordermsb") {
        lines.push_back(detail::trim(line.substr(0, line.find('='))) + " = False");
        continue;
      }
      lines.push_back(line);
    }
  } else {
    const auto& g = seg.geometry;
    lines = {"ObjectType = Image",
             "NDims = 3",
             "BinaryData = True",
             "BinaryDataByteOrderMSB = False",
             fmt::format("CompressedData = {}", compressed ? "True" : "False"),
             fmt::format("TransformMatrix = {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}",
                         g.direction(0, 0), g.direction(1, 0), g.direction(2, 0), g.direction(0, 1), g.direction(1, 1),
                         g.direction(2, 1), g.direction(0, 2), g.direction(1, 2), g.direction(2, 2)),
             fmt::format("Offset = {:.17g} {:.17g} {:.17g}", g.origin.x(), g.origin.y(), g.origin.z()),
             "AnatomicalOrientation = RAI",
             fmt::format("ElementSpacing = {:.17g} {:.17g} {:.17g}", g.spacing.x(), g.spacing.y(), g.spacing.z()),
             fmt::format("DimSize = {} {} {}", g.dims[0], g.dims[1], g.dims[2]),
             fmt::format("ElementType = {}", element_info(type).met)};
  }
  if (compressed) lines.push_back(fmt::format("CompressedDataSize = {}", data.size()));
  lines.push_back("ElementDataFile = LOCAL");
  std::string header;
  for (const auto& l : lines) header += l + "\n";
  return header + data;
}

}  // namespace

void write_segmentation(const std::filesystem::path& path, const Segmentation& seg) {
  const std::string name = path.string();
  if (seg.labels.size() != seg.num_voxels() * static_cast<std::size_t>(seg.layers))
    throw InputError(
        fmt::format("{}: {} labels for {} voxels in {} layers", name, seg.labels.size(), seg.num_voxels(), seg.layers));
  std::string bytes;
  if (ends_with(path, ".nrrd")) {
    bytes = nrrd_file(seg, is_slicer_segmentation_path(path) || seg.format == SegmentationFormat::SlicerNrrd);
  } else if (seg.layers != 1 && !ends_with(path, ".nhdr") && !ends_with(path, ".mhd")) {
    throw InputError(
        fmt::format("{}: a segmentation of {} layers goes to a .seg.nrrd (this format holds one)", name, seg.layers));
  } else if (ends_with(path, ".nii")) {
    bytes = nifti_file(seg, false);
  } else if (ends_with(path, ".nii.gz")) {
    bytes = nifti_file(seg, true);
  } else if (ends_with(path, ".mha")) {
    bytes = metaimage_file(seg);
  } else {
    throw InputError(fmt::format("{}: segmentations are written as .seg.nrrd, .nrrd, .nii, .nii.gz or .mha", name));
  }
  write_file_atomically(path, bytes);
}

}  // namespace meshpde
