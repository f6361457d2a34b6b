// A DICOM Part 10 file's data set, parsed by meshpde itself: every element's tag, value
// representation and where its value lies, sequences and their items nested, the
// fragments of encapsulated pixel data. GDCM (Debian builds it with its assertions on)
// aborted the process on damaged and inconsistent files in the dicom fuzz target: a
// truncated file, a length past its container, a value representation it did not
// expect, a sequence without the item it assumes. So the headers are read here, every
// length checked against the bytes present; GDCM only decodes JPEG pixels
// (dicom_codecs.cpp).
#include <fmt/format.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <sstream>
#include <string>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

constexpr std::uint32_t kUndefined = 0xffffffffu;
constexpr int kMaxDepth = 32;
constexpr std::size_t kMaxElements = 1u << 22;

std::uint32_t tag_of(std::uint16_t group, std::uint16_t element) {
  return static_cast<std::uint32_t>(group) << 16 | element;
}

// The value representations of DICOM PS3.5 (6.2).
bool known_vr(const char* vr) {
  for (const char* v :
       {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT", "OB", "OD", "OF", "OL", "OV",
        "OW", "PN", "SH", "SL", "SQ", "SS", "ST", "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"})
    if (std::memcmp(vr, v, 2) == 0) return true;
  return false;
}

