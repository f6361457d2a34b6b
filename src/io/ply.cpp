// Stanford PLY: ascii, binary_little_endian and binary_big_endian.
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "io_detail.h"

namespace meshpde::detail {

namespace {

enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

int type_size(Type t) {
  switch (t) {
    case Type::I8:
    case Type::U8:
      return 1;
    case Type::I16:
    case Type::U16:
      return 2;
    case Type::I32:
    case Type::U32:
    case Type::F32:
      return 4;
    case Type::F64:
      return 8;
  }
  return 0;
}

bool parse_type(std::string_view s, Type& t) {
  if (s == "char" || s == "int8")
    t = Type::I8;
  else if (s == "uchar" || s == "uint8")
    t = Type::U8;
  else if (s == "short" || s == "int16")
    t = Type::I16;
  else if (s == "ushort" || s == "uint16")
    t = Type::U16;
  else if (s == "int" || s == "int32")
    t = Type::I32;
  else if (s == "uint" || s == "uint32")
    t = Type::U32;
  else if (s == "float" || s == "float32")
    t = Type::F32;
  else if (s == "double" || s == "float64")
    t = Type::F64;
  else
    return false;
  return true;
}

struct Property {
  std::string name;
  bool is_list = false;
  Type count_type = Type::U8;
  Type type = Type::F32;
};

struct Element {
  std::string name;
  long long count = 0;
  std::vector<Property> props;
  int header_line = 0;
};

enum class Encoding { Ascii, Little, Big };

/// Reads one value of each binary type, converting byte order as needed.
class BinaryReader {
 public:
  BinaryReader(std::string_view bytes, std::size_t pos, bool big, const std::string& name)
      : b_(bytes), pos_(pos), big_(big), name_(name) {}
  double read(Type t, const std::string& where) {
    const int n = type_size(t);
    if (pos_ + n > b_.size()) fail(name_, where, "file ends in the middle of the data");
    unsigned char raw[8];
    std::memcpy(raw, b_.data() + pos_, n);
    pos_ += n;
    if (big_ != (std::endian::native == std::endian::big)) std::reverse(raw, raw + n);
    switch (t) {
      case Type::I8: {
        int8_t v;
        std::memcpy(&v, raw, 1);
        return v;
      }
      case Type::U8:
        return raw[0];
      case Type::I16: {
        int16_t v;
        std::memcpy(&v, raw, 2);
        return v;
      }
      case Type::U16: {
        uint16_t v;
        std::memcpy(&v, raw, 2);
        return v;
      }
      case Type::I32: {
        int32_t v;
        std::memcpy(&v, raw, 4);
        return v;
      }
      case Type::U32: {
        uint32_t v;
        std::memcpy(&v, raw, 4);
        return v;
      }
      case Type::F32: {
        float v;
        std::memcpy(&v, raw, 4);
        return v;
      }
      case Type::F64: {
        double v;
        std::memcpy(&v, raw, 8);
        return v;
      }
    }
    return 0;
  }
  std::size_t remaining() const { return b_.size() - pos_; }

