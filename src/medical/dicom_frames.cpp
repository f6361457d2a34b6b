// A DICOM file's frames (position, orientation, spacing, rescale and pixel storage of
// each image in it) and their pixels, from the data set dicom_parse.cpp parsed. Native
// transfer syntaxes are decoded here; compressed ones in dicom_codecs.cpp, after the
// Image Pixel module was checked here.
#include <fmt/format.h>

#include <cmath>
#include <fstream>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

constexpr std::uint32_t kPixelData = 0x7fe00010;
constexpr std::uint32_t kSharedGroups = 0x52009229, kPerFrameGroups = 0x52009230;

bool native_syntax(const std::string& s) {
  return s == "1.2.840.10008.1.2" || s == "1.2.840.10008.1.2.1" || s == "1.2.840.10008.1.2.2" ||
         s == "1.2.840.10008.1.2.1.99";
}

// Position, orientation, spacing and rescale, from `item` where present.
void read_geometry(const DicomFile& d, const DicomItem& item, DicomFrame& f) {
  if (const auto p = d.numbers(item, 0x00200032)) {
    if (p->size() != 3)
      throw InputError(fmt::format("{}: ImagePositionPatient has {} values, not 3", d.name, p->size()));
    f.position = Eigen::Vector3d((*p)[0], (*p)[1], (*p)[2]);
    f.has_position = true;
  }
  if (const auto o = d.numbers(item, 0x00200037)) {
    if (o->size() != 6)
      throw InputError(fmt::format("{}: ImageOrientationPatient has {} values, not 6", d.name, o->size()));
    f.row_dir = Eigen::Vector3d((*o)[0], (*o)[1], (*o)[2]);
    f.col_dir = Eigen::Vector3d((*o)[3], (*o)[4], (*o)[5]);
    f.has_orientation = true;
  }
  if (const auto s = d.numbers(item, 0x00280030)) {
    if (s->size() != 2) throw InputError(fmt::format("{}: PixelSpacing has {} values, not 2", d.name, s->size()));
    f.row_spacing = (*s)[0];
    f.col_spacing = (*s)[1];
    f.has_spacing = true;
  }
  if (const auto t = d.numbers(item, 0x00180050); t && !t->empty()) f.slice_thickness = t->front();
  if (const auto b = d.numbers(item, 0x00281052); b && !b->empty()) f.intercept = b->front();
  if (const auto m = d.numbers(item, 0x00281053); m && !m->empty()) f.slope = m->front();
}

// The functional groups of an enhanced multi-frame file that hold each geometry item:
// plane position, plane orientation, pixel measures, pixel value transformation.
void read_functional_groups(const DicomFile& d, const DicomItem& groups, DicomFrame& f) {
  for (const std::uint32_t seq : {0x00209113u, 0x00209116u, 0x00289110u, 0x00289145u})
    if (const DicomItem* i = d.first_item(groups, seq)) read_geometry(d, *i, f);
}

// The Image Pixel module, checked: a grey-level image of whole bytes a sample.
void read_pixel_module(const DicomFile& d, DicomFrame& f) {
  const DicomItem& ds = d.root;
  const auto need = [&](std::uint32_t tag, const char* what) {
    const auto v = d.us(ds, tag);
    if (!v) throw InputError(fmt::format("{}: no {} ({:04x},{:04x})", d.name, what, tag >> 16, tag & 0xffff));
    return static_cast<int>(*v);
  };
  f.rows = need(0x00280010, "Rows");
  f.cols = need(0x00280011, "Columns");
  if (f.rows <= 0 || f.cols <= 0)
    throw InputError(fmt::format("{}: an image of {} rows and {} columns", d.name, f.rows, f.cols));
  f.samples_per_pixel = static_cast<int>(d.us(ds, 0x00280002).value_or(1));
  const std::string photometric = d.text(ds, 0x00280004).value_or("MONOCHROME2");
  if (f.samples_per_pixel != 1 || (photometric != "MONOCHROME1" && photometric != "MONOCHROME2"))
    throw InputError(fmt::format("{}: a {} image of {} samples a pixel; a grey-level image is needed", d.name,
                                 photometric, f.samples_per_pixel));
  f.bits_allocated = need(0x00280100, "BitsAllocated");
  f.bits_stored = static_cast<int>(d.us(ds, 0x00280101).value_or(static_cast<unsigned>(f.bits_allocated)));
  f.high_bit = static_cast<int>(d.us(ds, 0x00280102).value_or(static_cast<unsigned>(f.bits_stored - 1)));
  const unsigned representation = d.us(ds, 0x00280103).value_or(0);
  if (f.bits_allocated != 8 && f.bits_allocated != 16 && f.bits_allocated != 32)
    throw InputError(fmt::format("{}: {} bits allocated a pixel (8, 16 or 32 are read)", d.name, f.bits_allocated));
  if (f.bits_stored < 1 || f.bits_stored > f.bits_allocated || f.high_bit >= f.bits_allocated ||
      f.high_bit + 1 < f.bits_stored || representation > 1)
    throw InputError(fmt::format("{}: {} bits stored with the high bit {} in {} allocated (pixel representation {})",
                                 d.name, f.bits_stored, f.high_bit, f.bits_allocated, representation));
  f.is_signed = representation == 1;
}

}  // namespace

