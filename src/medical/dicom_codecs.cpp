// Encapsulated (compressed) DICOM pixel data, frame by frame. Each decoder is a
// library that checks what it reads (OpenJPEG and CharLS are fuzzed continuously
// upstream) or is written here with every length checked: RLE (PS3.5 G) is a few lines
// of PackBits. The JPEG family (baseline, extended, lossless) goes to GDCM's IJG
// builds (the only decoders of 12-bit and lossless JPEG that Debian has) after its
// header is checked here, because GDCM asserts on a header IJG warns about.
#include <charls/charls.h>
#include <fmt/format.h>
#include <openjpeg.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"

namespace meshpde::detail {

namespace {

constexpr const char* kRle = "1.2.840.10008.1.2.5";

bool starts_with(const std::string& s, const char* prefix) {
  return s.rfind(prefix, 0) == 0;
}
bool is_jpegls(const std::string& syntax) {
  return starts_with(syntax, "1.2.840.10008.1.2.4.8");
}
bool is_jpeg2000(const std::string& syntax) {
  return starts_with(syntax, "1.2.840.10008.1.2.4.9");
}

std::uint32_t le32(const std::string& s, std::size_t at) {
  const auto* p = reinterpret_cast<const unsigned char*>(s.data() + at);
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

// Whether a fragment starts a codestream of the syntax (SOI for the JPEG family and
// JPEG-LS; SOC, or a JP2 box, for JPEG 2000).
bool starts_codestream(const std::string& syntax, const char* data, std::size_t size) {
  const auto* p = reinterpret_cast<const unsigned char*>(data);
  if (size < 2) return false;
  if (is_jpeg2000(syntax)) return (p[0] == 0xff && p[1] == 0x4f) || (size >= 4 && std::memcmp(p, "\0\0\0\x0c", 4) == 0);
  return p[0] == 0xff && p[1] == 0xd8;
}

// The codestream of each frame (PS3.5 A.4): by the basic offset table when it has one
// entry a frame; else one fragment a frame, all fragments for a single frame, or a new
// frame at each fragment that starts a codestream.
std::vector<std::string> frame_streams(const DicomFile& d, const DicomElement& pixels, int frames) {
  const auto& frags = pixels.fragments;  // [0] is the offset table
  const std::size_t n = frags.size() - 1;
  const auto fragment = [&](std::size_t k) { return std::string(d.bytes, frags[k + 1].first, frags[k + 1].second); };
  std::vector<std::string> out;
  const std::size_t table = frags[0].second;
  if (table == 4 * static_cast<std::size_t>(frames) && frames > 1) {
    // Offsets from the first fragment's item tag to each frame's first fragment's.
    const std::size_t base = frags[1].first - 8;
    std::vector<std::size_t> first(static_cast<std::size_t>(frames) + 1, n);
    for (int f = 0; f < frames; ++f) {
      const std::size_t at = base + le32(d.bytes, frags[0].first + 4 * static_cast<std::size_t>(f));
      std::size_t k = 0;
      while (k < n && frags[k + 1].first - 8 != at) ++k;
      if (k == n || (f > 0 && k <= first[static_cast<std::size_t>(f) - 1]))
        throw InputError(
            fmt::format("{}: the basic offset table's entry for frame {} points at no fragment", d.name, f + 1));
      first[static_cast<std::size_t>(f)] = k;
    }
    for (int f = 0; f < frames; ++f) {
      std::string s;
      for (std::size_t k = first[static_cast<std::size_t>(f)]; k < first[static_cast<std::size_t>(f) + 1]; ++k)
        s += fragment(k);
      out.push_back(std::move(s));
    }
    return out;
  }
  if (n == static_cast<std::size_t>(frames)) {
    for (std::size_t k = 0; k < n; ++k) out.push_back(fragment(k));
    return out;
  }
  if (frames == 1) {
    std::string s;
    for (std::size_t k = 0; k < n; ++k) s += fragment(k);
    return {s};
  }
  if (d.syntax != kRle) {
    for (std::size_t k = 0; k < n; ++k) {
      if (starts_codestream(d.syntax, d.bytes.data() + frags[k + 1].first, frags[k + 1].second))
        out.emplace_back();
      else if (out.empty())
        break;
      out.back() += fragment(k);
    }
    if (out.size() == static_cast<std::size_t>(frames)) return out;
  }
  throw InputError(
      fmt::format("{}: {} fragments of compressed pixel data for {} frames, and no offset table to tell the frames "
                  "apart",
                  d.name, n, frames));
}

// A sample written as bits_allocated / 8 little-endian bytes (two's complement).
void put_sample(std::string& out, std::int64_t v, int bytes) {
  for (int b = 0; b < bytes; ++b) out += static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * b)) & 0xff);
}

