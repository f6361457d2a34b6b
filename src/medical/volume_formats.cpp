#include "volume_formats.h"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include "meshpde/core/errors.h"

namespace meshpde::detail {

std::string read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))  // a directory opens, then throws on reading
    throw InputError(fmt::format("{}: not a readable file", path.string()));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", path.string()));
  try {
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw InputError(fmt::format("{}: read error", path.string()));
    return bytes;
  } catch (const std::ios_base::failure& e) {
    throw InputError(fmt::format("{}: read error ({})", path.string(), e.what()));
  }
}

struct Inflater::State {
  z_stream z{};
};

Inflater::Inflater(const std::string& bytes, std::size_t offset, std::string name)
    : state_(std::make_unique<State>()),
      compressed_(bytes.size() - std::min(offset, bytes.size())),
      name_(std::move(name)) {
  z_stream& z = state_->z;
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data() + std::min(offset, bytes.size())));
  // zlib takes an unsigned int of input at a time; refill is not needed below 4 GB.
  if (compressed_ > std::numeric_limits<uInt>::max())
    throw InputError(fmt::format("{}: compressed data of {} bytes is too large", name_, compressed_));
  z.avail_in = static_cast<uInt>(compressed_);
  // 15 + 32: zlib or gzip, detected from the header.
  if (inflateInit2(&z, 15 + 32) != Z_OK) throw InputError(fmt::format("{}: cannot start zlib", name_));
}

Inflater::~Inflater() {
  inflateEnd(&state_->z);
}

std::string Inflater::take(std::size_t n) {
  std::string out(n, '\0');
  z_stream& z = state_->z;
  std::size_t done = 0;
  while (done < n) {
    const std::size_t chunk = std::min<std::size_t>(n - done, std::numeric_limits<uInt>::max());
    z.next_out = reinterpret_cast<Bytef*>(out.data() + done);
    z.avail_out = static_cast<uInt>(chunk);
    const int rc = inflate(&z, Z_NO_FLUSH);
    done += chunk - z.avail_out;
    if (done == n) break;
    // Z_BUF_ERROR: no progress possible, the input is used up.
    if (rc == Z_STREAM_END || rc == Z_BUF_ERROR)
      throw InputError(fmt::format("{}: compressed data ends after {} of {} bytes", name_, done, n));
    if (rc != Z_OK)
      throw InputError(
          fmt::format("{}: damaged compressed data ({})", name_, z.msg ? z.msg : "zlib error " + std::to_string(rc)));
  }
  return out;
}

std::size_t inflated_bound(std::size_t compressed) {
  return compressed * 1100 + (1u << 16);
}

std::size_t element_size(Element e) {
  switch (e) {
    case Element::U8:
    case Element::I8:
      return 1;
    case Element::U16:
    case Element::I16:
      return 2;
    case Element::U32:
    case Element::I32:
    case Element::F32:
      return 4;
    case Element::U64:
    case Element::I64:
    case Element::F64:
      return 8;
  }
  return 0;
}

namespace {

template <class T>
T load(const char* p, bool big_endian) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

template <class T, class Out>
void convert(const char* data, std::size_t n, bool big, double slope, double inter, std::vector<Out>& out) {
  for (std::size_t i = 0; i < n; ++i)
    out[i] = static_cast<Out>(static_cast<double>(load<T>(data + i * sizeof(T), big)) * slope + inter);
}

template <class Out>
void convert_any(const char* data, std::size_t n, Element e, bool big, double slope, double inter,
                 std::vector<Out>& out) {
  out.resize(n);
  switch (e) {
    case Element::U8:
      return convert<std::uint8_t>(data, n, big, slope, inter, out);
    case Element::I8:
      return convert<std::int8_t>(data, n, big, slope, inter, out);
    case Element::U16:
      return convert<std::uint16_t>(data, n, big, slope, inter, out);
    case Element::I16:
      return convert<std::int16_t>(data, n, big, slope, inter, out);
    case Element::U32:
      return convert<std::uint32_t>(data, n, big, slope, inter, out);
    case Element::I32:
      return convert<std::int32_t>(data, n, big, slope, inter, out);
    case Element::U64:
      return convert<std::uint64_t>(data, n, big, slope, inter, out);
    case Element::I64:
      return convert<std::int64_t>(data, n, big, slope, inter, out);
    case Element::F32:
      return convert<float>(data, n, big, slope, inter, out);
    case Element::F64:
      return convert<double>(data, n, big, slope, inter, out);
  }
}

}  // namespace

void convert_elements(const char* data, std::size_t n, Element e, bool big, double slope, double inter,
                      std::vector<float>& out) {
  convert_any(data, n, e, big, slope, inter, out);
}

void convert_elements(const char* data, std::size_t n, Element e, bool big, std::vector<double>& out) {
  convert_any(data, n, e, big, 1.0, 0.0, out);
}

std::uint64_t load_unsigned(const char* data, std::size_t bytes, bool big_endian) {
  return bytes == 8 ? load<std::uint64_t>(data, big_endian) : load<std::uint32_t>(data, big_endian);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

bool is_single_data_file(const std::string& value) {
  return !value.empty() && lower(value).rfind("list", 0) != 0 && value.find('%') == std::string::npos &&
         value.find(' ') == std::string::npos;
}

std::vector<float> raw_voxels(const std::string& data, std::size_t offset, const VoxelLayout& l,
                              const std::string& name) {
  const std::size_t present = data.size() - std::min(offset, data.size());
  if (present < l.bytes())
    throw InputError(fmt::format("{}: {} data bytes for {} x {} x {} voxels of {} bytes (truncated data?)", name,
                                 present, l.dims[0], l.dims[1], l.dims[2], element_size(l.type)));
  std::vector<float> out;
  convert_elements(data.data() + offset, l.voxels, l.type, l.big_endian, 1, 0, out);
  return out;
}

std::vector<float> inflated_voxels(Inflater& inflater, std::size_t skip, const VoxelLayout& l,
                                   const std::string& name) {
  if (skip + l.bytes() > inflated_bound(inflater.compressed_size()))
    throw InputError(fmt::format("{}: {} compressed bytes cannot hold {} x {} x {} voxels", name,
                                 inflater.compressed_size(), l.dims[0], l.dims[1], l.dims[2]));
  if (skip > 0) inflater.take(skip);
  const std::string raw = inflater.take(l.bytes());
  std::vector<float> out;
  convert_elements(raw.data(), l.voxels, l.type, l.big_endian, 1, 0, out);
  return out;
}

std::size_t checked_voxels(const std::array<long long, 3>& dims, const std::string& name, std::size_t max_voxels) {
  std::size_t n = 1;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0 || dims[a] > std::numeric_limits<int>::max())
      throw InputError(fmt::format("{}: dimension {} is {}", name, a, dims[a]));
    if (n > std::numeric_limits<std::size_t>::max() / 16 / static_cast<std::size_t>(dims[a]))
      throw InputError(fmt::format("{}: {} x {} x {} voxels is too many", name, dims[0], dims[1], dims[2]));
    n *= static_cast<std::size_t>(dims[a]);
  }
  if (max_voxels > 0 && n > max_voxels)
    throw InputError(fmt::format("{}: {} x {} x {} voxels is more than this reader takes ({} at most)", name, dims[0],
                                 dims[1], dims[2], max_voxels));
  return n;
}

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

}  // namespace meshpde::detail
