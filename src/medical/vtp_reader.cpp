// VTK XML PolyData (.vtp) reading of our own; see polydata.h for why not VTK's.
//
// The format (VTK's "VTK File Formats" document): a <VTKFile type="PolyData"> holding
// <PolyData><Piece NumberOfPoints=.. NumberOfPolys=..> pieces with <Points>, <Verts>,
// <Lines>, <Polys>, <Strips> (each a connectivity and an offsets array, offsets being
// end positions), <PointData> and <CellData>. A <DataArray> is ascii text, inline base64
// ("binary") or an offset into <AppendedData> (raw bytes or base64). Binary data start
// with a header of header_type words: the byte count, or for compressed data the block
// count, block size, last block size and each block's compressed size. VTK encodes an
// uncompressed header with its data as one base64 stream and a compressed header as a
// stream of its own; decoding base64 group by group (padding ends a group, not the
// stream) reads both, and files written either way by other tools.
#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string_view>

#include "meshpde/core/errors.h"
#include "polydata.h"
#include "volume_formats.h"

namespace meshpde::detail {
namespace {

// ------------------------------------------------------------------- XML

struct XmlNode {
  std::string tag;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::vector<XmlNode> children;
  std::string text;  ///< the element's own character data, children's left out

  const std::string* attribute(std::string_view key) const {
    for (const auto& [k, v] : attributes)
      if (k == key) return &v;
    return nullptr;
  }
  std::string attribute_or(std::string_view key, std::string fallback) const {
    const std::string* v = attribute(key);
    return v ? *v : fallback;
  }
  const XmlNode* child(std::string_view t) const {
    for (const auto& c : children)
      if (c.tag == t) return &c;
    return nullptr;
  }
};

// A small XML parser for what VTK files use: elements, attributes, character data,
// comments, processing instructions, CDATA. It stops at <AppendedData>, whose content
// is binary; the position of its first data byte (after the '_' marker) is kept.
class XmlParser {
 public:
  XmlParser(std::string_view text, const std::string& name) : s_(text), name_(name) {}

