// Segmentations in Python (meshpde::medical): read and write them, a segment's surface
// and a surface back into a segment. The package's wrappers (meshpde/__init__.py) turn
// the flat label arrays into numpy arrays [i, j, k] or [i, j, k, layer].
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <optional>
#include <set>

#include "bindings.h"
#include "convert.h"
#include "meshpde/apps/segment_surface.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/segmentation_io.h"

namespace meshpde::python {

namespace {

Eigen::Matrix4d affine_of(const Volume& g) {
  Eigen::Matrix4d A = Eigen::Matrix4d::Identity();
  A.topLeftCorner<3, 3>() = g.direction * g.spacing.asDiagonal();
  A.topRightCorner<3, 1>() = g.origin;
  return A;
}

void set_geometry(Volume& g, const py::handle& affine) {
  const Field A = field_arg(affine, "affine", 4, 4);
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector3d axis = A.block<3, 1>(0, c);
    if (!(axis.norm() > 0)) throw InputError(fmt::format("affine: voxel axis {} has length 0", c));
    g.spacing[c] = axis.norm();
    g.direction.col(c) = axis / axis.norm();
  }
  g.origin = A.block<3, 1>(0, 3);
  if (std::abs(g.direction.determinant()) < 1e-6) throw InputError("affine: the voxel axes are not independent");
}

py::dict segment_dict(const Segment& s) {
  py::dict d;
  d["index"] = s.index;
  d["id"] = s.id;
  d["name"] = s.name;
  d["label"] = s.label;
  d["layer"] = s.layer;
  d["color"] = py::make_tuple(s.color.x(), s.color.y(), s.color.z());
  return d;
}

Segment segment_from(const py::handle& obj, int index) {
  if (!py::isinstance<py::dict>(obj)) throw py::type_error("segments: expected a list of dicts");
  const py::dict d = obj.cast<py::dict>();
  Segment s;
  s.index = index;
  if (d.contains("name")) s.name = py::str(d["name"]);
  if (d.contains("id")) s.id = py::str(d["id"]);
  if (d.contains("label")) s.label = d["label"].cast<int>();
  if (d.contains("layer")) s.layer = d["layer"].cast<int>();
  if (d.contains("color")) {
    s.color = Eigen::Vector3d(vector_arg(d["color"], "segments[].color", 3));
    s.has_color = true;
  }
  if (s.name.empty()) s.name = fmt::format("label {}", s.label);
  if (s.id.empty()) s.id = fmt::format("label_{}", s.label);
  return s;
}

// What the package turns into (labels, affine, segments).
py::dict segmentation_dict(const Segmentation& seg) {
  py::array_t<std::int32_t> flat(static_cast<py::ssize_t>(seg.labels.size()));
  std::copy(seg.labels.begin(), seg.labels.end(), flat.mutable_data());
  py::list segments;
  for (const auto& s : seg.segments) segments.append(segment_dict(s));
  py::dict d;
  d["labels"] = flat;
  d["dims"] = py::make_tuple(seg.geometry.dims[0], seg.geometry.dims[1], seg.geometry.dims[2]);
  d["layers"] = seg.layers;
  d["affine"] = to_numpy(Eigen::MatrixXd(affine_of(seg.geometry)));
  d["segments"] = segments;
  d["format"] = to_string(seg.format);
  return d;
}

// A Segmentation from the package's flat labels (layer fastest, then i, j, k).
Segmentation segmentation_from(const py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>& flat,
                               const std::array<int, 3>& dims, int layers, const py::handle& affine,
                               const py::handle& segments) {
  Segmentation seg;
  seg.name = "labels";
  for (int a = 0; a < 3; ++a)
    if (dims[a] < 1) throw InputError(fmt::format("labels: dimension {} is {}", a, dims[a]));
  if (layers < 1) throw InputError("labels: no layers");
  seg.geometry.dims = dims;
  seg.layers = layers;
  set_geometry(seg.geometry, affine);
  if (static_cast<std::size_t>(flat.size()) != seg.num_voxels() * static_cast<std::size_t>(layers))
    throw InputError("labels: the array does not match its dimensions");
  seg.labels.assign(flat.data(), flat.data() + flat.size());
  if (segments.is_none()) {
    std::set<std::int32_t> present(seg.labels.begin(), seg.labels.end());
    present.erase(0);
    for (const std::int32_t l : present) {
      Segment s;
      s.index = static_cast<int>(seg.segments.size());
      s.label = l;
      s.name = fmt::format("label {}", l);
      s.id = fmt::format("label_{}", l);
      seg.segments.push_back(s);
    }
  } else {
    int k = 0;
    for (const auto& s : segments) seg.segments.push_back(segment_from(s, k++));
  }
  for (const auto& s : seg.segments)
    if (s.layer < 0 || s.layer >= layers)
      throw InputError(fmt::format("segments: '{}' is in layer {} of {}", s.name, s.layer, layers));
  return seg;
}

}  // namespace

