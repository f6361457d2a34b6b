// MetaImage (.mha with its data attached, .mhd with a detached data file), read by
// meshpde itself: VTK 9.1's MetaIO aborted on a damaged ElementDataFile key (glibc's
// buffer-overflow check) and leaked on damaged headers. The header is "Key = Value"
// lines up to ElementDataFile; then the data, raw or zlib-compressed.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <sstream>

#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

// Numbers of a header value; InputError naming the key for anything else.
std::vector<double> numbers(const std::string& value, const std::string& key, const std::string& name) {
  std::vector<double> v;
  std::istringstream ss(value);
  std::string tok;
  while (ss >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (*end != '\0' || !std::isfinite(x))
      throw InputError(
          fmt::format("{}: {} = {}: '{}' is not a number", name, key, value.substr(0, 80), tok.substr(0, 40)));
    v.push_back(x);
  }
  return v;
}

bool truth(const std::string& value) {
  const std::string v = lower(value);
  return v == "true" || v == "1";
}

Element element_type(const std::string& value, const std::string& name) {
  static const std::map<std::string, Element> types{
      {"met_uchar", Element::U8},      {"met_char", Element::I8},   {"met_ushort", Element::U16},
      {"met_short", Element::I16},     {"met_uint", Element::U32},  {"met_int", Element::I32},
      {"met_ulong", Element::U32},     {"met_long", Element::I32},  {"met_ulong_long", Element::U64},
      {"met_long_long", Element::I64}, {"met_float", Element::F32}, {"met_double", Element::F64}};
  const auto it = types.find(lower(value));
  if (it == types.end())
    throw InputError(fmt::format("{}: ElementType '{}' is not a scalar type meshpde reads", name, value.substr(0, 40)));
  return it->second;
}

}  // namespace

Volume read_metaimage(const std::filesystem::path& path, std::size_t max_voxels, StoredVoxels* stored) {
  const std::string name = path.string();
  const std::string bytes = read_file_bytes(path);
  // The header: lines up to and including ElementDataFile (the last key, by the format).
  std::map<std::string, std::string> h;
  std::size_t pos = 0;
  bool ended = false;
  while (pos < bytes.size() && pos < (1u << 20)) {
    const std::size_t eol = bytes.find('\n', pos);
    const std::string line = bytes.substr(pos, eol == std::string::npos ? std::string::npos : eol - pos);
    pos = eol == std::string::npos ? bytes.size() : eol + 1;
    const auto at = line.find('=');
    if (at == std::string::npos) continue;
    const std::string key = lower(trim(line.substr(0, at)));
    h[key] = trim(line.substr(at + 1));
    if (key == "elementdatafile") {
      ended = true;
      break;
    }
  }
  if (!h.count("ndims") || !h.count("dimsize"))
    throw InputError(fmt::format("{}: not a MetaImage header (NDims and DimSize missing)", name));
  if (!ended) throw InputError(fmt::format("{}: the header has no ElementDataFile line", name));
  if (numbers(h.at("ndims"), "NDims", name) != std::vector<double>{3})
    throw InputError(fmt::format("{}: NDims = {} (only 3D images are read)", name, h.at("ndims").substr(0, 40)));
  const auto dims_d = numbers(h.at("dimsize"), "DimSize", name);
  if (dims_d.size() != 3) throw InputError(fmt::format("{}: DimSize needs 3 values", name));
  std::array<long long, 3> dims{};
  for (int a = 0; a < 3; ++a) {
    if (dims_d[a] != std::floor(dims_d[a]) || dims_d[a] < 1 || dims_d[a] > 1e9)
      throw InputError(fmt::format("{}: DimSize = {} is not three positive whole numbers", name, h.at("dimsize")));
    dims[a] = static_cast<long long>(dims_d[a]);
  }
  const std::size_t voxels = checked_voxels(dims, name, max_voxels);
  if (!h.count("elementtype")) throw InputError(fmt::format("{}: the header has no ElementType", name));
  const Element type = element_type(h.at("elementtype"), name);
  if (h.count("elementnumberofchannels") &&
      numbers(h.at("elementnumberofchannels"), "ElementNumberOfChannels", name) != std::vector<double>{1})
    throw InputError(fmt::format("{}: has {} components per voxel; a scalar image is needed", name,
                                 h.at("elementnumberofchannels").substr(0, 20)));
  if (h.count("binarydata") && !truth(h.at("binarydata")))
    throw InputError(fmt::format("{}: BinaryData = False (text voxel data) is not read", name));
  const bool big = (h.count("binarydatabyteordermsb") && truth(h.at("binarydatabyteordermsb"))) ||
                   (h.count("elementbyteordermsb") && truth(h.at("elementbyteordermsb")));
  const bool compressed = h.count("compresseddata") && truth(h.at("compresseddata"));
  const VoxelLayout layout{dims, voxels, type, big};

  // Where the data are: after the header (LOCAL), or in one other file beside it.
  std::string detached;
  const std::string* data = &bytes;
  std::size_t offset = pos;
  const std::string file = h.at("elementdatafile");
  if (lower(file) != "local") {
    if (!is_single_data_file(file))
      throw InputError(
          fmt::format("{}: ElementDataFile = '{}': only LOCAL or one data file is read", name, file.substr(0, 80)));
    const std::filesystem::path other = path.parent_path() / file;
    detached = read_file_bytes(other);
    data = &detached;
    offset = 0;
    if (h.count("headersize")) {
      const auto skip = numbers(h.at("headersize"), "HeaderSize", name);
      if (skip.size() != 1 || skip[0] < -1 || skip[0] != std::floor(skip[0]))
        throw InputError(fmt::format("{}: HeaderSize = {} is not a byte count", name, h.at("headersize")));
      // -1: the data are the last bytes of the file.
      offset = skip[0] < 0 ? (detached.size() >= layout.bytes() ? detached.size() - layout.bytes() : 0)
                           : static_cast<std::size_t>(std::min<double>(skip[0], static_cast<double>(detached.size())));
    }
  }

  if (stored) {
    stored->header = bytes.substr(0, pos);
    stored->type = type;
    stored->big_endian = big;
    stored->compressed = compressed;
    stored->detached = data != &bytes;
  }
  Volume v;
  v.name = name;
  v.dims = {static_cast<int>(dims[0]), static_cast<int>(dims[1]), static_cast<int>(dims[2])};
  if (compressed) {
    Inflater inflater(*data, offset, name);
    v.values = inflated_voxels(inflater, 0, layout, name);
  } else {
    v.values = raw_voxels(*data, offset, layout, name);
  }

  // Each quantity has synonyms in the MetaIO format; the first present wins.
  auto values = [&](std::initializer_list<const char*> keys, std::size_t count) -> std::optional<std::vector<double>> {
    for (const char* key : keys)
      if (h.count(key)) {
        auto x = numbers(h.at(key), key, name);
        if (x.size() != count) throw InputError(fmt::format("{}: {} needs {} values", name, key, count));
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

}  // namespace meshpde::detail
