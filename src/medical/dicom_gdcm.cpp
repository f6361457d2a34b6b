// The one translation unit that includes GDCM: a frame of the JPEG family (baseline,
// extended, lossless) decoded by GDCM's IJG builds. The DICOM header was parsed and
// checked by meshpde (dicom_parse.cpp, dicom_frames.cpp), the JPEG header by
// dicom_codecs.cpp; the codec gets one frame's codestream and the pixel format that the
// checked header gives, and GDCM's exceptions become InputError.
#include <fmt/format.h>
#include <gdcmDataElement.h>
#include <gdcmFragment.h>
#include <gdcmJPEGCodec.h>
#include <gdcmPhotometricInterpretation.h>
#include <gdcmPixelFormat.h>
#include <gdcmSequenceOfFragments.h>
#include <gdcmTrace.h>
#include <gdcmTransferSyntax.h>

#include <string>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"

namespace meshpde::detail {

namespace {

// GDCM prints its warnings and errors to stderr; what went wrong reaches the user as
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

}  // namespace

std::string decode_jpeg_with_gdcm(const DicomFile& d, const std::string& stream, const DicomFrame& f, int frame) {
  quiet_gdcm();
  const gdcm::TransferSyntax ts = gdcm::TransferSyntax::GetTSType(d.syntax.c_str());
  gdcm::JPEGCodec codec;
  const auto fail = [&](const std::string& why) {
    throw InputError(fmt::format("{}: frame {}: its JPEG pixel data cannot be decoded ({})", d.name, frame + 1, why));
  };
  if (!codec.CanDecode(ts)) fail("no codec for transfer syntax " + d.syntax);
  try {
    gdcm::SmartPointer<gdcm::SequenceOfFragments> sq = new gdcm::SequenceOfFragments;
    // IJG's decoder suspends when its source runs dry, and GDCM returns from a
    // suspended decode without releasing the decoder (its memory leaks). Behind the
    // stream: end-of-image markers for longer than any marker segment can skip
    // (65,535 bytes), so every read past the end finds one and the decode finishes.
    static const std::string tail = [] {
      std::string t;
      for (int k = 0; k < 32768 + 2; ++k) t += "\xff\xd9";
      return t;
    }();
    const std::string padded = stream + tail;
    gdcm::Fragment frag;
    frag.SetByteValue(padded.data(), static_cast<std::uint32_t>(padded.size()));
    sq->AddFragment(frag);
    gdcm::DataElement in(gdcm::Tag(0x7fe0, 0x0010));
    in.SetVR(gdcm::VR::OB);
    in.SetValue(*sq);
    const unsigned dims[3] = {static_cast<unsigned>(f.cols), static_cast<unsigned>(f.rows), 1};
    codec.SetNumberOfDimensions(2);
    codec.SetDimensions(dims);
    codec.SetPlanarConfiguration(0);
    codec.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
    codec.SetPixelFormat(gdcm::PixelFormat(1, static_cast<unsigned short>(f.bits_allocated),
                                           static_cast<unsigned short>(f.bits_stored),
                                           static_cast<unsigned short>(f.high_bit), f.is_signed ? 1 : 0));
    codec.SetNeedOverlayCleanup(false);  // the stored bits are taken out after decoding
    gdcm::DataElement out;
    if (!codec.Decode(in, out) || !out.GetByteValue()) fail(d.syntax);
    const gdcm::ByteValue* bv = out.GetByteValue();
    const std::size_t want = static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols) *
                             static_cast<std::size_t>(f.bits_allocated / 8);
    if (bv->GetLength() < want) fail(fmt::format("{} bytes for {} expected", bv->GetLength(), want));
    return std::string(bv->GetPointer(), want);
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    fail(e.what());
  }
  return {};
}

}  // namespace meshpde::detail
