// A segment's closed surface through VTK's discrete flying edges and windowed-sinc
// smoothing, and the surface back into the segment (apps/segment_surface.h).
#include "meshpde/apps/segment_surface.h"

#include <fmt/format.h>
#include <vtkCellArray.h>
#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkWindowedSincPolyDataFilter.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <set>

#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"
#include "volume_formats.h"
#include "vtk_capture.h"

namespace meshpde {

namespace {

double signed_volume(const Positions& V, const Triangles& F) {
  double vol = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) vol += V.row(F(f, 0)).dot(V.row(F(f, 1)).cross(V.row(F(f, 2))));
  return vol / 6;
}

}  // namespace

MeshData extract_surface(const Segmentation& seg, const Segment& segment, double smoothing) {
  if (!(smoothing >= 0 && smoothing <= 1))
    throw InputError(fmt::format("smoothing {}: expected a factor from 0 (none) to 1 (strong)", smoothing));
  const std::vector<std::uint8_t> mask = segment_mask(seg, segment);
  std::size_t count = 0;
  for (const auto m : mask) count += m;
  if (count == 0)
    throw InputError(fmt::format("{}: segment '{}' (label {}) has no voxels", seg.name, segment.name, segment.label));
  const auto& d = seg.geometry.dims;
  // The mask padded by one voxel of background on every side, in index coordinates.
  vtkNew<vtkImageData> image;
  image->SetExtent(-1, d[0], -1, d[1], -1, d[2]);
  image->SetOrigin(0, 0, 0);
  image->SetSpacing(1, 1, 1);
  image->AllocateScalars(VTK_UNSIGNED_CHAR, 1);
  auto* p = static_cast<unsigned char*>(image->GetScalarPointer());
  const std::size_t px = static_cast<std::size_t>(d[0]) + 2, py = static_cast<std::size_t>(d[1]) + 2;
  std::fill(p, p + px * py * (static_cast<std::size_t>(d[2]) + 2), 0);
  std::size_t v = 0;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i, ++v)
        p[static_cast<std::size_t>(i + 1) +
          px * (static_cast<std::size_t>(j + 1) + py * static_cast<std::size_t>(k + 1))] = mask[v];

  detail::VtkErrorCapture capture;
  vtkNew<vtkDiscreteFlyingEdges3D> edges;
  capture.watch(edges);
  edges->SetInputData(image);
  edges->ComputeGradientsOff();
  edges->ComputeNormalsOff();
  edges->ComputeScalarsOff();
  edges->SetValue(0, 1);
  edges->Update();
  vtkSmartPointer<vtkPolyData> surface = edges->GetOutput();
  if (smoothing > 0) {
    vtkNew<vtkWindowedSincPolyDataFilter> smoother;
    capture.watch(smoother);
    smoother->SetInputData(surface);
    smoother->SetNumberOfIterations(20);
    smoother->SetPassBand(std::pow(10.0, -4.0 * smoothing));
    smoother->BoundarySmoothingOff();
    smoother->FeatureEdgeSmoothingOff();
    smoother->NonManifoldSmoothingOn();
    smoother->NormalizeCoordinatesOn();
    smoother->Update();
    surface = smoother->GetOutput();
  }
  if (!capture.error().empty()) throw Error(fmt::format("VTK could not extract the surface: {}", capture.error()));
  const vtkIdType np = surface->GetNumberOfPoints();
  if (np == 0 || surface->GetNumberOfPolys() == 0)
    throw InputError(fmt::format("{}: segment '{}' gave no surface", seg.name, segment.name));

  MeshData out;
  out.V.resize(np, 3);
  for (vtkIdType i = 0; i < np; ++i) {
    double x[3];
    surface->GetPoint(i, x);
    out.V.row(i) = seg.geometry.index_to_lps(Eigen::Vector3d(x[0], x[1], x[2])).transpose();
  }
  std::vector<std::array<int, 3>> tris;
  vtkCellArray* polys = surface->GetPolys();
  vtkNew<vtkIdList> ids;
  polys->InitTraversal();
  while (polys->GetNextCell(ids)) {
    for (vtkIdType k = 1; k + 1 < ids->GetNumberOfIds(); ++k)
      tris.push_back(
          {static_cast<int>(ids->GetId(0)), static_cast<int>(ids->GetId(k)), static_cast<int>(ids->GetId(k + 1))});
  }
  out.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    out.F.row(static_cast<Eigen::Index>(t)) << tris[t][0], tris[t][1], tris[t][2];
  if (signed_volume(out.V, out.F) < 0) out.F.col(1).swap(out.F.col(2));  // outward
  out.space = "LPS";
  out.field_strings["Segment_Name"] = segment.name;
  out.field_strings["Segment_ID"] = segment.id;
  out.field_arrays["Segment_LabelValue"] = DataArray{Eigen::MatrixXd::Constant(1, 1, segment.label), "Int32"};
  out.field_arrays["Segment_Layer"] = DataArray{Eigen::MatrixXd::Constant(1, 1, segment.layer), "Int32"};
  out.field_arrays["Segment_Color"] = DataArray{segment.color.transpose(), "Float64"};
  return out;
}

