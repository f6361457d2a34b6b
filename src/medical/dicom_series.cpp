// DICOM series: files grouped by SeriesInstanceUID, frames ordered along the slice
// normal and checked to form one regular grid, then decoded into a Volume (dicom.h).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numeric>

#include "dicom_detail.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"
#include "volume_formats.h"

namespace meshpde {
namespace detail {

std::string frame_name(const DicomFrame& f) {
  const std::string file = f.file.filename().string();
  return f.frames_in_file > 1 ? fmt::format("{}, frame {}", file, f.frame) : file;
}

namespace {

// Within a relative tolerance of each other, component by component.
bool close(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double tol) {
  return (a - b).cwiseAbs().maxCoeff() <= tol;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

DicomGrid dicom_grid(const std::vector<DicomFrame>& frames, const std::string& series) {
  if (frames.empty()) throw InputError(fmt::format("{}: no images", series));
  const DicomFrame& first = frames.front();
  for (const DicomFrame& f : frames) {
    // Without its geometry an image cannot be placed in the patient frame; a reader
    // that assumed identity axes and 1 mm would put the scan where the mesh is not.
    const char* missing = !f.has_orientation ? "ImageOrientationPatient"
                          : !f.has_spacing   ? "PixelSpacing"
                          : !f.has_position  ? "ImagePositionPatient"
                                             : nullptr;
    if (missing)
      throw InputError(
          fmt::format("{}: {} has no {} (a secondary capture or a screenshot?), so its voxels cannot "
                      "be placed in the patient frame",
                      series, frame_name(f), missing));
    if (f.samples_per_pixel != 1)
      throw InputError(fmt::format("{}: {} has {} samples a pixel (colour); a grey-level image is needed", series,
                                   frame_name(f), f.samples_per_pixel));
    if (f.rows != first.rows || f.cols != first.cols)
      throw InputError(fmt::format("{}: mixed image sizes: {} is {} x {}, {} is {} x {} (columns x rows)", series,
                                   frame_name(first), first.cols, first.rows, frame_name(f), f.cols, f.rows));
    if (!close(f.row_dir, first.row_dir, 1e-4) || !close(f.col_dir, first.col_dir, 1e-4))
      throw InputError(fmt::format("{}: mixed orientations: {} and {} have different ImageOrientationPatient", series,
                                   frame_name(first), frame_name(f)));
    if (std::abs(f.row_spacing - first.row_spacing) > 1e-4 * first.row_spacing ||
        std::abs(f.col_spacing - first.col_spacing) > 1e-4 * first.col_spacing)
      throw InputError(fmt::format("{}: mixed pixel spacings: {} has {} x {} mm, {} has {} x {} mm", series,
                                   frame_name(first), first.row_spacing, first.col_spacing, frame_name(f),
                                   f.row_spacing, f.col_spacing));
  }
  if (!(first.row_spacing > 0) || !(first.col_spacing > 0))
    throw InputError(fmt::format("{}: {} has a pixel spacing of {} x {} mm", series, frame_name(first),
                                 first.row_spacing, first.col_spacing));
  const Eigen::Vector3d row = first.row_dir.normalized(), col = first.col_dir.normalized();
  if (!row.allFinite() || !col.allFinite() || std::abs(row.dot(col)) > 1e-3)
    throw InputError(
        fmt::format("{}: {}: ImageOrientationPatient's row and column directions are not orthogonal unit "
                    "vectors",
                    series, frame_name(first)));
  const Eigen::Vector3d n = row.cross(col);

  DicomGrid g;
  g.size = {first.cols, first.rows, static_cast<int>(frames.size())};
  g.direction.col(0) = row;
  g.direction.col(1) = col;
  g.direction.col(2) = n;
  g.order.resize(frames.size());
  std::iota(g.order.begin(), g.order.end(), std::size_t{0});
  if (frames.size() == 1) {
    g.spacing =
        Eigen::Vector3d(first.col_spacing, first.row_spacing, first.slice_thickness > 0 ? first.slice_thickness : 1.0);
    g.origin = first.position;
    return g;
  }
  std::vector<double> along(frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) along[k] = n.dot(frames[k].position);
  std::stable_sort(g.order.begin(), g.order.end(), [&](std::size_t a, std::size_t b) { return along[a] < along[b]; });
  std::vector<double> steps;
  for (std::size_t k = 0; k + 1 < frames.size(); ++k) steps.push_back(along[g.order[k + 1]] - along[g.order[k]]);
  const double dz = median(steps);
  const double in_plane = std::min(first.row_spacing, first.col_spacing);
  for (std::size_t k = 0; k + 1 < frames.size(); ++k) {
    const DicomFrame& a = frames[g.order[k]];
    const DicomFrame& b = frames[g.order[k + 1]];
    if (steps[k] <= 1e-3 * std::max(dz, in_plane))
      throw InputError(
          fmt::format("{}: {} and {} lie at the same position (one image twice, or several acquisitions "
                      "or echoes in one series?)",
                      series, frame_name(a), frame_name(b)));
  }
  for (std::size_t k = 0; k + 1 < frames.size(); ++k) {
    const DicomFrame& a = frames[g.order[k]];
    const DicomFrame& b = frames[g.order[k + 1]];
    const double tol = std::max(1e-2 * dz, 1e-3);
    if (std::abs(steps[k] - dz) > tol) {
      if (std::abs(steps[k] - 2 * dz) <= 0.1 * dz)
        throw InputError(
            fmt::format("{}: a gap between {} and {}: {:.4g} mm apart where the other slices are {:.4g} "
                        "mm apart (a missing slice?)",
                        series, frame_name(a), frame_name(b), steps[k], dz));
      throw InputError(
          fmt::format("{}: unequal slice spacing: {} and {} are {:.4g} mm apart, the other slices "
                      "{:.4g} mm",
                      series, frame_name(a), frame_name(b), steps[k], dz));
    }
    const Eigen::Vector3d delta = b.position - a.position;
    const double across = (delta - n.dot(delta) * n).norm();
    if (across > std::max(1e-2 * dz, 1e-3))
      throw InputError(
          fmt::format("{}: the slices are not stacked along their normal: {} is {:.3g} mm off {} across "
                      "the slice plane (a gantry tilt of {:.2g} degrees?); tilted series are not read",
                      series, frame_name(b), across, frame_name(a), std::atan2(across, steps[k]) * 180 / M_PI));
  }
  g.spacing = Eigen::Vector3d(first.col_spacing, first.row_spacing, dz);
  g.origin = frames[g.order.front()].position;
  return g;
}

}  // namespace detail

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string series_name(const std::string& uid, int number, const std::string& description) {
  std::string s = fmt::format("series {}", number);
  if (!description.empty()) s += fmt::format(" '{}'", description);
  return s + fmt::format(" ({})", uid.empty() ? "no SeriesInstanceUID" : uid);
}

std::string series_name(const DicomSeries& s) {
  return series_name(s.uid, s.number, s.description);
}

struct Scan {
  std::map<std::string, std::vector<detail::DicomFrame>> by_uid;
  std::vector<std::string> skipped;
  std::vector<std::string> damaged;  // DICOM files that could not be parsed (also in skipped)
};

void scan_file(const std::filesystem::path& file, Scan& scan) {
  std::string why_not;
  std::vector<detail::DicomFrame> frames;
  try {
    frames = detail::read_dicom_frames(file, why_not);
  } catch (const InputError& e) {
    scan.skipped.push_back(e.what());
    scan.damaged.push_back(e.what());
    return;
  }
  if (frames.empty()) {
    scan.skipped.push_back(fmt::format("{}: {}", file.string(), why_not));
    return;
  }
  auto& list = scan.by_uid[frames.front().series_uid];
  list.insert(list.end(), frames.begin(), frames.end());
}

std::vector<std::filesystem::path> files_in(const std::filesystem::path& dir, bool recursive) {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  std::error_code ec;
  auto add = [&](const fs::directory_entry& e) {
    std::error_code ec2;
    if (e.is_regular_file(ec2)) files.push_back(e.path());
  };
  if (recursive) {
    for (fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
         !ec && it != end; it.increment(ec))
      add(*it);
  } else {
    for (fs::directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end; !ec && it != end;
         it.increment(ec))
      add(*it);
  }
  if (ec) throw InputError(fmt::format("{}: cannot list the folder ({})", dir.string(), ec.message()));
  std::sort(files.begin(), files.end());
  return files;
}

DicomSeries describe_series(const std::vector<detail::DicomFrame>& frames) {
  const detail::DicomFrame& f = frames.front();
  DicomSeries s;
  s.uid = f.series_uid;
  s.number = f.series_number;
  s.description = f.description;
  s.modality = f.modality;
  try {
    const detail::DicomGrid g = detail::dicom_grid(frames, series_name(s));
    s.size = g.size;
    s.spacing = g.spacing;
    s.origin = g.origin;
    s.direction = g.direction;
    for (const std::size_t k : g.order)
      if (s.files.empty() || s.files.back() != frames[k].file) s.files.push_back(frames[k].file);
  } catch (const InputError& e) {
    s.problem = e.what();
    s.size = {f.cols, f.rows, static_cast<int>(frames.size())};
    for (const auto& fr : frames)
      if (std::find(s.files.begin(), s.files.end(), fr.file) == s.files.end()) s.files.push_back(fr.file);
  }
  return s;
}

// Every frame under `path` by series UID (see list_dicom_series).
Scan scan_path(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(fmt::format("{}: no such file or folder", path.string()));
  Scan scan;
  if (fs::is_directory(path, ec)) {
    for (const auto& file : files_in(path, true)) scan_file(file, scan);
  } else {
    std::string why_not;
    const std::vector<detail::DicomFrame> own = detail::read_dicom_frames(path, why_not);
    if (own.empty()) throw InputError(fmt::format("{}: {}", path.string(), why_not));
    if (own.front().frames_in_file > 1) {
      scan.by_uid[own.front().series_uid] = own;
    } else {
      // One file of a series: the series is every file of its folder with its UID.
      const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
      for (const auto& file : files_in(dir, false)) scan_file(file, scan);
      for (auto it = scan.by_uid.begin(); it != scan.by_uid.end();)
        it = it->first == own.front().series_uid ? std::next(it) : scan.by_uid.erase(it);
      scan.skipped.clear();
    }
  }
  return scan;
}

DicomListing listing_of(const std::filesystem::path& path, Scan& scan) {
  DicomListing listing;
  listing.skipped = std::move(scan.skipped);
  for (const auto& [uid, frames] : scan.by_uid) listing.series.push_back(describe_series(frames));
  std::sort(listing.series.begin(), listing.series.end(), [](const DicomSeries& a, const DicomSeries& b) {
    return a.number != b.number ? a.number < b.number : a.uid < b.uid;
  });
  if (listing.series.empty()) {
    std::string why;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, listing.skipped.size()); ++k)
      why += "\n  " + listing.skipped[k];
    if (listing.skipped.size() > 3) why += fmt::format("\n  ... and {} more", listing.skipped.size() - 3);
    throw InputError(
        fmt::format("{}: no DICOM images found ({} files passed over){}", path.string(), listing.skipped.size(), why));
  }
  return listing;
}

}  // namespace