  XmlNode parse_document() {
    if (s_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;
    for (;;) {
      skip_space();
      if (pos_ >= s_.size()) fail("no root element");
      if (starts("<?")) {
        skip_past("?>");
      } else if (starts("<!--")) {
        skip_past("-->");
      } else if (starts("<!")) {
        skip_past(">");
      } else {
        break;
      }
    }
    if (!starts("<")) fail("text before the root element");
    return element(0);
  }

  std::size_t appended_start() const { return appended_; }
  const XmlNode& appended_node() const { return appended_node_; }
  bool has_appended() const { return appended_ != std::string_view::npos; }

 private:
  static constexpr int kMaxDepth = 64;

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("{}: XML at byte {}: {}", name_, pos_, what));
  }
  bool starts(std::string_view p) const { return s_.substr(pos_, p.size()) == p; }
  void skip_space() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\r' || s_[pos_] == '\n')) ++pos_;
  }
  void skip_past(std::string_view end) {
    const auto e = s_.find(end, pos_);
    if (e == std::string_view::npos) fail(fmt::format("'{}' never closed", end));
    pos_ = e + end.size();
  }
  static bool name_char(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' || c == ':';
  }
  std::string name_token() {
    const std::size_t b = pos_;
    while (pos_ < s_.size() && name_char(s_[pos_])) ++pos_;
    if (pos_ == b) fail("expected a name");
    return std::string(s_.substr(b, pos_ - b));
  }
  static std::string unescape(std::string_view v) {
    std::string out;
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (v[i] == '&') {
        static constexpr std::pair<std::string_view, char> kEntities[] = {
            {"&lt;", '<'}, {"&gt;", '>'}, {"&amp;", '&'}, {"&quot;", '"'}, {"&apos;", '\''}};
        bool done = false;
        for (const auto& [e, c] : kEntities)
          if (v.substr(i, e.size()) == e) {
            out += c;
            i += e.size() - 1;
            done = true;
            break;
          }
        if (done) continue;
      }
      out += v[i];
    }
    return out;
  }

  // At '<' of a start tag.
  XmlNode element(int depth) {
    if (depth > kMaxDepth) fail(fmt::format("elements nested deeper than {}", kMaxDepth));
    ++pos_;
    XmlNode node;
    node.tag = name_token();
    for (;;) {
      skip_space();
      if (pos_ >= s_.size()) fail(fmt::format("<{}> never closed", node.tag));
      if (starts("/>")) {
        pos_ += 2;
        return node;
      }
      if (s_[pos_] == '>') {
        ++pos_;
        break;
      }
      std::string key = name_token();
      skip_space();
      if (pos_ >= s_.size() || s_[pos_] != '=') fail(fmt::format("attribute '{}' of <{}> has no value", key, node.tag));
      ++pos_;
      skip_space();
      if (pos_ >= s_.size() || (s_[pos_] != '"' && s_[pos_] != '\'')) fail("attribute value not quoted");
      const char quote = s_[pos_++];
      const auto end = s_.find(quote, pos_);
      if (end == std::string_view::npos) fail("attribute value never closed");
      node.attributes.emplace_back(std::move(key), unescape(s_.substr(pos_, end - pos_)));
      pos_ = end + 1;
    }
    if (node.tag == "AppendedData") {
      // Binary from here on: "_" after optional whitespace marks the first byte.
      skip_space();
      if (pos_ >= s_.size() || s_[pos_] != '_') fail("<AppendedData> does not start with '_'");
      appended_ = pos_ + 1;
      appended_node_ = node;
      return node;
    }
    for (;;) {
      const auto lt = s_.find('<', pos_);
      if (lt == std::string_view::npos) fail(fmt::format("<{}> never closed", node.tag));
      node.text.append(s_.substr(pos_, lt - pos_));
      pos_ = lt;
      if (starts("</")) {
        pos_ += 2;
        const std::string closing = name_token();
        if (closing != node.tag) fail(fmt::format("</{}> closes <{}>", closing, node.tag));
        skip_space();
        if (pos_ >= s_.size() || s_[pos_] != '>') fail(fmt::format("</{}> not closed by '>'", closing));
        ++pos_;
        return node;
      }
      if (starts("<!--")) {
        skip_past("-->");
      } else if (starts("<![CDATA[")) {
        const auto e = s_.find("]]>", pos_);
        if (e == std::string_view::npos) fail("CDATA never closed");
        node.text.append(s_.substr(pos_ + 9, e - pos_ - 9));
        pos_ = e + 3;
      } else if (starts("<?")) {
        skip_past("?>");
      } else {
        node.children.push_back(element(depth + 1));
        if (has_appended()) return node;  // the rest of the file is binary
      }
    }
  }

  std::string_view s_;
  const std::string& name_;
  std::size_t pos_ = 0;
  std::size_t appended_ = std::string_view::npos;
  XmlNode appended_node_;
};

// ------------------------------------------------------------ byte sources

// Where a binary array's bytes come from: raw appended bytes or base64 text.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// The next n bytes. \throw InputError when fewer are left.
  virtual std::string take(std::size_t n) = 0;
  /// At most this many bytes are left (checked before a claimed size is allocated).
  virtual std::size_t bound() const = 0;
};

class RawSource : public ByteSource {
 public:
  RawSource(std::string_view bytes, std::string what) : b_(bytes), what_(std::move(what)) {}
  std::string take(std::size_t n) override {
    if (n > b_.size() - pos_)
      throw InputError(fmt::format("{} needs {} bytes but {} are left in the file", what_, n, b_.size() - pos_));
    std::string out(b_.substr(pos_, n));
    pos_ += n;
    return out;
  }
  std::size_t bound() const override { return b_.size() - pos_; }

 private:
  std::string_view b_;
  std::size_t pos_ = 0;
  std::string what_;
};

class Base64Source : public ByteSource {
 public:
  Base64Source(std::string_view text, std::string what) : t_(text), what_(std::move(what)) {}
  std::string take(std::size_t n) override {
    if (n > bound()) throw InputError(fmt::format("{} needs {} bytes but its base64 text holds fewer", what_, n));
    std::string out = std::move(pending_);
    pending_.clear();
    out.reserve(n + 3);
    while (out.size() < n) group(out);
    pending_ = out.substr(n);
    out.resize(n);
    return out;
  }
  std::size_t bound() const override { return (t_.size() - pos_) / 4 * 3 + pending_.size(); }