VoxelizeReport voxelize_into(Segmentation& seg, const Segment& segment, const Positions& V, const Triangles& F,
                             const Field& displacement, const VoxelizeParams& params) {
  if (displacement.size() != 0 && (displacement.rows() != V.rows() || displacement.cols() != 3))
    throw InputError(
        fmt::format("a displacement of {} x {} for {} vertices", displacement.rows(), displacement.cols(), V.rows()));
  const Volume& grid = seg.geometry;
  VoxelizeReport r;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const Eigen::Vector3d q = grid.lps_to_index(V.row(i).transpose());
    for (int a = 0; a < 3; ++a)
      if (q[a] < -0.5 || q[a] > grid.dims[a] - 0.5) {
        ++r.vertices_outside_grid;
        break;
      }
  }
  std::vector<char> moved(static_cast<std::size_t>(V.rows()), 0);
  if (displacement.size() != 0)
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if (displacement.row(i).squaredNorm() > 0) {
        moved[static_cast<std::size_t>(i)] = 1;
        ++r.moved_vertices;
      }
  if (displacement.size() == 0 || params.full) {
    r.box = whole_grid(grid);
    const std::vector<std::uint8_t> inside = voxelize(V, F, grid, params.oversampling, &r.box);
    r.change = set_segment(seg, segment, inside);
    r.decided_voxels = grid.num_voxels();
    return r;
  }
  // The surface before the move differs from V only on the triangles of moved vertices:
  // the voxels that change side lie in the box of those triangles, before and after.
  r.partial = true;
  const Positions before = V - displacement;
  std::vector<Eigen::Vector3d> corners;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    bool touched = false;
    for (int c = 0; c < 3; ++c) touched = touched || moved[static_cast<std::size_t>(F(f, c))];
    if (!touched) continue;
    for (int c = 0; c < 3; ++c) {
      corners.push_back(V.row(F(f, c)).transpose());
      corners.push_back(before.row(F(f, c)).transpose());
    }
  }
  r.box = voxel_box_around(grid, corners, 1.0);
  if (r.box.empty()) return r;
  const std::vector<std::uint8_t> after_inside = voxelize(V, F, grid, params.oversampling, &r.box);
  const std::vector<std::uint8_t> before_inside = voxelize(before, F, grid, params.oversampling, &r.box);
  std::vector<std::uint8_t> decide(after_inside.size());
  for (std::size_t k = 0; k < decide.size(); ++k) {
    decide[k] = after_inside[k] != before_inside[k];
    r.decided_voxels += decide[k];
  }
  r.change = set_segment(seg, segment, after_inside, decide);
  return r;
}