bool is_dicom_path(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return true;
  const std::string name = lower(path.filename().string());
  if (name.ends_with(".dcm") || name.ends_with(".dicom")) return true;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream in(path, std::ios::binary);
  char magic[132] = {};
  in.read(magic, 132);
  return in.gcount() == 132 && std::string(magic + 128, 4) == "DICM";
}

DicomListing list_dicom_series(const std::filesystem::path& path) {
  Scan scan = scan_path(path);
  return listing_of(path, scan);
}

const DicomSeries& choose_dicom_series(const DicomListing& listing, const std::string& choice,
                                       const std::string& name) {
  auto list = [&] {
    std::string s;
    for (const auto& x : listing.series)
      s += fmt::format("\n  {}: {} x {} x {}, {}", series_name(x), x.size[0], x.size[1], x.size[2],
                       x.modality.empty() ? "no modality" : x.modality);
    return s;
  };
  if (choice.empty()) {
    if (listing.series.size() == 1) return listing.series.front();
    throw InputError(
        fmt::format("{} holds {} series; choose one by UID or series number:{}", name, listing.series.size(), list()));
  }
  for (const auto& s : listing.series)
    if (s.uid == choice || std::to_string(s.number) == choice) return s;
  throw InputError(fmt::format("{}: no series '{}'; the series are:{}", name, choice, list()));
}