 private:
  static int value(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    if (c == '=') return 64;
    return -1;
  }
  // Decodes the next group of four characters (whitespace skipped) onto `out`.
  void group(std::string& out) {
    int v[4];
    for (int& x : v) {
      while (pos_ < t_.size() && std::isspace(static_cast<unsigned char>(t_[pos_]))) ++pos_;
      if (pos_ >= t_.size()) throw InputError(fmt::format("{}: the base64 data end early", what_));
      x = value(t_[pos_]);
      if (x < 0)
        throw InputError(fmt::format(
            "{}: '{}' is not a base64 character", what_,
            std::isprint(static_cast<unsigned char>(t_[pos_])) ? std::string(1, t_[pos_]) : std::string("\\x??")));
      ++pos_;
    }
    if (v[0] == 64 || v[1] == 64 || (v[2] == 64 && v[3] != 64))
      throw InputError(fmt::format("{}: misplaced base64 padding", what_));
    out += static_cast<char>((v[0] << 2) | (v[1] >> 4));
    if (v[2] != 64) out += static_cast<char>(((v[1] & 15) << 4) | (v[2] >> 2));
    if (v[3] != 64) out += static_cast<char>(((v[2] & 3) << 6) | v[3]);
  }

  std::string_view t_;
  std::size_t pos_ = 0;
  std::string pending_;
  std::string what_;
};

// ------------------------------------------------------------ data arrays

struct FileSettings {
  bool big_endian = false;
  std::size_t header_bytes = 4;  // UInt32 or UInt64
  bool zlib = false;
  std::string_view appended;  // from the first byte after '_' to the end of the file
  bool appended_base64 = false;
};

bool element_of(const std::string& type, Element& e) {
  static constexpr std::pair<std::string_view, Element> kTypes[] = {
      {"Int8", Element::I8},     {"UInt8", Element::U8},    {"Int16", Element::I16}, {"UInt16", Element::U16},
      {"Int32", Element::I32},   {"UInt32", Element::U32},  {"Int64", Element::I64}, {"UInt64", Element::U64},
      {"Float32", Element::F32}, {"Float64", Element::F64}, {"Char", Element::I8},   {"Int", Element::I32}};
  for (const auto& [n, t] : kTypes)
    if (type == n) {
      e = t;
      return true;
    }
  return false;
}

// The bytes of one binary array (after its header), inflated when compressed.
std::string binary_block(ByteSource& src, const FileSettings& f, const std::string& what) {
  const std::size_t h = f.header_bytes;
  auto word = [&](const std::string& bytes, std::size_t i) {
    return load_unsigned(bytes.data() + i * h, h, f.big_endian);
  };
  if (!f.zlib) {
    const std::uint64_t n = word(src.take(h), 0);
    if (n > src.bound())
      throw InputError(fmt::format("{}: its header claims {} bytes but at most {} follow", what, n, src.bound()));
    return src.take(static_cast<std::size_t>(n));
  }
  const std::string head = src.take(3 * h);
  const std::uint64_t blocks = word(head, 0), block_size = word(head, 1), last_size = word(head, 2);
  if (blocks > src.bound() / h)
    throw InputError(fmt::format("{}: its header claims {} compressed blocks, more than the file holds", what, blocks));
  if (blocks == 0) return {};
  const std::string sizes = src.take(static_cast<std::size_t>(blocks) * h);
  std::string out;
  std::uint64_t compressed_total = 0;
  for (std::uint64_t b = 0; b < blocks; ++b) {
    const std::uint64_t c = word(sizes, static_cast<std::size_t>(b));
    if (c > src.bound() || compressed_total > src.bound() - c)
      throw InputError(
          fmt::format("{}: its blocks claim more compressed bytes than the {} that follow", what, src.bound()));
    compressed_total += c;
  }
  if (last_size > block_size)
    throw InputError(fmt::format("{}: last block size {} exceeds the block size {}", what, last_size, block_size));
  for (std::uint64_t b = 0; b < blocks; ++b) {
    const std::uint64_t csize = word(sizes, static_cast<std::size_t>(b));
    const std::uint64_t usize = (b + 1 == blocks && last_size != 0) ? last_size : block_size;
    // Checked block by block, so the total cannot outgrow what the compressed bytes hold.
    if (usize > inflated_bound(static_cast<std::size_t>(csize)))
      throw InputError(
          fmt::format("{}: block {} claims {} bytes from {} compressed bytes, more than zlib can inflate to", what, b,
                      usize, csize));
    const std::string packed = src.take(static_cast<std::size_t>(csize));
    const std::size_t at = out.size();
    out.resize(at + static_cast<std::size_t>(usize));
    uLongf got = static_cast<uLongf>(usize);
    const int rc = uncompress(reinterpret_cast<Bytef*>(out.data() + at), &got,
                              reinterpret_cast<const Bytef*>(packed.data()), static_cast<uLong>(packed.size()));
    if (rc != Z_OK || got != usize)
      throw InputError(fmt::format("{}: block {} does not inflate to its {} bytes (zlib: {})", what, b, usize,
                                   rc == Z_OK ? "short" : zError(rc)));
  }
  return out;
}

