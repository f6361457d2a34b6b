// Legacy VTK PolyData (.vtk) reading of our own; see polydata.h for why not VTK's.
//
// The format (VTK's "VTK File Formats" document): a "# vtk DataFile Version x.y" line, a
// title line (3D Slicer puts "SPACE=RAS" or "SPACE=LPS" there), ASCII or BINARY,
// "DATASET POLYDATA", then keyword sections: POINTS, VERTICES / LINES / POLYGONS /
// TRIANGLE_STRIPS, POINT_DATA and CELL_DATA with SCALARS, COLOR_SCALARS, LOOKUP_TABLE,
// VECTORS, NORMALS, TEXTURE_COORDINATES, TENSORS, GLOBAL_IDS, PEDIGREE_IDS and FIELD
// arrays, and METADATA blocks (ended by a blank line). Version 5 and later store a cell
// list as OFFSETS and CONNECTIVITY arrays; earlier ones as "n size" and then, for each
// cell, its corner count and ids. BINARY data are big-endian and start right after the
// newline of their keyword line; vtkIdType is written as a 4-byte int.
#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string_view>

#include "meshpde/core/errors.h"
#include "polydata.h"
#include "volume_formats.h"

namespace meshpde::detail {
namespace {

struct LegacyType {
  std::string_view name;
  Element element;
  std::string_view xml;  // the VTK XML type name we report
};
constexpr LegacyType kLegacyTypes[] = {
    {"unsigned_char", Element::U8, "UInt8"},    {"char", Element::I8, "Int8"},
    {"unsigned_short", Element::U16, "UInt16"}, {"short", Element::I16, "Int16"},
    {"unsigned_int", Element::U32, "UInt32"},   {"int", Element::I32, "Int32"},
    {"unsigned_long", Element::U64, "UInt64"},  {"long", Element::I64, "Int64"},
    {"float", Element::F32, "Float32"},         {"double", Element::F64, "Float64"},
    {"vtkidtype", Element::I32, "Int64"},       {"vtktypeint64", Element::I64, "Int64"},
    {"vtktypeuint64", Element::U64, "UInt64"},  {"signed_char", Element::I8, "Int8"},
};

class LegacyReader {
 public:
  LegacyReader(std::string_view text, const std::string& name) : s_(text), name_(name) {}

  PolyData read() {
    const std::string magic(line());
    if (magic.rfind("# vtk DataFile", 0) != 0)
      throw InputError(fmt::format("{}:1: not a legacy VTK file (expected '# vtk DataFile Version')", name_));
    const auto v = magic.find("Version");
    if (v != std::string::npos) {
      std::string_view ver = std::string_view(magic).substr(v + 7);
      while (!ver.empty() && ver.front() == ' ') ver.remove_prefix(1);
      std::from_chars(ver.data(), ver.data() + ver.size(), major_);
    }
    pd_.space = detect_space(line());  // the title line
    const std::string mode = lower(trim(std::string(line())));
    if (mode == "binary")
      binary_ = true;
    else if (mode != "ascii")
      fail(fmt::format("expected ASCII or BINARY, found '{}'", clip(mode)));

    bool have_dataset = false;
    Section section = Section::None;
    std::size_t tuples = 0;
    for (std::string key = keyword(); !key.empty(); key = keyword()) {
      if (key == "dataset") {
        const std::string kind = lower(std::string(token("the dataset type")));
        if (kind != "polydata") fail(fmt::format("DATASET {}: only POLYDATA is a surface mesh", clip(kind)));
        have_dataset = true;
        continue;
      }
      if (key == "metadata") {
        skip_metadata();
        continue;
      }
      if (key == "field") {
        token("the field name");
        read_field(section, tuples);
        continue;
      }
      if (!have_dataset) fail(fmt::format("'{}' before DATASET POLYDATA", clip(key)));
      if (key == "points") {
        const std::size_t n = count("the point count");
        const LegacyType& t = type(token("the point type"));
        pd_.points = values(3 * n, t, "the points");
        pd_.points_type = std::string(t.xml);
      } else if (key == "vertices") {
        pd_.verts = cells("VERTICES");
      } else if (key == "lines") {
        pd_.lines = cells("LINES");
      } else if (key == "polygons") {
        pd_.polys = cells("POLYGONS");
      } else if (key == "triangle_strips") {
        pd_.strips = cells("TRIANGLE_STRIPS");
      } else if (key == "point_data" || key == "cell_data") {
        section = key == "point_data" ? Section::Point : Section::Cell;
        tuples = count("the tuple count");
      } else {
        read_attribute(key, section, tuples);
      }
    }
    if (!have_dataset) fail("no DATASET POLYDATA");
    return std::move(pd_);
  }