namespace {

// A volume on a series' grid, its values allocated (zero) after the size is checked
// against `max_voxels` (the message names `what`).
Volume volume_on(const detail::DicomGrid& g, const std::string& name, const std::string& what, std::size_t max_voxels) {
  Volume v;
  v.name = name;
  v.dims = g.size;
  v.spacing = g.spacing;
  v.origin = g.origin;
  v.direction = g.direction;
  v.values.resize(detail::checked_voxels({g.size[0], g.size[1], g.size[2]}, what, max_voxels));
  return v;
}

}  // namespace

Volume read_dicom_series(const std::filesystem::path& path, const std::string& choice, std::size_t max_voxels) {
  Scan scan = scan_path(path);
  const DicomListing listing = listing_of(path, scan);
  const DicomSeries& series = choose_dicom_series(listing, choice, path.string());
  if (!series.problem.empty()) {
    std::string damaged;
    for (const auto& d : scan.damaged) damaged += "\n  " + d;
    throw InputError(fmt::format("{}: {}{}", path.string(), series.problem,
                                 damaged.empty() ? "" : "\nfiles that could not be read:" + damaged));
  }
  const std::vector<detail::DicomFrame>& frames = scan.by_uid.at(series.uid);
  const std::string name = fmt::format("{}: {}", path.string(), series_name(series));
  const detail::DicomGrid g = detail::dicom_grid(frames, name);
  Volume v = volume_on(g, path.string(), name, max_voxels);
  const std::size_t slice = static_cast<std::size_t>(g.size[0]) * static_cast<std::size_t>(g.size[1]);
  // Each file decoded once, its frames placed where the order puts them.
  std::map<std::filesystem::path, std::vector<std::size_t>> slots;  // file -> slice index of each of its frames
  for (std::size_t k = 0; k < g.order.size(); ++k) {
    const detail::DicomFrame& f = frames[g.order[k]];
    auto& s = slots[f.file];
    s.resize(static_cast<std::size_t>(f.frames_in_file), static_cast<std::size_t>(-1));
    s[static_cast<std::size_t>(f.frame)] = k;
  }
  for (std::size_t k = 0; k < g.order.size(); ++k) {
    const detail::DicomFrame& f = frames[g.order[k]];
    auto it = slots.find(f.file);
    if (it == slots.end()) continue;  // decoded already
    const std::vector<float> pixels = detail::read_dicom_pixels(f.file, f);
    for (const detail::DicomFrame& fr : frames) {
      if (fr.file != f.file) continue;
      const std::size_t at = it->second[static_cast<std::size_t>(fr.frame)];
      if (at == static_cast<std::size_t>(-1)) continue;
      const float* src = pixels.data() + static_cast<std::size_t>(fr.frame) * slice;
      float* dst = v.values.data() + at * slice;
      for (std::size_t p = 0; p < slice; ++p) dst[p] = static_cast<float>(src[p] * fr.slope + fr.intercept);
    }
    slots.erase(it);
  }
  v.validate();
  return v;
}

Volume read_dicom_file_from_memory(const std::string& bytes, const std::string& name) {
  std::string why_not;
  const std::vector<detail::DicomFrame> frames = detail::read_dicom_frames_from_memory(bytes, name, why_not);
  if (frames.empty()) throw InputError(fmt::format("{}: {}", name, why_not));
  const detail::DicomGrid g = detail::dicom_grid(frames, name);
  Volume v = volume_on(g, name, name, 1u << 26);
  const detail::DicomFrame& f = frames.front();
  const std::vector<float> pixels = detail::read_dicom_pixels_from_memory(bytes, name, f);
  const std::size_t slice = static_cast<std::size_t>(g.size[0]) * static_cast<std::size_t>(g.size[1]);
  for (std::size_t k = 0; k < g.order.size(); ++k) {
    const detail::DicomFrame& fr = frames[g.order[k]];
    for (std::size_t p = 0; p < slice; ++p)
      v.values[k * slice + p] =
          static_cast<float>(pixels[static_cast<std::size_t>(fr.frame) * slice + p] * fr.slope + fr.intercept);
  }
  v.validate();
  return v;
}

}  // namespace meshpde