// PS3.5 G: a header of 16 32-bit words (the number of segments, their offsets), then
// one PackBits segment a byte of the sample, the most significant first.
std::string decode_rle(const DicomFile& d, const std::string& s, const DicomFrame& f, int frame) {
  const int size = f.bits_allocated / 8;
  const std::size_t pixels = static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols);
  const auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}: frame {}: damaged RLE pixel data: {}", d.name, frame + 1, what));
  };
  if (s.size() < 64) fail("no segment table");
  const std::uint32_t segments = le32(s, 0);
  if (segments != static_cast<std::uint32_t>(size))
    fail(fmt::format("{} segments for samples of {} bytes", segments, size));
  std::vector<std::string> planes(segments);
  for (std::uint32_t k = 0; k < segments; ++k) {
    const std::size_t begin = le32(s, 4 + 4 * k);
    const std::size_t end = k + 1 < segments ? le32(s, 4 + 4 * (k + 1)) : s.size();
    if (begin < 64 || begin > end || end > s.size()) fail(fmt::format("segment {} lies outside the frame", k + 1));
    std::string& out = planes[k];
    out.reserve(pixels);
    for (std::size_t at = begin; at < end && out.size() < pixels;) {
      const int n = static_cast<signed char>(s[at++]);
      if (n >= 0) {
        const std::size_t count = std::min<std::size_t>(static_cast<std::size_t>(n) + 1, end - at);
        out.append(s, at, std::min(count, pixels - out.size()));
        at += count;
      } else if (n != -128) {
        if (at >= end) break;
        out.append(std::min<std::size_t>(static_cast<std::size_t>(1 - n), pixels - out.size()), s[at++]);
      }
    }
    if (out.size() < pixels) fail(fmt::format("segment {} holds {} of {} bytes", k + 1, out.size(), pixels));
  }
  std::string out(pixels * static_cast<std::size_t>(size), '\0');
  for (std::size_t i = 0; i < pixels; ++i)
    for (int b = 0; b < size; ++b)
      out[i * static_cast<std::size_t>(size) + static_cast<std::size_t>(b)] =
          planes[static_cast<std::size_t>(size - 1 - b)][i];
  return out;
}

std::string decode_jpegls(const DicomFile& d, const std::string& s, const DicomFrame& f, int frame) {
  const auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}: frame {}: damaged JPEG-LS pixel data: {}", d.name, frame + 1, what));
  };
  std::unique_ptr<charls_jpegls_decoder, decltype(&charls_jpegls_decoder_destroy)> dec(charls_jpegls_decoder_create(),
                                                                                       charls_jpegls_decoder_destroy);
  if (!dec) fail("no decoder");
  charls_frame_info info{};
  if (auto e = charls_jpegls_decoder_set_source_buffer(dec.get(), s.data(), s.size()); static_cast<int>(e) != 0)
    fail(charls_get_error_message(e));
  if (auto e = charls_jpegls_decoder_read_header(dec.get()); static_cast<int>(e) != 0)
    fail(charls_get_error_message(e));
  if (auto e = charls_jpegls_decoder_get_frame_info(dec.get(), &info); static_cast<int>(e) != 0)
    fail(charls_get_error_message(e));
  if (info.width != static_cast<std::uint32_t>(f.cols) || info.height != static_cast<std::uint32_t>(f.rows) ||
      info.component_count != 1 || info.bits_per_sample > f.bits_allocated || info.bits_per_sample > 16)
    fail(fmt::format("its frame is {} x {} of {} components of {} bits, the header's {} x {} of 1 of {} bits",
                     info.width, info.height, info.component_count, info.bits_per_sample, f.cols, f.rows,
                     f.bits_allocated));
  const int bytes = info.bits_per_sample > 8 ? 2 : 1;
  const std::size_t pixels = static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols);
  std::string raw(pixels * static_cast<std::size_t>(bytes), '\0');
  if (auto e = charls_jpegls_decoder_decode_to_buffer(dec.get(), raw.data(), raw.size(), 0); static_cast<int>(e) != 0)
    fail(charls_get_error_message(e));
  std::string out;
  out.reserve(pixels * static_cast<std::size_t>(f.bits_allocated / 8));
  const auto* p = reinterpret_cast<const unsigned char*>(raw.data());
  for (std::size_t i = 0; i < pixels; ++i)
    put_sample(out, bytes == 2 ? (p[2 * i] | p[2 * i + 1] << 8) : p[i], f.bits_allocated / 8);
  return out;
}