void bind_segmentation(py::module_& m) {
  m.def(
      "_read_segmentation",
      [](const std::filesystem::path& path) {
        Segmentation seg;
        {
          py::gil_scoped_release release;
          seg = read_segmentation(path);
        }
        return segmentation_dict(seg);
      },
      py::arg("path"));

  m.def(
      "_write_segmentation",
      [](const std::filesystem::path& path,
         const py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>& flat, std::array<int, 3> dims,
         int layers, const ArrayLike& affine, const py::handle& segments, const py::handle& like) {
        Segmentation seg = segmentation_from(flat, dims, layers, affine, segments);
        if (!like.is_none()) {
          // The header, format and table of `like`, with these labels.
          Segmentation ref = read_segmentation(like.cast<std::filesystem::path>());
          if (ref.geometry.dims != seg.geometry.dims || ref.layers != seg.layers)
            throw InputError(fmt::format("like: {} has {} x {} x {} voxels in {} layers, the labels {} x {} x {} in {}",
                                         ref.name, ref.geometry.dims[0], ref.geometry.dims[1], ref.geometry.dims[2],
                                         ref.layers, dims[0], dims[1], dims[2], layers));
          ref.labels = std::move(seg.labels);
          if (!segments.is_none()) ref.segments = std::move(seg.segments);
          seg = std::move(ref);
        }
        py::gil_scoped_release release;
        write_segmentation(path, seg);
      },
      py::arg("path"), py::arg("labels"), py::arg("dims"), py::arg("layers"), py::arg("affine"), py::arg("segments"),
      py::arg("like"));

  m.def(
      "_extract_surface",
      [](const py::handle& path, const ArrayLike& flat, std::array<int, 3> dims, int layers, const ArrayLike& affine,
         const std::string& segment, double smoothing) {
        Segmentation seg =
            path.is_none()
                ? segmentation_from(flat.cast<py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>>(),
                                    dims, layers, affine, py::none())
                : read_segmentation(path.cast<std::filesystem::path>());
        const Segment s = find_segment(seg, segment);
        MeshData surface;
        std::size_t voxels = 0;
        {
          py::gil_scoped_release release;
          surface = extract_surface(seg, s, smoothing);
          for (std::size_t v = 0; v < seg.num_voxels(); ++v) voxels += seg.at(v, s.layer) == s.label;
        }
        py::dict info = segment_dict(s);
        info["voxels"] = voxels;
        info["smoothing"] = smoothing;
        info["space"] = "LPS";
        return py::make_tuple(to_numpy(Eigen::MatrixXd(surface.V)), to_numpy(surface.F), info);
      },
      py::arg("path"), py::arg("labels"), py::arg("dims"), py::arg("layers"), py::arg("affine"), py::arg("segment"),
      py::arg("smoothing"));

  m.def(
      "_voxelize",
      [](const ArrayLike& V, const ArrayLike& F, const py::handle& displacement, const std::filesystem::path& reference,
         const std::string& segment, int oversampling, bool full, const std::string& space, const std::string& units,
         const py::handle& series, const py::handle& output) {
        MeshData surface;
        surface.V = positions_arg(V);
        surface.F = triangles_arg(F, surface.V.rows());
        if (!displacement.is_none()) {
          const Field d = field_arg(displacement, "displacement", surface.V.rows(), 3);
          surface.vertex_scalars["displacement_x"] = d.col(0);
          surface.vertex_scalars["displacement_y"] = d.col(1);
          surface.vertex_scalars["displacement_z"] = d.col(2);
        }
        VolumeReadOptions options;
        if (!series.is_none()) options.series = py::str(series);
        const std::optional<std::filesystem::path> out =
            output.is_none() ? std::nullopt : std::optional(output.cast<std::filesystem::path>());
        bool is_image = false;
        Segmentation seg;
        VoxelizeReport r;
        Segment s;
        {
          py::gil_scoped_release release;
          seg = voxelize_reference(reference, options, &is_image);
          s = segment_for_surface(seg, segment, surface);
          const SurfaceInLps lps = surface_in_lps(surface, parse_space(space), parse_length_unit(units));
          r = voxelize_into(seg, s, lps.V, surface.F, lps.displacement,
                            VoxelizeParams{.oversampling = oversampling, .full = full});
          if (out) write_segmentation(*out, seg);
        }
        py::dict report = segment_dict(s);
        report["partial"] = r.partial;
        report["moved_vertices"] = r.moved_vertices;
        report["added"] = r.change.added;
        report["removed"] = r.change.removed;
        report["conflicts"] = r.change.conflicts;
        report["decided_voxels"] = r.decided_voxels;
        report["vertices_outside_grid"] = r.vertices_outside_grid;
        report["reference_is_image"] = is_image;
        return py::make_tuple(segmentation_dict(seg), report);
      },
      py::arg("V"), py::arg("F"), py::arg("displacement"), py::arg("reference"), py::arg("segment"),
      py::arg("oversampling"), py::arg("full"), py::arg("space"), py::arg("units"), py::arg("series"),
      py::arg("output"));
}

}  // namespace meshpde::python