std::vector<double> ascii_values(std::string_view text, const std::string& what) {
  std::vector<double> out;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    if (i >= text.size()) break;
    std::size_t e = i;
    while (e < text.size() && !std::isspace(static_cast<unsigned char>(text[e]))) ++e;
    double v = 0;
    const auto [p, ec] = std::from_chars(text.data() + i, text.data() + e, v);
    if (ec != std::errc() || p != text.data() + e)
      throw InputError(fmt::format("{}: value {} is not a number ('{}')", what, out.size(),
                                   std::string(text.substr(i, std::min<std::size_t>(e - i, 24)))));
    out.push_back(v);
    i = e;
  }
  return out;
}

// Why an array cannot be read, or "" with its values filled in. A "String" array is
// read as its bytes (each string ends with a NUL), as VTK stores it.
std::string array_values(const XmlNode& da, const FileSettings& f, const std::string& what, Element& type,
                         std::vector<double>& values, bool strings = false) {
  const std::string type_name = da.attribute_or("type", "");
  if (strings && type_name == "String")
    type = Element::U8;
  else if (!element_of(type_name, type))
    return fmt::format("type '{}' is not numeric", type_name);
  const std::string format = da.attribute_or("format", "ascii");
  if (format == "ascii") {
    values = ascii_values(da.text, what);
    return {};
  }
  std::string bytes;
  if (format == "binary") {
    Base64Source src(da.text, what);
    bytes = binary_block(src, f, what);
  } else if (format == "appended") {
    if (f.appended.data() == nullptr)
      throw InputError(fmt::format("{} is appended but the file has no <AppendedData>", what));
    const std::string off = da.attribute_or("offset", "");
    unsigned long long offset = 0;
    const auto [p, ec] = std::from_chars(off.data(), off.data() + off.size(), offset);
    if (off.empty() || ec != std::errc() || p != off.data() + off.size() || offset > f.appended.size())
      throw InputError(
          fmt::format("{}: offset '{}' is not within the {} appended bytes", what, off, f.appended.size()));
    const std::string_view from = f.appended.substr(static_cast<std::size_t>(offset));
    if (f.appended_base64) {
      Base64Source src(from, what);
      bytes = binary_block(src, f, what);
    } else {
      RawSource src(from, what);
      bytes = binary_block(src, f, what);
    }
  } else {
    throw InputError(fmt::format("{}: unknown format '{}' (ascii, binary or appended)", what, format));
  }
  const std::size_t es = element_size(type);
  if (bytes.size() % es != 0)
    throw InputError(fmt::format("{}: {} bytes are not a whole number of {} values", what, bytes.size(), type_name));
  convert_elements(bytes.data(), bytes.size() / es, type, f.big_endian, values);
  return {};
}

int components_of(const XmlNode& da, const std::string& what) {
  const std::string s = da.attribute_or("NumberOfComponents", "1");
  int n = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), n);
  if (ec != std::errc() || p != s.data() + s.size() || n < 1 || n > 4096)
    throw InputError(fmt::format("{}: NumberOfComponents '{}' is not a count from 1 to 4096", what, s));
  return n;
}

std::size_t count_attribute(const XmlNode& piece, const char* key, std::size_t limit, const std::string& what) {
  const std::string s = piece.attribute_or(key, "0");
  unsigned long long n = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), n);
  if (ec != std::errc() || p != s.data() + s.size() || n > limit)
    throw InputError(fmt::format("{}: {} '{}' is not a count the file can hold", what, key, s));
  return static_cast<std::size_t>(n);
}