bool long_vr(const char* vr) {
  for (const char* v : {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"})
    if (std::memcmp(vr, v, 2) == 0) return true;
  return false;
}

// The value representations of the elements this reader uses: an explicit file that
// gives another is refused (a reader trusting it would take text for numbers).
const char* expected_vr(std::uint32_t tag) {
  switch (tag) {
    case 0x00020010:
    case 0x00080016:
    case 0x0020000e:
      return "UI";
    case 0x00080060:
    case 0x00280004:
      return "CS";
    case 0x0008103e:
      return "LO";
    case 0x00180050:
    case 0x00180088:
    case 0x00200032:
    case 0x00200037:
    case 0x00280030:
    case 0x00281052:
    case 0x00281053:
      return "DS";
    case 0x00200011:
    case 0x00280008:
      return "IS";
    case 0x00280002:
    case 0x00280006:
    case 0x00280010:
    case 0x00280011:
    case 0x00280100:
    case 0x00280101:
    case 0x00280102:
    case 0x00280103:
      return "US";
    case 0x52009229:
    case 0x52009230:
    case 0x00209113:
    case 0x00209116:
    case 0x00289110:
    case 0x00289145:
      return "SQ";
    default:
      return nullptr;
  }
}

struct Walker {
  const unsigned char* data;
  std::size_t size;
  bool big = false;
  bool implicit = false;
  const std::string& name;
  std::size_t count = 0;

  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    throw InputError(fmt::format("{}: damaged DICOM file at byte {}: {}", name, at, what));
  }
  std::uint16_t u16(std::size_t at, bool big_endian) const {
    return big_endian ? static_cast<std::uint16_t>(data[at] << 8 | data[at + 1])
                      : static_cast<std::uint16_t>(data[at] | data[at + 1] << 8);
  }
  std::uint32_t u32(std::size_t at, bool big_endian) const {
    const std::uint32_t a = data[at], b = data[at + 1], c = data[at + 2], d = data[at + 3];
    return big_endian ? (a << 24 | b << 16 | c << 8 | d) : (a | b << 8 | c << 16 | d << 24);
  }

  struct Header {
    std::uint16_t group = 0, element = 0;
    char vr[3] = {0, 0, 0};
    std::uint32_t length = 0;
    std::size_t value = 0;  // offset of the value
  };

  // Items and delimiters have no VR in any transfer syntax: tag and a 4-byte length.
  Header header(std::size_t at, std::size_t end, bool big_endian, bool implicit_vr) const {
    Header h;
    if (end < at || end - at < 8) fail(at, fmt::format("an element header needs 8 bytes, {} remain", end - at));
    h.group = u16(at, big_endian);
    h.element = u16(at + 2, big_endian);
    if (implicit_vr || h.group == 0xfffe) {
      h.length = u32(at + 4, big_endian);
      h.value = at + 8;
      return h;
    }
    h.vr[0] = static_cast<char>(data[at + 4]);
    h.vr[1] = static_cast<char>(data[at + 5]);
    if (!known_vr(h.vr))
      fail(at, fmt::format("element ({:04x},{:04x}) has no known value representation", h.group, h.element));
    if (long_vr(h.vr)) {
      if (end - at < 12) fail(at, fmt::format("element ({:04x},{:04x}): its header is cut off", h.group, h.element));
      h.length = u32(at + 8, big_endian);
      h.value = at + 12;
    } else {
      h.length = u16(at + 6, big_endian);
      h.value = at + 8;
    }
    return h;
  }

  // The items of a sequence (or the fragments of encapsulated pixel data, into `e`) from
  // `at`: up to `end` when the sequence has a length, else up to its delimiter. Returns
  // the offset after the sequence.
  std::size_t items(std::size_t at, std::size_t end, bool undefined, bool fragments, int depth, DicomElement& e) {
    if (depth > kMaxDepth) fail(at, fmt::format("sequences nested more than {} deep", kMaxDepth));
    while (true) {
      if (!undefined && at == end) return at;
      const Header h = header(at, end, big, true);
      if (h.group != 0xfffe)
        fail(at, fmt::format("({:04x},{:04x}) where a sequence item should be", h.group, h.element));
      if (h.element == 0xe0dd) {
        if (!undefined) fail(at, "a sequence delimiter in a sequence of defined length");
        if (h.length != 0) fail(at, "a sequence delimiter of non-zero length");
        return h.value;
      }
      if (h.element != 0xe000) fail(at, fmt::format("(fffe,{:04x}) where a sequence item should be", h.element));
      if (h.length == kUndefined) {
        if (fragments) fail(at, "a pixel data fragment of undefined length");
        e.items.emplace_back();
        at = elements(h.value, end, true, depth + 1, e.items.back());
      } else {
        if (h.length > end - h.value)
          fail(at, fmt::format("an item of {} bytes where {} remain", h.length, end - h.value));
        if (fragments) {
          e.fragments.emplace_back(h.value, h.length);
        } else {
          e.items.emplace_back();
          elements(h.value, h.value + h.length, false, depth + 1, e.items.back());
        }
        at = h.value + h.length;
      }
    }
  }

  // Data elements from `at` to `end`, or to an item delimiter when `in_undefined_item`,
  // into `item`. Returns the offset after them (after the delimiter).
  std::size_t elements(std::size_t at, std::size_t end, bool in_undefined_item, int depth, DicomItem& item) {
    if (depth > kMaxDepth) fail(at, fmt::format("sequences nested more than {} deep", kMaxDepth));
    while (at < end || in_undefined_item) {
      const Header h = header(at, end, big, implicit);
      if (++count > kMaxElements) fail(at, fmt::format("more than {} elements", kMaxElements));
      if (h.group == 0xfffe) {
        if (h.element == 0xe00d && in_undefined_item) {
          if (h.length != 0) fail(at, "an item delimiter of non-zero length");
          return h.value;
        }
        fail(at, fmt::format("(fffe,{:04x}) outside a sequence", h.element));
      }
      DicomElement e;
      e.tag = tag_of(h.group, h.element);
      std::memcpy(e.vr, h.vr, 3);
      // UN is what a tool writes for an element it did not know; its value is the same
      // bytes, so it is read as the element's own VR (a sequence excepted).
      const char* want = expected_vr(e.tag);
      const bool unknown_vr = std::memcmp(h.vr, "UN", 2) == 0 && want && std::memcmp(want, "SQ", 2) != 0;
      if (want && !implicit && !unknown_vr && std::memcmp(h.vr, want, 2) != 0)
        fail(at, fmt::format("element ({:04x},{:04x}) has value representation {}, not {}", h.group, h.element, h.vr,
                             want));
      const bool pixel_data = e.tag == 0x7fe00010;
      const bool sequence_tag = want && std::memcmp(want, "SQ", 2) == 0;
      if (h.length == kUndefined) {
        const bool sequence = implicit || std::memcmp(h.vr, "SQ", 2) == 0 || std::memcmp(h.vr, "UN", 2) == 0;
        const bool encapsulated =
            !implicit && pixel_data && (std::memcmp(h.vr, "OB", 2) == 0 || std::memcmp(h.vr, "OW", 2) == 0);
        if (!sequence && !encapsulated)
          fail(at, fmt::format("element ({:04x},{:04x}) of VR {} has an undefined length", h.group, h.element, h.vr));
        e.undefined = true;
        e.offset = h.value;
        at = items(h.value, end, true, encapsulated || (implicit && pixel_data), depth + 1, e);
        e.length = at - h.value;
        item.elements.push_back(std::move(e));
        continue;
      }
      if (h.length > end - h.value)
        fail(at, fmt::format("element ({:04x},{:04x}) holds {} bytes where {} remain (a truncated file?)", h.group,
                             h.element, h.length, end - h.value));
      e.offset = h.value;
      e.length = h.length;
      // A sequence of defined length: its items too. Implicit VR does not say which
      // elements are sequences; the ones read here are, and a value that starts with an
      // item tag is taken for one.
      const bool sq = !implicit && std::memcmp(h.vr, "SQ", 2) == 0;
      const bool looks_like_items =
          implicit && !pixel_data && h.length >= 8 && u16(h.value, big) == 0xfffe && u16(h.value + 2, big) == 0xe000;
      if (implicit && sequence_tag && h.length > 0 && !looks_like_items)
        fail(at, fmt::format("element ({:04x},{:04x}) should be a sequence of items", h.group, h.element));
      if (sq || looks_like_items) items(h.value, h.value + h.length, false, false, depth + 1, e);
      at = h.value + h.length;
      item.elements.push_back(std::move(e));
    }
    if (in_undefined_item) fail(at, "an item without its delimiter");
    return at;
  }
};

std::string inflate_raw(const unsigned char* data, std::size_t size, const std::string& name) {
  z_stream z{};
  if (inflateInit2(&z, -15) != Z_OK) throw InputError(fmt::format("{}: cannot start zlib", name));
  std::string out;
  const std::size_t limit = inflated_bound(size);
  z.next_in = const_cast<Bytef*>(data);
  z.avail_in = static_cast<uInt>(size);
  char buf[1 << 16];
  int rc = Z_OK;
  while (rc == Z_OK) {
    z.next_out = reinterpret_cast<Bytef*>(buf);
    z.avail_out = sizeof buf;
    rc = inflate(&z, Z_NO_FLUSH);
    out.append(buf, sizeof buf - z.avail_out);
    if (out.size() > limit) rc = Z_DATA_ERROR;
    if (rc == Z_BUF_ERROR && z.avail_in == 0) break;  // the input is used up
  }
  inflateEnd(&z);
  if (rc != Z_STREAM_END && rc != Z_BUF_ERROR)
    throw InputError(fmt::format("{}: damaged deflated DICOM data set", name));
  return out;
}

}  // namespace