 private:
  enum class Section { None, Point, Cell };

  [[noreturn]] void fail(const std::string& what) const { throw InputError(fmt::format("{}: {}", where(), what)); }
  static std::string clip(std::string_view s) {
    std::string out;
    for (const char c : s.substr(0, 32)) out += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
    return out;
  }
  std::size_t left() const { return s_.size() - pos_; }

  // The rest of the current line, the newline consumed.
  std::string_view line() {
    if (pos_ >= s_.size()) fail("the file ends early");
    const auto e = s_.find('\n', pos_);
    const std::size_t stop = e == std::string_view::npos ? s_.size() : e;
    std::string_view out = s_.substr(pos_, stop - pos_);
    if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
    pos_ = e == std::string_view::npos ? s_.size() : e + 1;
    ++line_;
    return out;
  }
  void skip_space() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) {
      if (s_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  // The next whitespace-separated token, or "" at the end of the file.
  std::string_view next() {
    skip_space();
    const std::size_t b = pos_;
    while (pos_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
    return s_.substr(b, pos_ - b);
  }
  std::string_view token(const char* what) {
    const auto t = next();
    if (t.empty()) fail(fmt::format("the file ends before {}", what));
    return t;
  }
  std::string keyword() { return lower(std::string(next())); }
  std::size_t count(const char* what) {
    const auto t = token(what);
    unsigned long long n = 0;
    const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), n);
    if (ec != std::errc() || p != t.data() + t.size()) fail(fmt::format("{} '{}' is not a count", what, clip(t)));
    // Every value takes a byte at least: a larger count is a damaged file.
    if (n > s_.size()) fail(fmt::format("{} {} is more than the file can hold", what, n));
    return static_cast<std::size_t>(n);
  }
  const LegacyType& type(std::string_view t) {
    const std::string l = lower(std::string(t));
    for (const auto& lt : kLegacyTypes)
      if (l == lt.name) return lt;
    fail(fmt::format("data type '{}' is not supported (numeric arrays only)", clip(t)));
  }

  // n values of type t: text numbers, or big-endian binary right after this line.
  std::vector<double> values(std::size_t n, const LegacyType& t, const std::string& what) {
    std::vector<double> out;
    if (binary_) {
      line();  // the rest of the keyword line; the data start after its newline
      const std::size_t es = element_size(t.element);
      if (n > left() / es)
        fail(fmt::format("{}: {} {} values need more bytes than the {} left", what, n, t.name, left()));
      convert_elements(s_.data() + pos_, n, t.element, true, out);
      pos_ += n * es;
      return out;
    }
    if (n > left() / 2 + 1) fail(fmt::format("{}: {} values cannot fit in the {} bytes left", what, n, left()));
    out.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto tok = next();
      if (tok.empty()) fail(fmt::format("{}: the file ends after {} of {} values", what, i, n));
      double v = 0;
      const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
      if (ec != std::errc() || p != tok.data() + tok.size())
        fail(fmt::format("{}: value {} is not a number ('{}')", what, i, clip(tok)));
      out.push_back(v);
    }
    return out;
  }

  // Where the reader is, as fail() says it: the line, or in binary data the byte.
  std::string where() const {
    return binary_ ? fmt::format("{}: byte {}", name_, pos_) : fmt::format("{}:{}", name_, line_);
  }
  std::vector<std::int64_t> ids(const std::vector<double>& v, const std::string& what) {
    return integer_ids(v, fmt::format("{}: {}", where(), what));
  }

