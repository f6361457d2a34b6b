// The structure of a DICOM Part 10 file, walked before GDCM sees its bytes. Debian's
// GDCM is built with its assertions on, and a truncated file or an element whose length
// runs past its container aborts the process inside GDCM's parser (found by the dicom
// fuzz target). This walk checks what the parser relies on: every element header and
// value lies inside its file, item or sequence; undefined lengths only where DICOM
// allows them and always closed by their delimiter; items only inside sequences; at
// most kMaxDepth nested sequences. It reads no values but the transfer syntax.
#include <fmt/format.h>
#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <string>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

constexpr std::uint32_t kUndefined = 0xffffffffu;
constexpr int kMaxDepth = 32;

struct Walker {
  const unsigned char* data;
  std::size_t size;
  bool big = false;       // explicit VR big endian
  bool implicit = false;  // implicit VR little endian
  const std::string& name;

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
  static bool is_item_tag(std::uint16_t group) { return group == 0xfffe; }

  // The value representations of DICOM PS3.5 (6.2); GDCM misreads a file whose element
  // has another (it takes the data set for implicit VR and asserts).
  static bool known_vr(const char* vr) {
    for (const char* v : {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT", "OB", "OD", "OF", "OL",
                          "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST", "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US",
                          "UT", "UV"})
      if (std::memcmp(vr, v, 2) == 0) return true;
    return false;
  }

  static bool long_vr(const char* vr) {
    for (const char* v : {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"})
      if (std::memcmp(vr, v, 2) == 0) return true;
    return false;
  }

  Header header(std::size_t at, std::size_t end, bool big_endian, bool implicit_vr) const {
    Header h;
    if (end - at < 8) fail(at, fmt::format("an element header needs 8 bytes, {} remain", end - at));
    h.group = u16(at, big_endian);
    h.element = u16(at + 2, big_endian);
    if (implicit_vr || is_item_tag(h.group)) {
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

  // The items of a sequence (or the fragments of encapsulated pixel data) from `at`:
  // up to `end` when the sequence has a length, else up to its delimiter. Returns the
  // offset after the sequence.
  std::size_t items(std::size_t at, std::size_t end, bool undefined, bool fragments, int depth) const {
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
        at = elements(h.value, end, true, depth + 1);
      } else {
        if (h.length > end - h.value)
          fail(at, fmt::format("an item of {} bytes where {} remain", h.length, end - h.value));
        if (!fragments) elements(h.value, h.value + h.length, false, depth + 1);
        at = h.value + h.length;
      }
    }
  }

  // Data elements from `at` to `end`, or to an item delimiter when `in_undefined_item`.
  // Returns the offset after them (after the delimiter).
  std::size_t elements(std::size_t at, std::size_t end, bool in_undefined_item, int depth) const {
    if (depth > kMaxDepth) fail(at, fmt::format("sequences nested more than {} deep", kMaxDepth));
    while (at < end || in_undefined_item) {
      const Header h = header(at, end, big, implicit);
      if (h.group == 0xfffe) {
        if (h.element == 0xe00d && in_undefined_item) {
          if (h.length != 0) fail(at, "an item delimiter of non-zero length");
          return h.value;
        }
        fail(at, fmt::format("(fffe,{:04x}) outside a sequence", h.element));
      }
      const bool pixel_data = h.group == 0x7fe0 && h.element == 0x0010;
      if (h.length == kUndefined) {
        const bool sequence = implicit || std::memcmp(h.vr, "SQ", 2) == 0 || std::memcmp(h.vr, "UN", 2) == 0;
        const bool encapsulated =
            !implicit && pixel_data && (std::memcmp(h.vr, "OB", 2) == 0 || std::memcmp(h.vr, "OW", 2) == 0);
        if (!sequence && !encapsulated)
          fail(at, fmt::format("element ({:04x},{:04x}) of VR {} has an undefined length", h.group, h.element, h.vr));
        at = items(h.value, end, true, encapsulated || (implicit && pixel_data), depth + 1);
        continue;
      }
      if (h.length > end - h.value)
        fail(at, fmt::format("element ({:04x},{:04x}) holds {} bytes where {} remain (a truncated file?)", h.group,
                             h.element, h.length, end - h.value));
      // A sequence of defined length: its items too. Implicit VR does not say which
      // elements are sequences; a value that starts with an item tag is one.
      const bool sq = !implicit && std::memcmp(h.vr, "SQ", 2) == 0;
      const bool looks_like_items =
          implicit && !pixel_data && h.length >= 8 && u16(h.value, big) == 0xfffe && u16(h.value + 2, big) == 0xe000;
      if (sq || looks_like_items) items(h.value, h.value + h.length, false, false, depth + 1);
      at = h.value + h.length;
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

void check_dicom_structure(const std::string& bytes, const std::string& name) {
  if (bytes.size() < 132 || bytes.compare(128, 4, "DICM") != 0)
    throw InputError(fmt::format("{}: not a DICOM Part 10 file (no DICM preamble)", name));
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  Walker meta{data, bytes.size(), false, false, name};
  // The file meta information: explicit VR little endian, group 0002.
  std::size_t at = 132;
  std::string syntax;
  while (at + 8 <= bytes.size() && meta.u16(at, false) == 0x0002) {
    const Walker::Header h = meta.header(at, bytes.size(), false, false);
    if (h.length == kUndefined || h.length > bytes.size() - h.value)
      meta.fail(at, fmt::format("meta element (0002,{:04x}) holds {} bytes where {} remain", h.element, h.length,
                                bytes.size() - h.value));
    if (h.element == 0x0010) {
      syntax.assign(bytes, h.value, h.length);
      while (!syntax.empty() && (syntax.back() == '\0' || syntax.back() == ' ')) syntax.pop_back();
    }
    at = h.value + h.length;
  }
  if (syntax.empty()) meta.fail(at, "no transfer syntax in the file meta information");
  if (syntax.size() > 64 || syntax.find_first_not_of("0123456789.") != std::string::npos)
    meta.fail(at, "the transfer syntax is not a UID (digits and dots)");
  if (at >= bytes.size()) meta.fail(at, "no data set after the file meta information");
  if (syntax == "1.2.840.10008.1.2.1.99") {  // deflated explicit VR little endian
    const std::string inflated = inflate_raw(data + at, bytes.size() - at, name);
    const Walker w{reinterpret_cast<const unsigned char*>(inflated.data()), inflated.size(), false, false, name};
    w.elements(0, inflated.size(), false, 0);
    return;
  }
  const Walker w{data, bytes.size(), syntax == "1.2.840.10008.1.2.2", syntax == "1.2.840.10008.1.2", name};
  w.elements(at, bytes.size(), false, 0);
}

}  // namespace meshpde::detail