bool dicom_syntax_decoded(const std::string& s) {
  for (const char* uid : {"1.2.840.10008.1.2.5", "1.2.840.10008.1.2.4.50", "1.2.840.10008.1.2.4.51",
                          "1.2.840.10008.1.2.4.57", "1.2.840.10008.1.2.4.70", "1.2.840.10008.1.2.4.80",
                          "1.2.840.10008.1.2.4.81", "1.2.840.10008.1.2.4.90", "1.2.840.10008.1.2.4.91"})
    if (s == uid) return true;
  return native_syntax(s);
}

std::vector<DicomFrame> dicom_frames(const DicomFile& d, const std::filesystem::path& file, std::string& why_not) {
  const DicomItem& ds = d.root;
  const DicomElement* pixels = ds.find(kPixelData);
  if (!pixels) {
    why_not = "no pixel data (not an image)";
    return {};
  }
  if (!dicom_syntax_decoded(d.syntax))
    throw InputError(fmt::format("{}: transfer syntax {} is not read", d.name, d.syntax));
  DicomFrame base;
  base.file = file;
  base.series_uid = d.text(ds, 0x0020000e).value_or("");
  base.description = d.text(ds, 0x0008103e).value_or("");
  base.modality = d.text(ds, 0x00080060).value_or("");
  if (const auto n = d.numbers(ds, 0x00200011); n && !n->empty() && std::abs(n->front()) < 2e9)
    base.series_number = static_cast<int>(n->front());
  read_pixel_module(d, base);
  const auto frames = d.numbers(ds, 0x00280008);
  const double count = frames && !frames->empty() ? frames->front() : 1.0;
  if (!(count >= 1 && count <= 1e6) || count != std::floor(count))
    throw InputError(fmt::format("{}: NumberOfFrames is {}", d.name, count));
  base.frames_in_file = static_cast<int>(count);
  // The pixel data hold what the header says.
  const std::size_t bytes = static_cast<std::size_t>(base.rows) * static_cast<std::size_t>(base.cols) *
                            static_cast<std::size_t>(base.frames_in_file) *
                            static_cast<std::size_t>(base.bits_allocated / 8);
  if (native_syntax(d.syntax)) {
    if (pixels->undefined || pixels->length < bytes)
      throw InputError(fmt::format("{}: {} bytes of pixel data for {} x {} x {} pixels of {} bits", d.name,
                                   pixels->length, base.cols, base.rows, base.frames_in_file, base.bits_allocated));
  } else if (pixels->fragments.size() < 2) {  // the offset table, then a fragment at least
    throw InputError(fmt::format("{}: compressed pixel data without fragments", d.name));
  }
  read_geometry(d, ds, base);

  std::vector<DicomFrame> out;
  if (const DicomElement* per = ds.find(kPerFrameGroups)) {
    // Enhanced multi-frame: each frame's geometry from its functional groups, where
    // absent from the shared ones, where absent from the top level.
    const DicomItem* shared = d.first_item(ds, kSharedGroups);
    if (per->items.size() != static_cast<std::size_t>(base.frames_in_file))
      throw InputError(fmt::format("{}: {} per-frame functional groups for {} frames", d.name, per->items.size(),
                                   base.frames_in_file));
    for (int k = 0; k < base.frames_in_file; ++k) {
      DicomFrame f = base;
      f.frame = k;
      if (shared) read_functional_groups(d, *shared, f);
      read_functional_groups(d, per->items[static_cast<std::size_t>(k)], f);
      out.push_back(f);
    }
  } else if (base.frames_in_file > 1) {
    // A legacy multi-frame image: the frames stacked from the first one's position along
    // the normal, SpacingBetweenSlices apart (SliceThickness when that is absent).
    const auto between = d.numbers(ds, 0x00180088);
    const double dz = between && !between->empty() ? between->front() : base.slice_thickness;
    if (!(dz > 0) || !std::isfinite(dz))
      throw InputError(
          fmt::format("{}: {} frames without their positions and without SpacingBetweenSlices or "
                      "SliceThickness, so they cannot be stacked",
                      d.name, base.frames_in_file));
    const Eigen::Vector3d n = base.row_dir.cross(base.col_dir);
    for (int k = 0; k < base.frames_in_file; ++k) {
      DicomFrame f = base;
      f.frame = k;
      f.position = base.position + k * dz * n;
      out.push_back(f);
    }
  } else {
    out.push_back(base);
  }
  for (const DicomFrame& f : out)
    if (!(std::isfinite(f.slope) && f.slope != 0 && std::isfinite(f.intercept)))
      throw InputError(fmt::format("{}: RescaleSlope {} and RescaleIntercept {}", d.name, f.slope, f.intercept));
  return out;
}