// OpenJPEG reads from memory through these callbacks.
struct MemoryStream {
  const unsigned char* data;
  std::size_t size, at = 0;
};
OPJ_SIZE_T opj_read(void* buffer, OPJ_SIZE_T n, void* user) {
  auto* m = static_cast<MemoryStream*>(user);
  if (m->at >= m->size) return static_cast<OPJ_SIZE_T>(-1);
  n = std::min<OPJ_SIZE_T>(n, m->size - m->at);
  std::memcpy(buffer, m->data + m->at, n);
  m->at += n;
  return n;
}
OPJ_OFF_T opj_skip(OPJ_OFF_T n, void* user) {
  auto* m = static_cast<MemoryStream*>(user);
  if (n < 0) {
    n = std::max<OPJ_OFF_T>(n, -static_cast<OPJ_OFF_T>(m->at));
  } else {
    n = std::min<OPJ_OFF_T>(n, static_cast<OPJ_OFF_T>(m->size - m->at));
  }
  m->at = static_cast<std::size_t>(static_cast<OPJ_OFF_T>(m->at) + n);
  return n;
}
OPJ_BOOL opj_seek(OPJ_OFF_T n, void* user) {
  auto* m = static_cast<MemoryStream*>(user);
  if (n < 0 || static_cast<std::size_t>(n) > m->size) return OPJ_FALSE;
  m->at = static_cast<std::size_t>(n);
  return OPJ_TRUE;
}
void opj_message(const char* msg, void* user) {
  auto* last = static_cast<std::string*>(user);
  if (last && msg) {
    *last = msg;
    while (!last->empty() && last->back() == '\n') last->pop_back();
  }
}
void opj_quiet(const char*, void*) {}

std::string decode_jpeg2000(const DicomFile& d, const std::string& s, const DicomFrame& f, int frame) {
  std::string why;
  const auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}: frame {}: damaged JPEG 2000 pixel data: {}", d.name, frame + 1,
                                 what.empty() ? std::string("cannot decode") : what));
  };
  MemoryStream m{reinterpret_cast<const unsigned char*>(s.data()), s.size()};
  const bool jp2 = s.size() >= 12 && std::memcmp(s.data(), "\0\0\0\x0cjP  \r\n\x87\n", 12) == 0;
  std::unique_ptr<opj_codec_t, decltype(&opj_destroy_codec)> codec(
      opj_create_decompress(jp2 ? OPJ_CODEC_JP2 : OPJ_CODEC_J2K), opj_destroy_codec);
  std::unique_ptr<opj_stream_t, decltype(&opj_stream_destroy)> stream(opj_stream_create(1 << 16, OPJ_TRUE),
                                                                      opj_stream_destroy);
  if (!codec || !stream) fail("no decoder");
  opj_set_error_handler(codec.get(), opj_message, &why);
  opj_set_warning_handler(codec.get(), opj_quiet, nullptr);
  opj_set_info_handler(codec.get(), opj_quiet, nullptr);
  opj_stream_set_user_data(stream.get(), &m, nullptr);
  opj_stream_set_user_data_length(stream.get(), s.size());
  opj_stream_set_read_function(stream.get(), opj_read);
  opj_stream_set_skip_function(stream.get(), opj_skip);
  opj_stream_set_seek_function(stream.get(), opj_seek);
  opj_dparameters_t params;
  opj_set_default_decoder_parameters(&params);
  if (!opj_setup_decoder(codec.get(), &params)) fail(why);
  opj_image_t* raw_image = nullptr;
  const bool header = opj_read_header(stream.get(), codec.get(), &raw_image);
  std::unique_ptr<opj_image_t, decltype(&opj_image_destroy)> image(raw_image, opj_image_destroy);
  if (!header || !image) fail(why);
  // The frame the header announces, before the codestream is decoded.
  if (image->numcomps != 1) fail(fmt::format("{} components where a grey-level image has 1", image->numcomps));
  const opj_image_comp_t& c0 = image->comps[0];
  const std::uint32_t width = image->x1 - image->x0, height = image->y1 - image->y0;
  if (width != static_cast<std::uint32_t>(f.cols) || height != static_cast<std::uint32_t>(f.rows) || c0.dx != 1 ||
      c0.dy != 1 || c0.prec < 1 || c0.prec > 16 || static_cast<int>(c0.prec) > f.bits_allocated)
    fail(fmt::format("its frame is {} x {} of {} bits, the header's {} x {} of {} bits", width, height, c0.prec, f.cols,
                     f.rows, f.bits_allocated));
  if (!opj_decode(codec.get(), stream.get(), image.get()) || !opj_end_decompress(codec.get(), stream.get())) fail(why);
  const opj_image_comp_t& c = image->comps[0];
  if (!c.data || c.w != width || c.h != height || c.factor != 0) fail("the decoded frame is not the header's");
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  std::string out;
  out.reserve(pixels * static_cast<std::size_t>(f.bits_allocated / 8));
  for (std::size_t i = 0; i < pixels; ++i) put_sample(out, c.data[i], f.bits_allocated / 8);
  return out;
}