// The numeric arrays under <PointData> or <CellData>, each `tuples` long; others skipped.
std::vector<NamedArray> data_arrays(const XmlNode* parent, const char* kind, std::size_t tuples, const FileSettings& f,
                                    const std::string& where, std::vector<std::string>& warnings) {
  std::vector<NamedArray> out;
  if (!parent) return out;
  int index = 0;
  for (const XmlNode& da : parent->children) {
    if (da.tag != "DataArray") continue;
    NamedArray a;
    a.name = da.attribute_or("Name", fmt::format("{}_array_{}", kind, index));
    ++index;
    const std::string what = fmt::format("{} {} array '{}'", where, kind, a.name);
    a.components = components_of(da, what);
    Element type{};
    const std::string why = array_values(da, f, what, type, a.values);
    if (!why.empty()) {
      warnings.push_back(fmt::format("{}: ignored ({})", what, why));
      continue;
    }
    a.type = da.attribute_or("type", "");
    if (a.type == "Char") a.type = "Int8";
    if (a.type == "Int") a.type = "Int32";
    if (a.values.size() != tuples * static_cast<std::size_t>(a.components))
      throw InputError(fmt::format("{}: {} values, expected {} {} x {} components", what, a.values.size(), tuples, kind,
                                   a.components));
    out.push_back(std::move(a));
  }
  return out;
}

CellList cell_list(const XmlNode* cells, const char* kind, std::size_t count, const FileSettings& f,
                   const std::string& where) {
  CellList out;
  if (count == 0) return out;
  const std::string what = fmt::format("{} <{}>", where, kind);
  if (!cells) throw InputError(fmt::format("{}: missing, but the piece says it has {} cells", what, count));
  const XmlNode *conn = nullptr, *offs = nullptr;
  for (const XmlNode& da : cells->children) {
    if (da.tag != "DataArray") continue;
    const std::string n = da.attribute_or("Name", "");
    if (n == "connectivity") conn = &da;
    if (n == "offsets") offs = &da;
  }
  if (!conn || !offs) throw InputError(fmt::format("{}: needs a 'connectivity' and an 'offsets' DataArray", what));
  Element type{};
  std::vector<double> values;
  if (const auto why = array_values(*conn, f, what + " connectivity", type, values); !why.empty())
    throw InputError(fmt::format("{} connectivity: {}", what, why));
  out.connectivity = integer_ids(values, what + " connectivity");
  if (const auto why = array_values(*offs, f, what + " offsets", type, values); !why.empty())
    throw InputError(fmt::format("{} offsets: {}", what, why));
  if (values.size() != count) throw InputError(fmt::format("{}: {} offsets for {} cells", what, values.size(), count));
  const std::vector<std::int64_t> ends = integer_ids(values, what + " offsets");
  std::int64_t previous = 0;
  for (std::size_t c = 0; c < ends.size(); ++c) {
    if (ends[c] < previous || ends[c] > static_cast<std::int64_t>(out.connectivity.size()))
      throw InputError(fmt::format("{}: offset {} of cell {} is out of order or past the {} connectivity entries", what,
                                   ends[c], c, out.connectivity.size()));
    previous = ends[c];
  }
  if (previous != static_cast<std::int64_t>(out.connectivity.size()))
    throw InputError(fmt::format("{}: the offsets end at {} but there are {} connectivity entries", what, previous,
                                 out.connectivity.size()));
  out.offsets.insert(out.offsets.end(), ends.begin(), ends.end());
  return out;
}

struct Piece {
  PolyData data;
  std::size_t cells[4]{};  // verts, lines, polys, strips
};

Piece read_piece(const XmlNode& node, std::size_t index, std::size_t limit, const FileSettings& f,
                 const std::string& name) {
  Piece piece;
  PolyData& pd = piece.data;
  const std::string where = fmt::format("{}: piece {}", name, index);
  const std::size_t np = count_attribute(node, "NumberOfPoints", limit, where);
  static constexpr const char* kKinds[4] = {"Verts", "Lines", "Polys", "Strips"};
  for (int k = 0; k < 4; ++k)
    piece.cells[k] = count_attribute(node, (std::string("NumberOf") + kKinds[k]).c_str(), limit, where);
  if (np > 0) {
    const XmlNode* points = node.child("Points");
    const XmlNode* da = points ? points->child("DataArray") : nullptr;
    if (!da) throw InputError(fmt::format("{}: has {} points but no <Points> DataArray", where, np));
    if (components_of(*da, where + " points") != 3)
      throw InputError(fmt::format("{}: the points do not have 3 components", where));
    Element type{};
    if (const auto why = array_values(*da, f, where + " points", type, pd.points); !why.empty())
      throw InputError(fmt::format("{} points: {}", where, why));
    pd.points_type = da->attribute_or("type", "Float64");
    if (pd.points.size() != 3 * np)
      throw InputError(fmt::format("{}: {} point coordinates for {} points", where, pd.points.size(), np));
  }
  CellList* lists[4] = {&pd.verts, &pd.lines, &pd.polys, &pd.strips};
  for (int k = 0; k < 4; ++k) *lists[k] = cell_list(node.child(kKinds[k]), kKinds[k], piece.cells[k], f, where);
  const std::size_t cells = piece.cells[0] + piece.cells[1] + piece.cells[2] + piece.cells[3];
  pd.point_arrays = data_arrays(node.child("PointData"), "point", np, f, where, pd.warnings);
  pd.cell_arrays = data_arrays(node.child("CellData"), "cell", cells, f, where, pd.warnings);
  return piece;
}