namespace {

// A file's bytes when it starts with the preamble; empty otherwise (read no further).
std::string part10_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", file.string()));
  std::string head(132, '\0');
  in.read(head.data(), 132);
  if (in.gcount() != 132 || head.compare(128, 4, "DICM") != 0) return {};
  return read_file_bytes(file);
}

// Stored values from their bytes: bits_stored bits ending at high_bit, sign-extended
// when signed (the bits above are overlays or padding).
std::vector<float> stored_values(const char* data, std::size_t n, const DicomFrame& f, bool big) {
  std::vector<float> out(n);
  const int size = f.bits_allocated / 8, shift = f.high_bit + 1 - f.bits_stored;
  const std::uint64_t mask = f.bits_stored >= 64 ? ~0ull : (1ull << f.bits_stored) - 1;
  const auto* p = reinterpret_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t raw = 0;
    for (int b = 0; b < size; ++b) raw |= static_cast<std::uint64_t>(p[i * size + (big ? size - 1 - b : b)]) << (8 * b);
    std::uint64_t v = (raw >> shift) & mask;
    if (f.is_signed && (v >> (f.bits_stored - 1)) & 1) {
      out[i] = static_cast<float>(static_cast<double>(v) - std::ldexp(1.0, f.bits_stored));
    } else {
      out[i] = static_cast<float>(v);
    }
  }
  return out;
}

std::vector<float> pixels_of(const DicomFile& d, const DicomFrame& f) {
  const DicomElement* pixels = d.root.find(kPixelData);
  if (!pixels) throw InputError(fmt::format("{}: no pixel data", d.name));
  const std::size_t n =
      static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols) * static_cast<std::size_t>(f.frames_in_file);
  if (native_syntax(d.syntax)) {
    // 8-bit pixels are bytes in either byte order.
    return stored_values(d.bytes.data() + pixels->offset, n, f, d.big && f.bits_allocated > 8);
  }
  const std::string decoded = decode_compressed_pixels(d, *pixels, f);
  if (decoded.size() < n * static_cast<std::size_t>(f.bits_allocated / 8))
    throw InputError(
        fmt::format("{}: the compressed pixel data decode to {} bytes for {} pixels", d.name, decoded.size(), n));
  return stored_values(decoded.data(), n, f, false);
}

}  // namespace

std::vector<DicomFrame> read_dicom_frames(const std::filesystem::path& file, std::string& why_not) {
  std::string bytes = part10_bytes(file);
  if (bytes.empty()) {
    why_not = "not a DICOM Part 10 file (no DICM preamble)";
    return {};
  }
  const DicomFile d = parse_dicom(std::move(bytes), file.string());
  return dicom_frames(d, file, why_not);
}

std::vector<DicomFrame> read_dicom_frames_from_memory(const std::string& bytes, const std::string& name,
                                                      std::string& why_not) {
  if (bytes.size() < 132 || bytes.compare(128, 4, "DICM") != 0) {
    why_not = "not a DICOM Part 10 file (no DICM preamble)";
    return {};
  }
  return dicom_frames(parse_dicom(bytes, name), name, why_not);
}

std::vector<float> read_dicom_pixels(const std::filesystem::path& file, const DicomFrame& frame) {
  std::string bytes = part10_bytes(file);
  if (bytes.empty()) throw InputError(fmt::format("{}: not a DICOM Part 10 file (no DICM preamble)", file.string()));
  return pixels_of(parse_dicom(std::move(bytes), file.string()), frame);
}

std::vector<float> read_dicom_pixels_from_memory(const std::string& bytes, const std::string& name,
                                                 const DicomFrame& frame) {
  return pixels_of(parse_dicom(bytes, name), frame);
}

}  // namespace meshpde::detail