Segmentation voxelize_reference(const std::filesystem::path& path, const VolumeReadOptions& options, bool* is_image) {
  if (holds_segments(path)) {
    if (is_image) *is_image = false;
    return read_segmentation(path);
  }
  Volume v = read_volume(path, options);
  // A label map: whole, non-negative values of at most 1,000 labels; anything else (a
  // CT in HU, an MR) is an image whose grid gets a new label map.
  std::set<float> labels;
  bool label_map = true;
  for (const float x : v.values) {
    if (!(x >= 0 && x == std::floor(x) && x < 2e9)) {
      label_map = false;
      break;
    }
    if (x != 0 && labels.insert(x).second && labels.size() > 1000) {
      label_map = false;
      break;
    }
  }
  if (label_map && !is_dicom_path(path)) {
    if (is_image) *is_image = false;
    return read_segmentation(path);
  }
  Segmentation seg;
  seg.labels.assign(v.num_voxels(), 0);
  seg.geometry = std::move(v);
  seg.geometry.values.clear();
  seg.layers = 1;
  seg.name = path.string();
  seg.format = SegmentationFormat::Nrrd;
  if (is_image) *is_image = true;
  return seg;
}

Segment segment_for_surface(Segmentation& seg, const std::string& choice, const MeshData& surface) {
  auto label_number = [](const std::string& s) -> std::optional<int> {
    if (s.empty() || s.size() > 9 || !std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); }))
      return std::nullopt;
    return std::stoi(s);
  };
  auto new_segment = [&](int label, const std::string& name) {
    Segment s;
    s.index = static_cast<int>(seg.segments.size());
    s.label = label;
    s.name = name.empty() ? fmt::format("label {}", label) : name;
    s.id = fmt::format("label_{}", label);
    seg.segments.push_back(s);
    return s;
  };
  auto has_label = [&](int label) {
    return std::any_of(seg.segments.begin(), seg.segments.end(), [&](const Segment& s) { return s.label == label; });
  };
  if (!choice.empty()) {
    if (const auto l = label_number(choice); l && *l > 0 && seg.layers == 1 && !has_label(*l))
      return new_segment(*l, "");
    return find_segment(seg, choice);
  }
  const auto name = surface.field_strings.find("Segment_Name");
  if (name != surface.field_strings.end())
    for (const auto& s : seg.segments)
      if (s.name == name->second) return s;
  const auto label = surface.field_arrays.find("Segment_LabelValue");
  if (label != surface.field_arrays.end() && label->second.values.size() == 1) {
    const double l = label->second.values(0, 0);
    if (l >= 1 && l <= 2e9 && l == std::floor(l)) {
      for (const auto& s : seg.segments)
        if (s.label == static_cast<int>(l) && seg.layers == 1) return s;
      if (seg.layers == 1 && !has_label(static_cast<int>(l)))
        return new_segment(static_cast<int>(l), name != surface.field_strings.end() ? name->second : "");
    }
  }
  if (seg.segments.empty() && seg.layers == 1) return new_segment(1, "");
  return find_segment(seg, "");
}

SurfaceInLps surface_in_lps(const MeshData& surface, Space space, LengthUnit units) {
  const double s = millimetres_per(units);
  const Eigen::Vector3d flip = space == Space::RAS ? Eigen::Vector3d(-1, -1, 1) : Eigen::Vector3d(1, 1, 1);
  SurfaceInLps out;
  out.V = surface.V * s * flip.asDiagonal();
  const auto& f = surface.vertex_scalars;
  if (f.count("displacement_x") && f.count("displacement_y") && f.count("displacement_z")) {
    out.displacement.resize(surface.V.rows(), 3);
    out.displacement.col(0) = f.at("displacement_x") * s * flip.x();
    out.displacement.col(1) = f.at("displacement_y") * s * flip.y();
    out.displacement.col(2) = f.at("displacement_z") * s * flip.z();
    if (!out.displacement.allFinite())
      throw InputError("the surface's displacement field has a value that is not finite");
  }
  return out;
}

double dice(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  if (a.size() != b.size()) throw InputError(fmt::format("dice: masks of {} and {} voxels", a.size(), b.size()));
  std::size_t both = 0, na = 0, nb = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    both += a[k] && b[k];
    na += a[k] != 0;
    nb += b[k] != 0;
  }
  return na + nb == 0 ? 1.0 : 2.0 * static_cast<double>(both) / static_cast<double>(na + nb);
}

}  // namespace meshpde