// The JPEG (ITU T.81) header up to the first scan: markers back to back (IJG warns
// about bytes between them, and GDCM's codec asserts on any warning), every segment
// inside the stream, one frame of one component of the DICOM header's size.
void check_jpeg_header(const DicomFile& d, const std::string& s, const DicomFrame& f, int frame) {
  const auto* p = reinterpret_cast<const unsigned char*>(s.data());
  const auto fail = [&](std::size_t at, const std::string& what) {
    throw InputError(fmt::format("{}: frame {}: damaged JPEG pixel data at byte {}: {}", d.name, frame + 1, at, what));
  };
  if (s.size() < 4 || p[0] != 0xff || p[1] != 0xd8) fail(0, "no start-of-image marker");
  // A fragment is padded to an even length with a zero byte; before that, the stream
  // ends with its end-of-image marker, or it was cut short.
  std::size_t end = s.size();
  while (end > 2 && p[end - 1] == 0) --end;
  if (end < 4 || p[end - 2] != 0xff || p[end - 1] != 0xd9)
    fail(end, "no end-of-image marker at the end of the stream (the stream is cut short)");
  bool frame_seen = false;
  std::size_t at = 2;
  while (true) {
    if (at >= s.size() || p[at] != 0xff) fail(at, "bytes where a marker should be");
    while (at < s.size() && p[at] == 0xff) ++at;  // fill bytes
    if (at + 2 >= s.size()) fail(at, "the stream ends before the first scan");
    const unsigned marker = p[at];
    const std::size_t length = static_cast<std::size_t>(p[at + 1] << 8 | p[at + 2]);
    const std::size_t seg = at + 1;  // the segment's length field
    if (length < 2 || seg + length > s.size()) fail(at, fmt::format("marker {:02X} of length {}", marker, length));
    const bool sof = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (sof) {
      if (frame_seen) fail(at, "a second frame header");
      if (length < 8 + 3) fail(at, "a frame header too short for one component");
      const unsigned precision = p[seg + 2];
      const unsigned height = static_cast<unsigned>(p[seg + 3] << 8 | p[seg + 4]);
      const unsigned width = static_cast<unsigned>(p[seg + 5] << 8 | p[seg + 6]);
      const unsigned components = p[seg + 7];
      const bool lossless = marker == 0xc3 || marker == 0xc7 || marker == 0xcb || marker == 0xcf;
      const bool precision_ok =
          lossless ? precision >= 2 && precision <= 16 : precision == 8 || (precision == 12 && marker != 0xc0);
      if (components != 1 || height != static_cast<unsigned>(f.rows) || width != static_cast<unsigned>(f.cols) ||
          !precision_ok || static_cast<int>(precision) > f.bits_allocated || length != 8 + 3 * components)
        fail(at, fmt::format("its frame is {} x {} of {} components of {} bits, the header's {} x {} of 1 of {} bits",
                             width, height, components, precision, f.cols, f.rows, f.bits_allocated));
      frame_seen = true;
    } else if (marker == 0xda) {
      if (!frame_seen) fail(at, "a scan before the frame header");
      if (length != 6 + 2 * 1 || p[seg + 2] != 1) fail(at, "a scan of other than one component");
      if (seg + length >= s.size()) fail(at, "a scan without data");
      return;
    } else if (marker == 0xe0 && length >= 16 && std::memcmp(p + seg + 2, "JFIF\0", 5) == 0) {
      if (p[seg + 7] != 1) fail(at, fmt::format("JFIF version {}", p[seg + 7]));
    } else if (!(marker == 0xc4 || marker == 0xdb || marker == 0xdd || marker == 0xcc || marker == 0xfe ||
                 (marker >= 0xe0 && marker <= 0xef))) {
      fail(at, fmt::format("marker {:02X} before the first scan", marker));
    }
    at = seg + length;
  }
}

}  // namespace

std::string decode_compressed_pixels(const DicomFile& d, const DicomElement& pixels, const DicomFrame& f) {
  if (f.bits_allocated > 16)
    throw InputError(
        fmt::format("{}: compressed pixels of {} bits allocated (8 or 16 are read)", d.name, f.bits_allocated));
  const std::vector<std::string> streams = frame_streams(d, pixels, f.frames_in_file);
  std::string out;
  for (int k = 0; k < f.frames_in_file; ++k) {
    const std::string& s = streams[static_cast<std::size_t>(k)];
    if (d.syntax == kRle) {
      out += decode_rle(d, s, f, k);
    } else if (is_jpegls(d.syntax)) {
      out += decode_jpegls(d, s, f, k);
    } else if (is_jpeg2000(d.syntax)) {
      out += decode_jpeg2000(d, s, f, k);
    } else {
      check_jpeg_header(d, s, f, k);
      out += decode_jpeg_with_gdcm(d, s, f, k);
    }
  }
  return out;
}

}  // namespace meshpde::detail