void append_cells(CellList& to, const CellList& from, std::int64_t point_shift) {
  const std::int64_t base = static_cast<std::int64_t>(to.connectivity.size());
  for (std::size_t c = 1; c < from.offsets.size(); ++c) to.offsets.push_back(base + from.offsets[c]);
  for (const std::int64_t v : from.connectivity) to.connectivity.push_back(v + point_shift);
}

// Joins the pieces as VTK numbers their cells: all verts, then lines, polys, strips.
PolyData merge(std::vector<Piece>& pieces, const std::string& name) {
  if (pieces.size() == 1) return std::move(pieces[0].data);
  PolyData out;
  std::int64_t shift = 0;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    PolyData& pd = pieces[p].data;
    out.points.insert(out.points.end(), pd.points.begin(), pd.points.end());
    append_cells(out.verts, pd.verts, shift);
    append_cells(out.lines, pd.lines, shift);
    append_cells(out.polys, pd.polys, shift);
    append_cells(out.strips, pd.strips, shift);
    shift += static_cast<std::int64_t>(pd.point_count());
    out.warnings.insert(out.warnings.end(), pd.warnings.begin(), pd.warnings.end());
    const auto same_arrays = [&](const std::vector<NamedArray>& a, const std::vector<NamedArray>& b) {
      if (a.size() != b.size()) return false;
      for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].name != b[i].name || a[i].components != b[i].components) return false;
      return true;
    };
    if (p > 0 && (!same_arrays(pd.point_arrays, pieces[0].data.point_arrays) ||
                  !same_arrays(pd.cell_arrays, pieces[0].data.cell_arrays)))
      throw InputError(fmt::format("{}: piece {} has other point or cell arrays than piece 0", name, p));
  }
  out.point_arrays = pieces[0].data.point_arrays;
  for (std::size_t i = 0; i < out.point_arrays.size(); ++i) {
    out.point_arrays[i].values.clear();
    for (Piece& piece : pieces) {
      const auto& v = piece.data.point_arrays[i].values;
      out.point_arrays[i].values.insert(out.point_arrays[i].values.end(), v.begin(), v.end());
    }
  }
  out.cell_arrays = pieces[0].data.cell_arrays;
  for (std::size_t i = 0; i < out.cell_arrays.size(); ++i) {
    auto& values = out.cell_arrays[i].values;
    values.clear();
    const auto nc = static_cast<std::size_t>(out.cell_arrays[i].components);
    for (int kind = 0; kind < 4; ++kind)
      for (Piece& piece : pieces) {
        std::size_t first = 0;
        for (int k = 0; k < kind; ++k) first += piece.cells[k];
        const auto& v = piece.data.cell_arrays[i].values;
        values.insert(values.end(), v.begin() + static_cast<std::ptrdiff_t>(first * nc),
                      v.begin() + static_cast<std::ptrdiff_t>((first + piece.cells[kind]) * nc));
      }
  }
  return out;
}