 private:
  std::string_view b_;
  std::size_t pos_;
  bool big_;
  const std::string& name_;
};

/// Appends the triangles of a triangle strip whose restarts are -1: within each run
/// s0 s1 s2 s3 ..., the triangle ending at run position i >= 2 is (s[i-2], s[i-1], s[i])
/// when i is even and (s[i-1], s[i-2], s[i]) when odd, so that all share one orientation.
/// Triangles with a repeated corner (strips are often stitched that way) are dropped;
/// returns how many were.
int add_strip(std::vector<int>& tris, const std::vector<int>& strip) {
  int dropped = 0;
  std::size_t start = 0;
  for (std::size_t i = 0; i < strip.size(); ++i) {
    if (strip[i] < 0) {
      start = i + 1;
      continue;
    }
    if (i < start + 2) continue;
    const int a = strip[i - 2], b = strip[i - 1], c = strip[i];
    if (a == b || b == c || a == c) {
      ++dropped;
      continue;
    }
    const bool odd = (i - start) % 2 == 1;
    tris.push_back(odd ? b : a);
    tris.push_back(odd ? a : b);
    tris.push_back(c);
  }
  return dropped;
}

}  // namespace

MeshData read_ply(std::string_view bytes, const std::string& name) {
  TextCursor in(bytes, name);
  if (!in.next_line() || in.token() != "ply") fail(name, "line 1", "not a PLY file (missing 'ply' magic)");
  Encoding enc = Encoding::Ascii;
  bool have_format = false;
  std::vector<Element> elements;
  bool ended = false;
  while (in.next_line()) {
    const auto key = in.token();
    if (key == "format") {
      const auto f = in.token();
      if (f == "ascii")
        enc = Encoding::Ascii;
      else if (f == "binary_little_endian")
        enc = Encoding::Little;
      else if (f == "binary_big_endian")
        enc = Encoding::Big;
      else
        in.error(fmt::format("unknown PLY format '{}'", TextCursor::clip(f)));
      have_format = true;
    } else if (key == "comment" || key == "obj_info" || key.empty()) {
    } else if (key == "element") {
      Element e;
      e.name = std::string(in.token());
      e.count = in.integer("the element count");
      e.header_line = in.line_number();
      if (e.count < 0) in.error(fmt::format("element '{}' has a negative count {}", e.name, e.count));
      // One vertex and one face element: a second would mix its count with the first's.
      if ((e.name == "vertex" || e.name == "face") &&
          std::any_of(elements.begin(), elements.end(), [&](const Element& x) { return x.name == e.name; }))
        in.error(fmt::format("a second '{}' element", e.name));
      elements.push_back(std::move(e));
    } else if (key == "property") {
      if (elements.empty()) in.error("property before any element");
      Property p;
      const auto t = in.token();
      if (t == "list") {
        p.is_list = true;
        if (!parse_type(in.token(), p.count_type) || !parse_type(in.token(), p.type))
          in.error("unknown list property type");
      } else if (!parse_type(t, p.type)) {
        in.error(fmt::format("unknown property type '{}'", TextCursor::clip(t)));
      }
      p.name = std::string(in.token());
      if (p.name.empty()) in.error("property without a name");
      elements.back().props.push_back(std::move(p));
    } else if (key == "end_header") {
      ended = true;
      break;
    } else {
      in.error(fmt::format("unknown header keyword '{}'", TextCursor::clip(key)));
    }
  }
  if (!ended) fail(name, "header", "no 'end_header' line");
  if (!have_format) fail(name, "header", "no 'format' line");

  // Refuse counts the remaining bytes cannot hold before allocating anything.
  const std::size_t data_start = in.position();
  const long long remaining = static_cast<long long>(bytes.size() - data_start);
  for (const auto& e : elements) {
    long long min_bytes = 0;
    for (const auto& p : e.props) min_bytes += p.is_list ? type_size(p.count_type) : type_size(p.type);
    if (enc == Encoding::Ascii) min_bytes = std::max<long long>(2 * static_cast<long long>(e.props.size()), 1);
    if (min_bytes > 0 && e.count > remaining / min_bytes)
      fail(name, fmt::format("line {}", e.header_line),
           fmt::format("element '{}' claims {} entries, more than the {} data bytes can hold", e.name, e.count,
                       remaining));
  }

  MeshData d;
  std::vector<double> xyz;
  std::vector<int> tris, poly;
  int polygons = 0, strip_degenerates = 0;
  bool have_vertices = false;
  long long nv = 0;
  TextCursor text(bytes, name, data_start, in.line_number());
  BinaryReader bin(bytes, data_start, enc == Encoding::Big, name);
  auto value = [&](Type t, const std::string& where) -> double {
    if (enc != Encoding::Ascii) return bin.read(t, where);
    if (!text.has_token() && !text.next_content_line('\0')) fail(name, where, "file ends in the middle of the data");
    if (t == Type::F32 || t == Type::F64) return text.real("a number");
    return static_cast<double>(text.integer("an integer"));
  };

  for (const auto& e : elements) {
    const bool is_vertex = e.name == "vertex", is_strip = e.name == "tristrips";
    const bool is_face = is_strip || e.name == "face";
    int ix = -1, iy = -1, iz = -1, ilist = -1;
    std::vector<std::pair<int, Eigen::VectorXd*>> scalars;
    if (is_vertex) {
      nv = e.count;
      have_vertices = true;
      for (int k = 0; k < static_cast<int>(e.props.size()); ++k) {
        const auto& p = e.props[k];
        if (p.name == "x")
          ix = k;
        else if (p.name == "y")
          iy = k;
        else if (p.name == "z")
          iz = k;
        else if (!p.is_list) {
          auto& field = d.vertex_scalars[p.name];
          field.resize(e.count);
          scalars.emplace_back(k, &field);
        }
      }
      if (ix < 0 || iy < 0 || iz < 0)
        fail(name, fmt::format("line {}", e.header_line), "vertex element lacks x, y or z");
      // Only now: the count of an element with x, y and z was bounded by the data bytes
      // above, and that of one without properties (a binary one) was not.
      xyz.reserve(static_cast<std::size_t>(3 * e.count));
    }
    if (is_face) {
      for (int k = 0; k < static_cast<int>(e.props.size()); ++k)
        if (e.props[k].is_list && (e.props[k].name == "vertex_indices" || e.props[k].name == "vertex_index")) ilist = k;
      if (ilist < 0)
        fail(name, fmt::format("line {}", e.header_line), fmt::format("{} element lacks vertex_indices", e.name));
      if (!have_vertices) fail(name, fmt::format("line {}", e.header_line), "faces come before vertices");
      if (!is_strip) tris.reserve(static_cast<std::size_t>(3 * e.count));
    }
    // An element without properties holds no bytes, whatever its count: nothing to
    // read (a count of 10^15 would otherwise loop that often over nothing).
    if (e.props.empty()) continue;
    for (long long i = 0; i < e.count; ++i) {
      const std::string where = fmt::format("{} {}", e.name, i);
      if (enc == Encoding::Ascii && !text.has_token() && !text.next_content_line('\0'))
        fail(name, where, fmt::format("file ends after {} of {} {} entries", i, e.count, e.name));
      double pos[3] = {0, 0, 0};
      for (int k = 0; k < static_cast<int>(e.props.size()); ++k) {
        const auto& p = e.props[k];
        if (p.is_list) {
          const double n = value(p.count_type, where);
          // A face has few corners; a strip may hold the whole mesh, but never more
          // entries than bytes are left.
          const double most = is_strip && k == ilist ? static_cast<double>(bytes.size()) : 1'000'000.0;
          // (NaN and fractions too: a float count type can hold them.)
          if (!(n >= 0 && n <= most) || n != std::floor(n))
            fail(name, where, fmt::format("list length {} is invalid", n));
          if (k == ilist) poly.clear();
          for (long long j = 0; j < static_cast<long long>(n); ++j) {
            const double x = value(p.type, where);
            if (k == ilist) {
              const bool restart = is_strip && x == -1;
              if (!restart && (!(x >= 0 && x < static_cast<double>(nv)) || x != std::floor(x)))
                fail(name, where, fmt::format("vertex index {} outside [0, {})", x, nv));
              poly.push_back(static_cast<int>(x));
            }
          }
          if (k == ilist && is_strip) {
            strip_degenerates += add_strip(tris, poly);
          } else if (k == ilist) {
            if (poly.size() < 3) fail(name, where, fmt::format("a face needs 3 corners, found {}", poly.size()));
            if (poly.size() > 3) ++polygons;
            add_polygon(tris, poly);
          }
        } else {
          const double x = value(p.type, where);
          if (is_vertex) {
            if (k == ix || k == iy || k == iz) {
              if (!std::isfinite(x)) fail(name, where, "non-finite coordinate");
              pos[k == ix ? 0 : (k == iy ? 1 : 2)] = x;
            } else {
              for (auto& [kk, field] : scalars)
                if (kk == k) (*field)(i) = x;
            }
          }
        }
      }
      if (is_vertex) xyz.insert(xyz.end(), pos, pos + 3);
    }
  }
  if (!have_vertices) fail(name, "header", "no vertex element");
  d.V = to_positions(xyz);
  d.F = to_triangles(tris);
  if (polygons)
    d.warnings.push_back(fmt::format("{}: triangulated {} polygons with more than three corners", name, polygons));
  if (strip_degenerates)
    d.warnings.push_back(fmt::format("{}: dropped {} triangles with a repeated corner from the triangle strips", name,
                                     strip_degenerates));
  return d;
}

std::string write_ply(const MeshData& d, bool binary) {
  std::string out = "ply\n";
  out += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
  out += "comment written by meshpde\n";
  out += fmt::format("element vertex {}\nproperty double x\nproperty double y\nproperty double z\n", d.V.rows());
  for (const auto& [key, field] : d.vertex_scalars) out += fmt::format("property double {}\n", key);
  out += fmt::format("element face {}\nproperty list uchar int vertex_indices\nend_header\n", d.F.rows());
  auto put = [&](const auto& v) {
    static_assert(std::endian::native == std::endian::little, "big-endian hosts are not supported");
    out.append(reinterpret_cast<const char*>(&v), sizeof(v));
  };
  for (Eigen::Index i = 0; i < d.V.rows(); ++i) {
    if (binary) {
      for (int c = 0; c < 3; ++c) put(d.V(i, c));
      for (const auto& [key, field] : d.vertex_scalars) put(field(i));
    } else {
      fmt::format_to(std::back_inserter(out), "{} {} {}", d.V(i, 0), d.V(i, 1), d.V(i, 2));
      for (const auto& [key, field] : d.vertex_scalars) fmt::format_to(std::back_inserter(out), " {}", field(i));
      out += '\n';
    }
  }
  for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
    if (binary) {
      put(static_cast<uint8_t>(3));
      for (int c = 0; c < 3; ++c) put(static_cast<int32_t>(d.F(f, c)));
    } else {
      fmt::format_to(std::back_inserter(out), "3 {} {} {}\n", d.F(f, 0), d.F(f, 1), d.F(f, 2));
    }
  }
  return out;
}

}  // namespace meshpde::detail
