// The one translation unit that includes GDCM: a DICOM file's frames (header values
// read up to the pixel data) and its decoded pixels. Bytes reach GDCM only after
// check_dicom_structure() has walked them (GDCM asserts on damaged files), and GDCM's
// exceptions become InputError.
#include <fmt/format.h>
#include <gdcmAttribute.h>
#include <gdcmDataSet.h>
#include <gdcmImage.h>
#include <gdcmImageHelper.h>
#include <gdcmImageReader.h>
#include <gdcmMediaStorage.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>

#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"
#include "volume_formats.h"

namespace meshpde::detail {

namespace {

const gdcm::Tag kPixelData(0x7fe0, 0x0010);
const gdcm::Tag kSharedGroups(0x5200, 0x9229);
const gdcm::Tag kPerFrameGroups(0x5200, 0x9230);

// GDCM prints its warnings and errors to stderr ("This Enhanced Multiframe is not
// supported for now" while it reads one we read); what went wrong reaches the user as
// our InputError instead.
void quiet_gdcm() {
  static const bool once = [] {
    gdcm::Trace::DebugOff();
    gdcm::Trace::WarningOff();
    gdcm::Trace::ErrorOff();
    return true;
  }();
  (void)once;
}

// The DICM magic of Part 10 after the 128-byte preamble.
bool has_preamble(const std::string& bytes) {
  return bytes.size() >= 132 && bytes.compare(128, 4, "DICM") == 0;
}

// A file's bytes when it starts with the preamble; empty otherwise (read no further).
std::string part10_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open for reading", file.string()));
  std::string head(132, '\0');
  in.read(head.data(), 132);
  if (in.gcount() != 132 || !has_preamble(head)) return {};
  in.clear();
  in.seekg(0);
  return read_file_bytes(file);
}

// The text of an element (DS, IS, CS, LO, UI...), without the padding DICOM allows.
std::optional<std::string> text(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  if (!ds.FindDataElement(tag)) return std::nullopt;
  const gdcm::DataElement& de = ds.GetDataElement(tag);
  const gdcm::ByteValue* bv = de.GetByteValue();
  if (!bv || bv->GetLength() == 0) return std::nullopt;
  std::string s(bv->GetPointer(), bv->GetLength());
  const auto end = s.find_last_not_of(std::string(" \0", 2));
  s.erase(end == std::string::npos ? 0 : end + 1);
  const auto begin = s.find_first_not_of(' ');
  return begin == std::string::npos ? std::string() : s.substr(begin);
}

// The numbers of a DS or IS element ("a\b\c"); nullopt when absent.
std::optional<std::vector<double>> numbers(const gdcm::DataSet& ds, const gdcm::Tag& tag, const std::string& name) {
  const auto t = text(ds, tag);
  if (!t) return std::nullopt;
  std::vector<double> v;
  std::stringstream ss(*t);
  std::string item;
  while (std::getline(ss, item, '\\')) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    while (end && *end == ' ') ++end;
    if (item.empty() || *end != '\0' || !std::isfinite(x))
      throw InputError(fmt::format("{}: element ({:04x},{:04x}) holds '{}', not a number", name, tag.GetGroup(),
                                   tag.GetElement(), item.substr(0, 40)));
    v.push_back(x);
  }
  return v;
}

std::optional<double> number(const gdcm::DataSet& ds, const gdcm::Tag& tag, const std::string& name) {
  const auto v = numbers(ds, tag, name);
  if (!v || v->empty()) return std::nullopt;
  return v->front();
}

// The first item's data set of a sequence element, or null.
const gdcm::DataSet* item(const gdcm::DataSet& ds, const gdcm::Tag& tag, std::size_t index = 1) {
  if (!ds.FindDataElement(tag)) return nullptr;
  const gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(tag).GetValueAsSQ();
  if (!sq || sq->GetNumberOfItems() < index) return nullptr;
  return &sq->GetItem(index).GetNestedDataSet();  // items count from 1
}

// Position, orientation, spacing and rescale of a frame, from `ds` where present.
void read_geometry(const gdcm::DataSet& ds, DicomFrame& f, const std::string& name) {
  if (const auto p = numbers(ds, gdcm::Tag(0x0020, 0x0032), name)) {
    if (p->size() != 3) throw InputError(fmt::format("{}: ImagePositionPatient has {} values, not 3", name, p->size()));
    f.position = Eigen::Vector3d((*p)[0], (*p)[1], (*p)[2]);
    f.has_position = true;
  }
  if (const auto o = numbers(ds, gdcm::Tag(0x0020, 0x0037), name)) {
    if (o->size() != 6)
      throw InputError(fmt::format("{}: ImageOrientationPatient has {} values, not 6", name, o->size()));
    f.row_dir = Eigen::Vector3d((*o)[0], (*o)[1], (*o)[2]);
    f.col_dir = Eigen::Vector3d((*o)[3], (*o)[4], (*o)[5]);
    f.has_orientation = true;
  }
  if (const auto s = numbers(ds, gdcm::Tag(0x0028, 0x0030), name)) {
    if (s->size() != 2) throw InputError(fmt::format("{}: PixelSpacing has {} values, not 2", name, s->size()));
    f.row_spacing = (*s)[0];
    f.col_spacing = (*s)[1];
    f.has_spacing = true;
  }
  if (const auto t = number(ds, gdcm::Tag(0x0018, 0x0050), name)) f.slice_thickness = *t;
  if (const auto b = number(ds, gdcm::Tag(0x0028, 0x1052), name)) f.intercept = *b;
  if (const auto m = number(ds, gdcm::Tag(0x0028, 0x1053), name)) f.slope = *m;
}