// The field data: string arrays (the first string of each) and numeric arrays, by name.
// 3D Slicer's frame tag of XML files is the string array SPACE ("LPS" or "RAS"). An
// array that cannot be read is passed over with a warning: field data describe the
// mesh, nothing reads the mesh through them.
void read_field_data(const XmlNode* field_data, const FileSettings& f, const std::string& name, PolyData& pd) {
  if (!field_data) return;
  for (const XmlNode& da : field_data->children) {
    // VTK writes a string array as <Array>, numeric ones as <DataArray>.
    if (da.tag != "Array" && da.tag != "DataArray") continue;
    const std::string array = da.attribute_or("Name", "");
    const std::string what = fmt::format("{}: field data '{}'", name, array);
    Element type{};
    std::vector<double> values;
    const bool is_string = da.attribute_or("type", "") == "String";
    std::string why;
    try {
      why = array_values(da, f, what, type, values, is_string);
    } catch (const InputError& e) {
      why = e.what();
    }
    if (!why.empty()) {
      pd.warnings.push_back(fmt::format("{}: not read ({})", what, why));
      continue;
    }
    if (is_string) {
      std::string value;
      for (const double b : values) {
        if (b == 0) break;
        // An ascii array may hold any number: only byte values spell a string.
        if (!(b >= 0 && b <= 255) || b != std::floor(b)) {
          value.clear();
          break;
        }
        value.push_back(static_cast<char>(static_cast<unsigned char>(b)));
      }
      if (array == "SPACE") {
        if (value.find("RAS") != std::string::npos) pd.space = "RAS";
        if (value.find("LPS") != std::string::npos) pd.space = "LPS";
        continue;
      }
      pd.field_strings.emplace_back(array, value);
      continue;
    }
    NamedArray a;
    a.name = array;
    a.type = da.attribute_or("type", "Float64");
    a.components = std::max(1, components_of(da, what));
    a.values = std::move(values);
    if (a.values.size() % static_cast<std::size_t>(a.components) != 0) {
      pd.warnings.push_back(
          fmt::format("{}: not read ({} values of {} components)", what, a.values.size(), a.components));
      continue;
    }
    pd.field_arrays.push_back(std::move(a));
  }
}

}  // namespace

PolyData read_vtp_polydata(const std::string& bytes, const std::string& name) {
  if (bytes.find("<VTKFile") == std::string::npos)
    throw InputError(fmt::format("{}: not a VTK XML file (no <VTKFile> element)", name));
  XmlParser parser(bytes, name);
  const XmlNode root = parser.parse_document();
  if (root.tag != "VTKFile")
    throw InputError(fmt::format("{}: the root element is <{}>, not <VTKFile>", name, root.tag));
  const std::string type = root.attribute_or("type", "");
  if (type != "PolyData")
    throw InputError(fmt::format("{}: the VTK XML file holds {}, not PolyData", name, type.empty() ? "?" : type));

  FileSettings f;
  const std::string order = root.attribute_or("byte_order", "LittleEndian");
  if (order != "LittleEndian" && order != "BigEndian")
    throw InputError(fmt::format("{}: byte_order '{}' (LittleEndian or BigEndian)", name, order));
  f.big_endian = order == "BigEndian";
  const std::string header = root.attribute_or("header_type", "UInt32");
  if (header != "UInt32" && header != "UInt64")
    throw InputError(fmt::format("{}: header_type '{}' (UInt32 or UInt64)", name, header));
  f.header_bytes = header == "UInt64" ? 8 : 4;
  const std::string compressor = root.attribute_or("compressor", "");
  if (compressor == "vtkZLibDataCompressor")
    f.zlib = true;
  else if (!compressor.empty())
    throw InputError(
        fmt::format("{}: compressor '{}' is not supported (uncompressed or vtkZLibDataCompressor; "
                    "re-save with zlib)",
                    name, compressor));
  if (parser.has_appended()) {
    f.appended = std::string_view(bytes).substr(parser.appended_start());
    const std::string encoding = parser.appended_node().attribute_or("encoding", "raw");
    if (encoding != "raw" && encoding != "base64")
      throw InputError(fmt::format("{}: <AppendedData> encoding '{}' (raw or base64)", name, encoding));
    f.appended_base64 = encoding == "base64";
  }

  const XmlNode* poly = root.child("PolyData");
  if (!poly) throw InputError(fmt::format("{}: <VTKFile> has no <PolyData>", name));
  // No count can exceed what the file's bytes inflate to (one byte a value at least).
  const std::size_t limit = inflated_bound(bytes.size());
  std::vector<Piece> pieces;
  for (const XmlNode& node : poly->children)
    if (node.tag == "Piece") pieces.push_back(read_piece(node, pieces.size(), limit, f, name));
  if (pieces.empty()) throw InputError(fmt::format("{}: <PolyData> has no <Piece>", name));
  PolyData pd = merge(pieces, name);
  read_field_data(poly->child("FieldData"), f, name, pd);
  if (pd.space.empty())
    pd.space = detect_space(std::string_view(bytes).substr(0, std::min<std::size_t>(bytes.size(), 4096)));
  return pd;
}

}  // namespace meshpde::detail
