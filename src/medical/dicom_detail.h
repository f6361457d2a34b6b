// Internal to meshpde::medical: a DICOM file's data set as parsed (dicom_parse.cpp), the
// frames the reader takes from it (dicom_frames.cpp), their pixels (native ones read
// there, compressed ones decoded in dicom_codecs.cpp: RLE by meshpde, JPEG-LS by
// CharLS, JPEG 2000 by OpenJPEG, the JPEG family by GDCM in dicom_gdcm.cpp, the one
// translation unit that includes GDCM)
// and the grid built from a series' frames (dicom_series.cpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace meshpde::detail {

struct DicomItem;

/// One data element: its tag (group << 16 | element), value representation (empty in
/// implicit VR) and where its value lies in the file's bytes; a sequence's items; the
/// fragments (offset, length) of encapsulated pixel data.
struct DicomElement {
  std::uint32_t tag = 0;
  char vr[3] = {0, 0, 0};
  std::size_t offset = 0, length = 0;
  bool undefined = false;  ///< an undefined length (a sequence, or encapsulated pixel data)
  std::vector<DicomItem> items;
  std::vector<std::pair<std::size_t, std::size_t>> fragments;
};

struct DicomItem {
  std::vector<DicomElement> elements;
  const DicomElement* find(std::uint32_t tag) const;
};

/// A parsed Part 10 file: the bytes (a deflated data set inflated), its transfer syntax,
/// and its data set (the file meta information left out).
struct DicomFile {
  std::string name, bytes, syntax;
  bool big = false, implicit = false;
  DicomItem root;
  /// A text value (DS, IS, CS, LO, UI...) without its padding; nullopt when absent or empty.
  std::optional<std::string> text(const DicomItem& item, std::uint32_t tag) const;
  /// The numbers of a DS or IS value ("a\b\c"). \throw InputError for one that is not.
  std::optional<std::vector<double>> numbers(const DicomItem& item, std::uint32_t tag) const;
  /// A US value. \throw InputError when it is not 2 bytes.
  std::optional<unsigned> us(const DicomItem& item, std::uint32_t tag) const;
  /// The first item of a sequence, or null.
  const DicomItem* first_item(const DicomItem& item, std::uint32_t tag) const;
};

/// Parses a Part 10 file. Every element header and value lies inside its file, item or
/// sequence; undefined lengths only where DICOM allows them and closed by their
/// delimiter; the value representations of the elements read are the standard's.
/// \throw InputError naming `name` and the byte at fault.
DicomFile parse_dicom(std::string bytes, const std::string& name);

/// One image of a series: a single-frame file, or one frame of a multi-frame file.
struct DicomFrame {
  std::filesystem::path file;
  int frame = 0;            ///< index in a multi-frame file, 0 otherwise
  int frames_in_file = 1;   ///< NumberOfFrames
  std::string series_uid;   ///< (0020,000E)
  int series_number = 0;    ///< (0020,0011)
  std::string description;  ///< (0008,103E)
  std::string modality;     ///< (0008,0060)
  int rows = 0, cols = 0;   ///< (0028,0010), (0028,0011)
  int samples_per_pixel = 1;
  bool has_position = false;  ///< ImagePositionPatient present
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool has_orientation = false;  ///< ImageOrientationPatient present
  Eigen::Vector3d row_dir = Eigen::Vector3d::UnitX(), col_dir = Eigen::Vector3d::UnitY();
  double row_spacing = 1, col_spacing = 1;  ///< PixelSpacing: between rows (j), between columns (i)
  bool has_spacing = false;
  double slice_thickness = 0;  ///< (0018,0050), the spacing of a single slice
  double slope = 1, intercept = 0;
  // The pixels' storage (the Image Pixel module).
  int bits_allocated = 16, bits_stored = 16, high_bit = 15;
  bool is_signed = false;  ///< PixelRepresentation 1
};

/// The frames of one file, read up to its pixel data. Empty, with `why_not` set, for a
/// file that is not a DICOM image (no DICM preamble, no pixel data, a DICOMDIR).
/// \throw InputError naming the file when it is DICOM but damaged.
std::vector<DicomFrame> read_dicom_frames(const std::filesystem::path& file, std::string& why_not);
std::vector<DicomFrame> read_dicom_frames_from_memory(const std::string& bytes, const std::string& name,
                                                      std::string& why_not);

/// The stored values of every frame of a file (frame after frame, row after row),
/// decoded from whatever transfer syntax it has (`frame` says how they are stored); not
/// rescaled. \throw InputError naming the file when its pixels cannot be decoded.
std::vector<float> read_dicom_pixels(const std::filesystem::path& file, const DicomFrame& frame);
std::vector<float> read_dicom_pixels_from_memory(const std::string& bytes, const std::string& name,
                                                 const DicomFrame& frame);

/// Whether meshpde decodes pixel data of this transfer syntax: the native ones, RLE,
/// the JPEG family, JPEG-LS and JPEG 2000 (dicom_codecs.cpp).
bool dicom_syntax_decoded(const std::string& syntax);
/// Encapsulated pixel data decoded (dicom_codecs.cpp): frames x rows x columns values
/// of bits_allocated / 8 bytes, little endian. \throw InputError naming the file.
std::string decode_compressed_pixels(const DicomFile& file, const DicomElement& pixels, const DicomFrame& frame);
/// One frame's JPEG codestream (its header checked) decoded by GDCM (dicom_gdcm.cpp).
std::string decode_jpeg_with_gdcm(const DicomFile& file, const std::string& stream, const DicomFrame& frame, int index);

/// The grid of a series: its frames in slice order (indices into the input) and the
/// geometry of dicom.h.
struct DicomGrid {
  std::vector<std::size_t> order;
  std::array<int, 3> size{0, 0, 0};
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
};

/// Orders the frames of one series along the slice normal and checks that they form one
/// regular grid. \throw InputError starting with `series` (how the series is named in
/// messages) and naming the frames at fault.
DicomGrid dicom_grid(const std::vector<DicomFrame>& frames, const std::string& series);

/// How a frame is named in messages: its file's name, and ", frame F" in a multi-frame file.
std::string frame_name(const DicomFrame& f);

}  // namespace meshpde::detail