// The functional groups of an enhanced multi-frame file that hold each geometry item:
// plane position, plane orientation, pixel measures, pixel value transformation.
void read_functional_groups(const gdcm::DataSet& groups, DicomFrame& f, const std::string& name) {
  for (const gdcm::Tag& seq :
       {gdcm::Tag(0x0020, 0x9113), gdcm::Tag(0x0020, 0x9116), gdcm::Tag(0x0028, 0x9110), gdcm::Tag(0x0028, 0x9145)})
    if (const gdcm::DataSet* d = item(groups, seq)) read_geometry(*d, f, name);
}

std::vector<DicomFrame> frames_of(gdcm::Reader& reader, const std::filesystem::path& file, const std::string& name,
                                  std::string& why_not) {
  const gdcm::File& gf = reader.GetFile();
  const gdcm::DataSet& ds = gf.GetDataSet();
  gdcm::MediaStorage ms;
  ms.SetFromFile(gf);
  if (ms == gdcm::MediaStorage::MediaStorageDirectoryStorage) {
    why_not = "a DICOMDIR (the series are read from their files)";
    return {};
  }
  if (!ds.FindDataElement(kPixelData)) {
    why_not = "no pixel data (not an image)";
    return {};
  }
  DicomFrame base;
  base.file = file;
  base.series_uid = text(ds, gdcm::Tag(0x0020, 0x000e)).value_or("");
  base.description = text(ds, gdcm::Tag(0x0008, 0x103e)).value_or("");
  base.modality = text(ds, gdcm::Tag(0x0008, 0x0060)).value_or("");
  if (const auto n = number(ds, gdcm::Tag(0x0020, 0x0011), name)) base.series_number = static_cast<int>(*n);
  {
    gdcm::Attribute<0x0028, 0x0010> rows;
    gdcm::Attribute<0x0028, 0x0011> cols;
    gdcm::Attribute<0x0028, 0x0002> samples;
    rows.SetFromDataSet(ds);
    cols.SetFromDataSet(ds);
    samples.SetFromDataSet(ds);
    base.rows = rows.GetValue();
    base.cols = cols.GetValue();
    base.samples_per_pixel = ds.FindDataElement(samples.GetTag()) ? samples.GetValue() : 1;
  }
  if (base.rows <= 0 || base.cols <= 0)
    throw InputError(fmt::format("{}: an image of {} rows and {} columns", name, base.rows, base.cols));
  const double frames = number(ds, gdcm::Tag(0x0028, 0x0008), name).value_or(1.0);
  if (!(frames >= 1 && frames <= 1e6) || frames != std::floor(frames))
    throw InputError(fmt::format("{}: NumberOfFrames is {}", name, frames));
  base.frames_in_file = static_cast<int>(frames);
  read_geometry(ds, base, name);

  std::vector<DicomFrame> out;
  if (ds.FindDataElement(kPerFrameGroups)) {
    // Enhanced multi-frame: each frame's geometry from its functional groups, where
    // absent from the shared ones, where absent from the top level.
    const gdcm::DataSet* shared = item(ds, kSharedGroups);
    const gdcm::SmartPointer<gdcm::SequenceOfItems> per = ds.GetDataElement(kPerFrameGroups).GetValueAsSQ();
    if (!per || per->GetNumberOfItems() != static_cast<std::size_t>(base.frames_in_file))
      throw InputError(fmt::format("{}: {} per-frame functional groups for {} frames", name,
                                   per ? per->GetNumberOfItems() : 0, base.frames_in_file));
    for (int k = 0; k < base.frames_in_file; ++k) {
      DicomFrame f = base;
      f.frame = k;
      if (shared) read_functional_groups(*shared, f, name);
      read_functional_groups(per->GetItem(static_cast<std::size_t>(k) + 1).GetNestedDataSet(), f, name);
      out.push_back(f);
    }
    return out;
  }
  if (base.frames_in_file > 1) {
    // A legacy multi-frame image: the frames stacked from the first one's position along
    // the normal, SpacingBetweenSlices apart (SliceThickness when that is absent).
    const double dz =
        number(ds, gdcm::Tag(0x0018, 0x0088), name).value_or(base.slice_thickness > 0 ? base.slice_thickness : 1.0);
    const Eigen::Vector3d n = base.row_dir.cross(base.col_dir);
    for (int k = 0; k < base.frames_in_file; ++k) {
      DicomFrame f = base;
      f.frame = k;
      f.position = base.position + k * dz * n;
      out.push_back(f);
    }
    return out;
  }
  out.push_back(base);
  return out;
}