const DicomElement* DicomItem::find(std::uint32_t tag) const {
  for (const auto& e : elements)
    if (e.tag == tag) return &e;
  return nullptr;
}

DicomFile parse_dicom(std::string bytes, const std::string& name) {
  if (bytes.size() < 132 || bytes.compare(128, 4, "DICM") != 0)
    throw InputError(fmt::format("{}: not a DICOM Part 10 file (no DICM preamble)", name));
  DicomFile file;
  file.name = name;
  file.bytes = std::move(bytes);
  const auto* data = reinterpret_cast<const unsigned char*>(file.bytes.data());
  Walker meta{data, file.bytes.size(), false, false, name};
  // The file meta information: explicit VR little endian, group 0002.
  std::size_t at = 132;
  while (at + 8 <= file.bytes.size() && meta.u16(at, false) == 0x0002) {
    const Walker::Header h = meta.header(at, file.bytes.size(), false, false);
    if (h.length == kUndefined || h.length > file.bytes.size() - h.value)
      meta.fail(at, fmt::format("meta element (0002,{:04x}) holds {} bytes where {} remain", h.element, h.length,
                                file.bytes.size() - h.value));
    if (h.element == 0x0010) {
      file.syntax.assign(file.bytes, h.value, h.length);
      while (!file.syntax.empty() && (file.syntax.back() == '\0' || file.syntax.back() == ' ')) file.syntax.pop_back();
    }
    at = h.value + h.length;
  }
  if (file.syntax.empty()) meta.fail(at, "no transfer syntax in the file meta information");
  if (file.syntax.size() > 64 || file.syntax.find_first_not_of("0123456789.") != std::string::npos)
    meta.fail(at, "the transfer syntax is not a UID (digits and dots)");
  if (at >= file.bytes.size()) meta.fail(at, "no data set after the file meta information");
  file.big = file.syntax == "1.2.840.10008.1.2.2";
  file.implicit = file.syntax == "1.2.840.10008.1.2";
  if (file.syntax == "1.2.840.10008.1.2.1.99") {  // deflated explicit VR little endian
    file.bytes = file.bytes.substr(0, at) + inflate_raw(data + at, file.bytes.size() - at, name);
    data = reinterpret_cast<const unsigned char*>(file.bytes.data());
  }
  Walker w{data, file.bytes.size(), file.big, file.implicit, name};
  w.elements(at, file.bytes.size(), false, 0, file.root);
  return file;
}