  CellList cells(const char* kind) {
    CellList out;
    const std::size_t a = count("the cell count"), b = count("the cell list size");
    if (major_ >= 5) {
      // "KIND offsets connectivity", then OFFSETS type, values, CONNECTIVITY type, values.
      if (lower(std::string(token("OFFSETS"))) != "offsets") fail(fmt::format("{}: expected OFFSETS", kind));
      const std::vector<std::int64_t> offsets =
          ids(values(a, type(token("the offsets type")), fmt::format("{} offsets", kind)), kind);
      skip_metadata_if_present();
      if (lower(std::string(token("CONNECTIVITY"))) != "connectivity")
        fail(fmt::format("{}: expected CONNECTIVITY", kind));
      out.connectivity =
          ids(values(b, type(token("the connectivity type")), fmt::format("{} connectivity", kind)), kind);
      if (!offsets.empty()) {
        if (offsets.front() != 0) fail(fmt::format("{}: the offsets start at {}, not 0", kind, offsets.front()));
        for (std::size_t c = 1; c < offsets.size(); ++c) {
          if (offsets[c] < offsets[c - 1] || offsets[c] > static_cast<std::int64_t>(b))
            fail(fmt::format("{}: offset {} of cell {} is out of order or past the {} connectivity entries", kind,
                             offsets[c], c - 1, b));
          out.offsets.push_back(offsets[c]);
        }
        if (offsets.back() != static_cast<std::int64_t>(b))
          fail(fmt::format("{}: the offsets end at {}, not at the {} connectivity entries", kind, offsets.back(), b));
      } else if (b != 0) {
        fail(fmt::format("{}: {} connectivity entries but no offsets", kind, b));
      }
      return out;
    }
    // "KIND n size", then for each cell its corner count and ids.
    static const LegacyType kInt{"int", Element::I32, "Int32"};
    const std::vector<std::int64_t> list = ids(values(b, kInt, kind), kind);
    std::size_t at = 0;
    for (std::size_t c = 0; c < a; ++c) {
      if (at >= list.size()) fail(fmt::format("{}: the list of {} entries ends at cell {} of {}", kind, b, c, a));
      const std::int64_t k = list[at++];
      if (k < 0 || static_cast<std::uint64_t>(k) > list.size() - at)
        fail(fmt::format("{}: cell {} claims {} corners, past the end of the list", kind, c, k));
      out.connectivity.insert(out.connectivity.end(), list.begin() + static_cast<std::ptrdiff_t>(at),
                              list.begin() + static_cast<std::ptrdiff_t>(at + static_cast<std::size_t>(k)));
      out.offsets.push_back(static_cast<std::int64_t>(out.connectivity.size()));
      at += static_cast<std::size_t>(k);
    }
    if (at != list.size()) fail(fmt::format("{}: {} cells use {} of the {} entries", kind, a, at, b));
    return out;
  }

  // A METADATA block: lines up to the next blank one.
  void skip_metadata() {
    line();
    while (pos_ < s_.size()) {
      std::string_view l = line();
      while (!l.empty() && std::isspace(static_cast<unsigned char>(l.back()))) l.remove_suffix(1);
      if (l.empty()) return;
    }
  }
  void skip_metadata_if_present() {
    const std::size_t at = pos_;
    const int ln = line_;
    if (lower(std::string(next())) == "metadata") {
      skip_metadata();
    } else {
      pos_ = at;
      line_ = ln;
    }
  }

  void add(Section section, std::size_t tuples, std::string name, const LegacyType& t, int components,
           std::vector<double> v) {
    if (section == Section::None) return;  // dataset-level field data: read past, not kept
    if (v.size() != tuples * static_cast<std::size_t>(components))
      fail(fmt::format("array '{}' has {} values for {} tuples", clip(name), v.size(), tuples));
    NamedArray a{std::move(name), std::string(t.xml), components, std::move(v)};
    (section == Section::Point ? pd_.point_arrays : pd_.cell_arrays).push_back(std::move(a));
  }

  int components(const char* what, std::size_t max) {
    const std::size_t n = count(what);
    if (n < 1 || n > max) fail(fmt::format("{} {} is not from 1 to {}", what, n, max));
    return static_cast<int>(n);
  }