std::vector<DicomFrame> read_frames(const std::string& bytes, const std::filesystem::path& file,
                                    const std::string& name, std::string& why_not) {
  if (!has_preamble(bytes)) {
    why_not = "not a DICOM Part 10 file (no DICM preamble)";
    return {};
  }
  check_dicom_structure(bytes, name);
  quiet_gdcm();
  std::istringstream in(bytes);
  gdcm::Reader reader;
  reader.SetStream(in);
  try {
    if (!reader.ReadUpToTag(kPixelData))
      throw InputError(fmt::format("{}: damaged DICOM file (GDCM cannot parse it)", name));
    return frames_of(reader, file, name, why_not);
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: damaged DICOM file ({})", name, e.what()));
  }
}

Element element_of(const gdcm::PixelFormat& pf, const std::string& name) {
  switch (pf.GetScalarType()) {
    case gdcm::PixelFormat::UINT8:
      return Element::U8;
    case gdcm::PixelFormat::INT8:
      return Element::I8;
    case gdcm::PixelFormat::UINT12:
    case gdcm::PixelFormat::UINT16:
      return Element::U16;
    case gdcm::PixelFormat::INT12:
    case gdcm::PixelFormat::INT16:
      return Element::I16;
    case gdcm::PixelFormat::UINT32:
      return Element::U32;
    case gdcm::PixelFormat::INT32:
      return Element::I32;
    case gdcm::PixelFormat::UINT64:
      return Element::U64;
    case gdcm::PixelFormat::INT64:
      return Element::I64;
    case gdcm::PixelFormat::FLOAT32:
      return Element::F32;
    case gdcm::PixelFormat::FLOAT64:
      return Element::F64;
    default:
      throw InputError(fmt::format("{}: pixels of type {} are not read", name, pf.GetScalarTypeAsString()));
  }
}

std::vector<float> decode(const std::string& bytes, const std::string& name, int rows, int cols, int frames) {
  check_dicom_structure(bytes, name);
  quiet_gdcm();
  std::istringstream in(bytes);
  gdcm::ImageReader reader;
  reader.SetStream(in);
  try {
    if (!reader.Read()) throw InputError(fmt::format("{}: its image cannot be read (damaged DICOM?)", name));
    const gdcm::Image& image = reader.GetImage();
    const gdcm::PixelFormat& pf = image.GetPixelFormat();
    if (pf.GetSamplesPerPixel() != 1)
      throw InputError(
          fmt::format("{}: {} samples a pixel (colour); a grey-level image is needed", name, pf.GetSamplesPerPixel()));
    const Element type = element_of(pf, name);
    const std::size_t pixels =
        static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * static_cast<std::size_t>(frames);
    const std::size_t length = image.GetBufferLength();
    if (length != pixels * element_size(type))
      throw InputError(fmt::format("{}: {} bytes of pixels for {} x {} x {} of {} bytes", name, length, cols, rows,
                                   frames, element_size(type)));
    std::string buffer(length, '\0');
    if (!image.GetBuffer(buffer.data()))
      throw InputError(fmt::format("{}: its pixels cannot be decoded (transfer syntax {})", name,
                                   reader.GetFile().GetHeader().GetDataSetTransferSyntax().GetString()));
    std::vector<float> out;
    convert_elements(buffer.data(), pixels, type, false, 1.0, 0.0, out);
    return out;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: its image cannot be read ({})", name, e.what()));
  }
}

}  // namespace

std::vector<DicomFrame> read_dicom_frames(const std::filesystem::path& file, std::string& why_not) {
  return read_frames(part10_bytes(file), file, file.string(), why_not);
}

std::vector<DicomFrame> read_dicom_frames_from_memory(const std::string& bytes, const std::string& name,
                                                      std::string& why_not) {
  return read_frames(bytes, name, name, why_not);
}

std::vector<float> read_dicom_pixels(const std::filesystem::path& file, int rows, int cols, int frames) {
  const std::string bytes = part10_bytes(file);
  if (bytes.empty()) throw InputError(fmt::format("{}: not a DICOM Part 10 file (no DICM preamble)", file.string()));
  return decode(bytes, file.string(), rows, cols, frames);
}

std::vector<float> read_dicom_pixels_from_memory(const std::string& bytes, const std::string& name, int rows, int cols,
                                                 int frames) {
  return decode(bytes, name, rows, cols, frames);
}

}  // namespace meshpde::detail