std::optional<std::string> DicomFile::text(const DicomItem& item, std::uint32_t tag) const {
  const DicomElement* e = item.find(tag);
  if (!e || e->undefined || e->length == 0) return std::nullopt;
  std::string s(bytes, e->offset, e->length);
  const auto end = s.find_last_not_of(std::string(" \0", 2));
  s.erase(end == std::string::npos ? 0 : end + 1);
  const auto begin = s.find_first_not_of(' ');
  return begin == std::string::npos ? std::string() : s.substr(begin);
}

std::optional<std::vector<double>> DicomFile::numbers(const DicomItem& item, std::uint32_t tag) const {
  const auto t = text(item, tag);
  if (!t) return std::nullopt;
  std::vector<double> v;
  std::stringstream ss(*t);
  std::string part;
  while (std::getline(ss, part, '\\')) {
    char* end = nullptr;
    const double x = std::strtod(part.c_str(), &end);
    while (end && *end == ' ') ++end;
    if (part.empty() || *end != '\0' || !std::isfinite(x))
      throw InputError(fmt::format("{}: element ({:04x},{:04x}) holds '{}', not a number", name, tag >> 16,
                                   tag & 0xffff, part.substr(0, 40)));
    v.push_back(x);
  }
  return v;
}

std::optional<unsigned> DicomFile::us(const DicomItem& item, std::uint32_t tag) const {
  const DicomElement* e = item.find(tag);
  if (!e || e->undefined || e->length == 0) return std::nullopt;
  if (e->length != 2)
    throw InputError(fmt::format("{}: element ({:04x},{:04x}) holds {} bytes, not one unsigned short", name, tag >> 16,
                                 tag & 0xffff, e->length));
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data() + e->offset);
  return big ? static_cast<unsigned>(p[0] << 8 | p[1]) : static_cast<unsigned>(p[0] | p[1] << 8);
}

const DicomItem* DicomFile::first_item(const DicomItem& item, std::uint32_t tag) const {
  const DicomElement* e = item.find(tag);
  return e && !e->items.empty() ? &e->items.front() : nullptr;
}

}  // namespace meshpde::detail