  void read_attribute(const std::string& key, Section section, std::size_t tuples) {
    if (section == Section::None) fail(fmt::format("'{}' before POINT_DATA or CELL_DATA", clip(key)));
    if (key == "lookup_table") {
      token("the table name");
      const std::size_t n = count("the table size");
      static const LegacyType kFloat{"float", Element::F32, "Float32"}, kByte{"unsigned_char", Element::U8, "UInt8"};
      if (n > left() / 4) fail(fmt::format("lookup table of {} entries longer than the file", n));
      values(4 * n, binary_ ? kByte : kFloat, "the lookup table");
      return;
    }
    std::string name(token("the array name"));
    if (key == "scalars") {
      const LegacyType& t = type(token("the scalar type"));
      int nc = 1;
      std::string_view next_tok = token("LOOKUP_TABLE");
      if (lower(std::string(next_tok)) != "lookup_table") {
        unsigned long long c = 0;
        const auto [p, ec] = std::from_chars(next_tok.data(), next_tok.data() + next_tok.size(), c);
        if (ec != std::errc() || p != next_tok.data() + next_tok.size() || c < 1 || c > 4)
          fail(fmt::format("SCALARS {}: component count '{}' is not from 1 to 4", clip(name), clip(next_tok)));
        nc = static_cast<int>(c);
        next_tok = token("LOOKUP_TABLE");
      }
      if (lower(std::string(next_tok)) != "lookup_table")
        fail(fmt::format("SCALARS {}: expected LOOKUP_TABLE, found '{}'", clip(name), clip(next_tok)));
      token("the lookup table name");
      add(section, tuples, name, t, nc, values(tuples * static_cast<std::size_t>(nc), t, name));
    } else if (key == "color_scalars") {
      const int nc = components("the color component count", 4);
      static const LegacyType kByte{"unsigned_char", Element::U8, "UInt8"}, kFloat{"float", Element::F32, "Float32"};
      std::vector<double> v = values(tuples * static_cast<std::size_t>(nc), binary_ ? kByte : kFloat, name);
      if (!binary_)  // text colours are 0..1; VTK keeps them as bytes
        for (double& x : v) x = std::floor(std::clamp(x, 0.0, 1.0) * 255.0);
      add(section, tuples, name, kByte, nc, std::move(v));
    } else if (key == "vectors" || key == "normals") {
      const LegacyType& t = type(token("the vector type"));
      add(section, tuples, name, t, 3, values(3 * tuples, t, name));
    } else if (key == "texture_coordinates") {
      const int dim = components("the texture dimension", 3);
      const LegacyType& t = type(token("the texture coordinate type"));
      add(section, tuples, name, t, dim, values(tuples * static_cast<std::size_t>(dim), t, name));
    } else if (key == "tensors" || key == "tensors6") {
      const int nc = key == "tensors" ? 9 : 6;
      const LegacyType& t = type(token("the tensor type"));
      add(section, tuples, name, t, nc, values(tuples * static_cast<std::size_t>(nc), t, name));
    } else if (key == "global_ids" || key == "pedigree_ids") {
      const LegacyType& t = type(token("the id type"));
      add(section, tuples, name, t, 1, values(tuples, t, name));
    } else {
      fail(fmt::format("unknown keyword '{}'", clip(key)));
    }
  }

  void read_field(Section section, std::size_t tuples) {
    const std::size_t arrays = count("the field's array count");
    for (std::size_t i = 0; i < arrays; ++i) {
      skip_metadata_if_present();
      std::string name(token("the field array name"));
      if (name == "NULL_ARRAY") continue;
      const int nc = components("the field array's component count", 4096);
      const std::size_t n = count("the field array's tuple count");
      if (section != Section::None && n != tuples)
        fail(fmt::format("field array '{}' has {} tuples, not {}", clip(name), n, tuples));
      const LegacyType& t = type(token("the field array type"));
      if (n > s_.size() / static_cast<std::size_t>(nc))
        fail(fmt::format("field array '{}' is longer than the file", clip(name)));
      add(section, tuples, name, t, nc, values(n * static_cast<std::size_t>(nc), t, name));
    }
  }

  std::string_view s_;
  const std::string& name_;
  std::size_t pos_ = 0;
  int line_ = 0;
  int major_ = 0;
  bool binary_ = false;
  PolyData pd_;
};

}  // namespace

PolyData read_legacy_vtk_polydata(const std::string& bytes, const std::string& name) {
  return LegacyReader(bytes, name).read();
}

}  // namespace meshpde::detail
