// meshpde's mesh layer in Python: reading and writing, diagnostics, generators,
// normals, self-intersections and pictures.
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Sparse>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <optional>

#include "bindings.h"
#include "convert.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/surface_point_reading.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "meshpde/viz/render.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/dicom.h"
#include "meshpde/io/medical_io.h"
#endif

namespace meshpde::python {

namespace {

// FileNotFoundError (an OSError, as open() raises) rather than the library's InputError.
void require_file(const std::filesystem::path& path) {
  if (std::filesystem::exists(path)) return;
  errno = ENOENT;
  PyErr_SetFromErrnoWithFilename(PyExc_FileNotFoundError, path.c_str());
  throw py::error_already_set();
}

// numpy's name of a VTK array type (an unknown one reads as float64).
const char* numpy_type(const std::string& vtk) {
  static const std::pair<const char*, const char*> types[] = {
      {"Float32", "float32"}, {"Float64", "float64"}, {"Int8", "int8"},     {"UInt8", "uint8"}, {"Int16", "int16"},
      {"UInt16", "uint16"},   {"Int32", "int32"},     {"UInt32", "uint32"}, {"Int64", "int64"}, {"UInt64", "uint64"}};
  for (const auto& [v, n] : types)
    if (vtk == v) return n;
  return "float64";
}

// The VTK type an array is written as: its numpy dtype's (bool as UInt8; others Float64).
std::string vtk_type(const py::handle& obj) {
  if (!py::isinstance<py::array>(obj)) return "Float64";
  const py::dtype dt = obj.cast<py::array>().dtype();
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'b') return "UInt8";
  if (kind == 'f') return size == 4 ? "Float32" : "Float64";
  if (kind == 'i' || kind == 'u') {
    const std::string bits = std::to_string(8 * size);
    if (size == 1 || size == 2 || size == 4 || size == 8) return (kind == 'i' ? "Int" : "UInt") + bits;
  }
  return "Float64";
}

// Values (rows x cols, stored as doubles) as a numpy array of their file's type; one
// column as a 1-D array.
py::object typed(const Eigen::MatrixXd& m, const std::string& type) {
  py::object a = to_numpy(m).attr("astype")(numpy_type(type));
  return m.cols() == 1 ? a.attr("ravel")() : a;
}

// Vertex fields as Python sees them: NAME_x, NAME_y, NAME_z (the library's storage of a
// 3-vector field in every format) joined into one (n, 3) array NAME, other scalars as
// (n,) arrays, VTK point arrays of other widths as (n, k); each in its file's type.
py::dict fields_to_python(const MeshData& d) {
  py::dict out;
  const auto& s = d.vertex_scalars;
  auto type_of = [&](const std::string& key) {
    const auto it = d.scalar_types.find(key);
    return it == d.scalar_types.end() ? std::string("Float64") : it->second;
  };
  for (const auto& [name, values] : s) {
    if (name.size() > 2 && name.compare(name.size() - 2, 2, "_x") == 0) {
      const std::string base = name.substr(0, name.size() - 2);
      if (s.count(base + "_y") && s.count(base + "_z") && !s.count(base)) {
        Eigen::MatrixXd m(values.size(), 3);
        m << values, s.at(base + "_y"), s.at(base + "_z");
        out[py::str(base)] = typed(m, type_of(name));
        continue;
      }
    }
    if (name.size() > 2 &&
        (name.compare(name.size() - 2, 2, "_y") == 0 || name.compare(name.size() - 2, 2, "_z") == 0)) {
      const std::string base = name.substr(0, name.size() - 2);
      if (s.count(base + "_x") && s.count(base + "_y") && s.count(base + "_z") && !s.count(base)) continue;
    }
    out[py::str(name)] = typed(values, type_of(name));
  }
  for (const auto& [name, array] : d.point_arrays) out[py::str(name)] = typed(array.values, array.type);
  return out;
}

py::dict cells_to_python(const MeshData& d) {
  py::dict out;
  for (const auto& [name, array] : d.cell_arrays) out[py::str(name)] = typed(array.values, array.type);
  return out;
}

// Field data: strings as str, arrays of one tuple as 1-D arrays, others (tuples, k).
py::dict field_data_to_python(const MeshData& d) {
  py::dict out;
  for (const auto& [name, value] : d.field_strings) out[py::str(name)] = value;
  for (const auto& [name, array] : d.field_arrays)
    out[py::str(name)] = array.values.rows() == 1 ? typed(array.values.transpose(), array.type).attr("ravel")()
                                                  : typed(array.values, array.type);
  return out;
}

void fields_from_python(const py::handle& fields, Eigen::Index nv, MeshData& d) {
  if (fields.is_none()) return;
  if (!py::isinstance<py::dict>(fields)) throw py::type_error("fields: expected a dict of name -> array");
  for (const auto& [key, value] : fields.cast<py::dict>()) {
    const std::string name = py::str(key);
    const std::string what = fmt::format("fields['{}']", name);
    const Field f = field_arg(value, what.c_str(), nv);
    const std::string type = vtk_type(value);
    if (f.cols() == 1) {
      d.vertex_scalars[name] = f.col(0);
      d.scalar_types[name] = type;
    } else if (f.cols() == 3) {
      const char* suffix[3] = {"_x", "_y", "_z"};
      for (int c = 0; c < 3; ++c) {
        d.vertex_scalars[name + suffix[c]] = f.col(c);
        d.scalar_types[name + suffix[c]] = type;
      }
    } else {
      d.point_arrays[name] = DataArray{Eigen::MatrixXd(f), type};
    }
  }
}

void cells_from_python(const py::handle& cells, Eigen::Index nf, MeshData& d) {
  if (cells.is_none()) return;
  if (!py::isinstance<py::dict>(cells)) throw py::type_error("cells: expected a dict of name -> array");
  for (const auto& [key, value] : cells.cast<py::dict>()) {
    const std::string name = py::str(key);
    const std::string what = fmt::format("cells['{}']", name);
    d.cell_arrays[name] = DataArray{Eigen::MatrixXd(field_arg(value, what.c_str(), nf)), vtk_type(value)};
  }
}

void field_data_from_python(const py::handle& field_data, MeshData& d) {
  if (field_data.is_none()) return;
  if (!py::isinstance<py::dict>(field_data)) throw py::type_error("field_data: expected a dict of name -> value");
  for (const auto& [key, value] : field_data.cast<py::dict>()) {
    const std::string name = py::str(key);
    if (py::isinstance<py::str>(value)) {
      d.field_strings[name] = value.cast<std::string>();
      continue;
    }
    const std::string what = fmt::format("field_data['{}']", name);
    const py::array a = py::array::ensure(value);
    Field f = field_arg(value, what.c_str());
    if (a && a.ndim() <= 1) f = Field(f.transpose());  // one tuple of k components
    d.field_arrays[name] = DataArray{Eigen::MatrixXd(f), vtk_type(value)};
  }
}

// A mesh's report with the units warning (as `meshpde info` prints it), also raised as a
// UserWarning.
py::dict with_units_warning(py::dict report, const std::string& warning) {
  report["units_warning"] = warning.empty() ? py::object(py::none()) : py::object(py::str(warning));
  if (!warning.empty()) PyErr_WarnEx(PyExc_UserWarning, warning.c_str(), 1);
  return report;
}

py::dict report_to_python(const MeshReport& r) {
  return json_to_python(to_json(r));
}

py::tuple vec3(const Eigen::Vector3d& v) {
  return py::make_tuple(v.x(), v.y(), v.z());
}

// A 3 x 3 matrix as a tuple of its rows (a direction's columns are the voxel axes).
py::tuple matrix3(const Eigen::Matrix3d& m) {
  return py::make_tuple(vec3(m.row(0).transpose()), vec3(m.row(1).transpose()), vec3(m.row(2).transpose()));
}

py::dict volume_report_to_python(const VolumeReport& r) {
  return json_to_python(to_json(r));
}

#ifdef MESHPDE_HAVE_MEDICAL
// What `meshpde info DIR --json` prints of DICOM input.
py::dict dicom_info_to_python(const std::filesystem::path& path) {
  DicomListing listing;
  std::optional<VolumeReport> volume;
  {
    py::gil_scoped_release release;
    listing = list_dicom_series(path);
    if (listing.series.size() == 1 && listing.series.front().problem.empty())
      volume = describe(read_dicom_series(path, listing.series.front().uid));
  }
  py::list series;
  for (const auto& s : listing.series) {
    py::dict d;
    d["uid"] = s.uid;
    d["number"] = s.number;
    d["description"] = s.description;
    d["modality"] = s.modality;
    d["size"] = py::make_tuple(s.size[0], s.size[1], s.size[2]);
    d["spacing"] = vec3(s.spacing);
    d["origin"] = vec3(s.origin);
    d["direction"] = matrix3(s.direction);
    py::list files;
    for (const auto& f : s.files) files.append(f.string());
    d["files"] = files;
    if (!s.problem.empty()) d["problem"] = s.problem;
    series.append(d);
  }
  py::dict j;
  j["kind"] = "dicom";
  j["path"] = path.string();
  j["series"] = series;
  j["skipped"] = listing.skipped;
  if (volume) {
    py::dict v = volume_report_to_python(*volume);
    v["series"] = listing.series.front().uid;
    j["volume"] = v;
  }
  return j;
}
#endif

py::tuple generated(const GeneratedMesh& g) {
  return py::make_tuple(to_numpy(Eigen::MatrixXd(g.V)), to_numpy(g.F));
}

}  // namespace

void bind_mesh(py::module_& m) {
  m.def(
      "_read_mesh",
      [](const std::filesystem::path& path) {
        require_file(path);
        MeshData d;
        {
          py::gil_scoped_release release;
          d = read_mesh(path);
        }
        for (const auto& w : d.warnings) {
          // The readers' warnings name the file already; the others get its name.
          const std::string text = w.rfind(path.string(), 0) == 0 ? w : fmt::format("{}: {}", path.string(), w);
          PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1);
        }
        return py::make_tuple(to_numpy(Eigen::MatrixXd(d.V)), to_numpy(d.F), fields_to_python(d), cells_to_python(d),
                              d.space.empty() ? py::object(py::none()) : py::object(py::str(d.space)),
                              field_data_to_python(d));
      },
      py::arg("path"));

  m.def(
      "_write_mesh",
      [](const std::filesystem::path& path, const ArrayLike& V, const ArrayLike& F, const py::handle& fields,
         bool binary, const py::handle& cells, const py::handle& space, const py::handle& field_data) {
        MeshData d;
        d.V = positions_arg(V);
        d.F = triangles_arg(F, d.V.rows());
        fields_from_python(fields, d.V.rows(), d);
        cells_from_python(cells, d.F.rows(), d);
        field_data_from_python(field_data, d);
        if (!space.is_none()) d.space = to_string(parse_space(py::str(space).cast<std::string>()));
        std::vector<std::string> warnings;
        {
          py::gil_scoped_release release;
          warnings = write_mesh(path, d, WriteOptions{.binary = binary});
        }
        for (const auto& w : warnings)
          PyErr_WarnEx(PyExc_UserWarning, fmt::format("{}: {}", path.string(), w).c_str(), 1);
        return warnings;
      },
      py::arg("path"), py::arg("V"), py::arg("F"), py::arg("fields"), py::arg("binary"), py::arg("cells"),
      py::arg("space"), py::arg("field_data"));

  m.def(
      "_refresh_normals",
      [](const ArrayLike& V, const ArrayLike& F, const py::handle& fields, const py::handle& cells) {
        MeshData d;
        d.V = positions_arg(V);
        d.F = triangles_arg(F, d.V.rows());
        fields_from_python(fields, d.V.rows(), d);
        cells_from_python(cells, d.F.rows(), d);
        const std::vector<std::string> names = refresh_normal_fields(d);
        return py::make_tuple(fields_to_python(d), cells_to_python(d), names);
      },
      py::arg("V"), py::arg("F"), py::arg("fields"), py::arg("cells"));

  m.def(
      "info",
      [](const ArrayLike& V, const ArrayLike& F) -> py::dict {
        if (F.is_none()) {  // info(path): a mesh file, or a volume
          const auto path = V.cast<std::filesystem::path>();
          require_file(path);
#ifdef MESHPDE_HAVE_MEDICAL
          if (!is_volume_path(path) && is_dicom_path(path)) return dicom_info_to_python(path);
          if (is_volume_path(path)) {
            VolumeReport r;
            {
              py::gil_scoped_release release;
              r = describe(read_volume(path));
            }
            return volume_report_to_python(r);
          }
#endif
          MeshData d;
          {
            py::gil_scoped_release release;
            d = read_mesh(path);
          }
          const Mesh mesh(d.V, d.F);
          MeshReport r;
          std::string w;
          {
            py::gil_scoped_release release;
            r = analyze(mesh);
            w = units_warning(mesh, LengthUnit::Millimetre, path.string(), "units=");
          }
          return with_units_warning(report_to_python(r), w);
        }
        const Mesh mesh = mesh_arg(V, F);
        MeshReport r;
        std::string w;
        {
          py::gil_scoped_release release;
          r = analyze(mesh);
          w = units_warning(mesh, LengthUnit::Millimetre, "V", "units=");
        }
        return with_units_warning(report_to_python(r), w);
      },
      R"doc(info(V, F) or info(path) -> dict

The report of `meshpde info --json`: counts, boundary loops, non-manifold edges and
vertices, components, orientation, signed volume, angles, warnings. For a volume file:
dims, spacing, origin, direction (LPS; rows of the matrix whose columns are the voxel
axes), orientation code, extent, value range. For DICOM (a folder or one file): kind
"dicom", every series found ("series": uid, number, description, modality, size,
spacing, origin, direction, files in slice order, and "problem" when it is not one
regular grid), the files passed over ("skipped"), and with a single series its
"volume".)doc",
      py::arg("V"), py::arg("F") = py::none());

  m.def(
      "check_units",
      [](const ArrayLike& V, const ArrayLike& F, const std::string& units) -> py::dict {
        const LengthUnit unit = parse_length_unit(units);
        const Mesh mesh = mesh_arg(V, F);
        const UnitsCheck c = check_units(mesh, unit);
        py::dict d;
        d["units"] = to_string(unit);
        d["diagonal_mm"] = c.diagonal_mm;
        d["mean_edge_mm"] = c.mean_edge_mm;
        d["median_radius_mm"] = c.median_radius_mm;
        d["implausible"] = c.implausible;
        d["suggested"] = c.suggested ? py::object(py::str(to_string(*c.suggested))) : py::object(py::none());
        const std::string w = units_warning(mesh, unit, "V", "units=");
        d["warning"] = w.empty() ? py::object(py::none()) : py::object(py::str(w));
        return d;
      },
      R"doc(check_units(V, F, units="mm") -> dict

What V looks like in millimetres when read in `units` ("mm", "cm" or "m"): its
bounding-box diagonal and mean edge (`diagonal_mm`, `mean_edge_mm`), the median vessel
radius when it matters (`median_radius_mm`: measured on models under 60 mm across with
edges under 0.15 mm, else 0), whether that is unlike a vessel model (`implausible`:
outside 15 mm to 2 m across or 0.02 to 8 mm edges, or under 60 mm across with edges
under 0.15 mm and vessels under 2 mm in radius, finer than a scanner resolves: a
SimVascular model in centimetres) and the unit that would fit (`suggested`, or None),
as `correct(units=)` warns.)doc",
      py::arg("V"), py::arg("F"), py::arg("units") = "mm");

  m.def(
      "vertex_normals",
      [](const ArrayLike& V, const ArrayLike& F, bool outward) {
        const Mesh mesh = mesh_arg(V, F);
        return to_numpy(Eigen::MatrixXd(outward ? outward_vertex_normals(mesh) : vertex_normals(mesh)));
      },
      R"doc(vertex_normals(V, F, outward=True) -> (n, 3)

Area-weighted unit normals; outward=True turns them away from the enclosed volume of a
closed mesh whatever its triangles' orientation. Zero rows for vertices without area.)doc",
      py::arg("V"), py::arg("F"), py::arg("outward") = true);

  m.def(
      "geodesic_ball",
      [](const ArrayLike& V, const ArrayLike& F, long long vertex, double radius) {
        const Mesh mesh = mesh_arg(V, F);
        if (!(radius > 0) || !std::isfinite(radius))
          throw InputError(fmt::format("radius: expected a length > 0, got {}", radius));
        return to_numpy(geodesic_ball(mesh, vertex_arg(vertex, "vertex", mesh.num_vertices()), radius));
      },
      R"doc(geodesic_ball(V, F, vertex, radius) -> indices

Vertices whose edge-path distance from `vertex` is below `radius` (mesh units), nearest first.)doc",
      py::arg("V"), py::arg("F"), py::arg("vertex"), py::arg("radius"));
  m.def(
      "ring_ball",
      [](const ArrayLike& V, const ArrayLike& F, long long vertex, int rings) {
        const Mesh mesh = mesh_arg(V, F);
        if (rings < 0) throw InputError(fmt::format("rings: expected >= 0, got {}", rings));
        return to_numpy(ring_ball(mesh, vertex_arg(vertex, "vertex", mesh.num_vertices()), rings));
      },
      R"doc(ring_ball(V, F, vertex, rings) -> indices

Vertices within `rings` edges of `vertex`.)doc",
      py::arg("V"), py::arg("F"), py::arg("vertex"), py::arg("rings"));

  m.def(
      "self_intersections",
      [](const ArrayLike& V, const ArrayLike& F) {
        const Mesh mesh = mesh_arg(V, F);
        std::vector<std::pair<int, int>> pairs;
        {
          py::gil_scoped_release release;
          pairs = SelfIntersectionChecker(mesh).all_pairs();
        }
        py::array_t<int> a({static_cast<py::ssize_t>(pairs.size()), py::ssize_t(2)});
        auto w = a.mutable_unchecked<2>();
        for (std::size_t k = 0; k < pairs.size(); ++k) {
          w(k, 0) = pairs[k].first;
          w(k, 1) = pairs[k].second;
        }
        return a;
      },
      R"doc(self_intersections(V, F) -> (p, 2) int

Pairs of triangles (i < j) that overlap beyond the corners or edge they share: crossing
triangles, coplanar overlaps, triangles of one corner meeting elsewhere, and two wings
of an edge folded onto each other (mesh/self_intersections.h; CGAL's
Polygon_mesh_processing::self_intersections counts the same pairs).)doc",
      py::arg("V"), py::arg("F"));

  m.def(
      "hausdorff_distance",
      [](const ArrayLike& VA, const ArrayLike& FA, const ArrayLike& VB, const ArrayLike& FB, bool directed) {
        const Mesh a = mesh_arg(VA, FA), b = mesh_arg(VB, FB);
        py::gil_scoped_release release;
        return directed ? directed_hausdorff(a.positions(), a.triangles(), b.positions(), b.triangles())
                        : hausdorff_distance(a.positions(), a.triangles(), b.positions(), b.triangles());
      },
      R"doc(hausdorff_distance(VA, FA, VB, FB, directed=False) -> float

The symmetric Hausdorff distance between two triangle surfaces (with directed=True,
from A to B only): sampled at every vertex and triangle centroid of a surface and
measured exactly to the other (mesh/surface_distance.h). Units of the positions.)doc",
      py::arg("VA"), py::arg("FA"), py::arg("VB"), py::arg("FB"), py::arg("directed") = false);

  m.def(
      "closest_surface_points",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& points) {
        const Mesh mesh = mesh_arg(V, F);
        const std::vector<Eigen::Vector3d> at = points_arg(points, "points");
        std::vector<SurfacePoint> found;
        {
          py::gil_scoped_release release;
          found = closest_surface_points(mesh, at);
        }
        std::vector<int> faces;
        Eigen::MatrixXd bary(static_cast<Eigen::Index>(found.size()), 3);
        for (std::size_t k = 0; k < found.size(); ++k) {
          faces.push_back(found[k].face);
          bary.row(static_cast<Eigen::Index>(k)) = found[k].bary.transpose();
        }
        return py::make_tuple(to_numpy(faces), to_numpy(bary));
      },
      R"doc(closest_surface_points(V, F, points) -> (faces, barycentric)

The surface point nearest to each of the (k, 3) points: its triangle (k,) and its
barycentric coordinates (k, 3), one weight per corner F[face], >= 0, summing to 1.
A field on the vertices at those points is ``(bary[:, :, None] * field[F[faces]]).sum(1)``.)doc",
      py::arg("V"), py::arg("F"), py::arg("points"));

  m.def(
      "quadratic_reading",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& points) {
        const Mesh mesh = mesh_arg(V, F);
        const std::vector<Eigen::Vector3d> at = points_arg(points, "points");
        std::vector<Eigen::Triplet<double>> weights;
        {
          py::gil_scoped_release release;
          const std::vector<SurfacePoint> found = closest_surface_points(mesh, at);
          for (std::size_t k = 0; k < found.size(); ++k) {
            const auto row = static_cast<int>(k);
            if (const auto reading = quadratic_reading(mesh, found[k])) {
              for (const auto& [v, w] : *reading) weights.emplace_back(row, v, w);
            } else {  // no fit around the point: its corners, linearly
              for (int c = 0; c < 3; ++c)
                weights.emplace_back(row, mesh.triangles()(found[k].face, c), found[k].bary[c]);
            }
          }
        }
        Eigen::SparseMatrix<double, Eigen::RowMajor> W(static_cast<Eigen::Index>(at.size()), mesh.num_vertices());
        W.setFromTriplets(weights.begin(), weights.end());
        return to_csr(W);
      },
      R"doc(quadratic_reading(V, F, points) -> scipy.sparse.csr_matrix (k x n)

Weights that read a vertex field at the surface point nearest to each of the (k, 3)
points to second order: ``W @ field`` is, per point, the value of the weighted
least-squares quadratic fitted to the field at the vertices around it, in the plane of
its triangle (mesh/surface_point_reading.h; exact on quadratics, 50 to 200 times closer
than the corners' linear interpolation on a sphere). Where no sound fit exists (too
few vertices within 4 edges, a surface that turns more than about 27 degrees around the
point, a fit that would amplify noise) a row holds the corners' barycentric weights. A
correction reads a handle with a size this way.)doc",
      py::arg("V"), py::arg("F"), py::arg("points"));

  m.def(
      "geodesic_distance",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& sources, double radius) {
        const Mesh mesh = mesh_arg(V, F);
        GeodesicSources s;
        const py::array a = py::array::ensure(sources);
        if (a && a.ndim() == 2 && a.dtype().kind() == 'f') {
          s.points = closest_surface_points(mesh, points_arg(sources, "sources"));
        } else {
          s.vertices = vertices_arg(sources, "sources", mesh.num_vertices());
        }
        if (s.vertices.empty() && s.points.empty()) throw InputError("sources: give at least one vertex or point");
        if (std::isnan(radius) || !(radius > 0)) throw InputError("radius: expected a length > 0");
        Eigen::VectorXd d;
        {
          py::gil_scoped_release release;
          d = geodesic_distance(mesh, s, radius);
        }
        return to_numpy(d);
      },
      R"doc(geodesic_distance(V, F, sources, radius=inf) -> (n,) array

Distance along the surface (not along edges) from the nearest source to every vertex;
inf where none was reached (beyond ``radius``, or on another connected part). sources:
vertex indices (an int or integer array), or a (k, 3) float array of points, each
placed at the surface point nearest to it. Exact on planes and on surfaces that unroll
onto one; on curved ones the error falls like the edge length (mesh/geodesic_distance.h).
Units of V.)doc",
      py::arg("V"), py::arg("F"), py::arg("sources"), py::arg("radius") = std::numeric_limits<double>::infinity());

  m.def(
      "render",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& field, const ArrayLike& vectors,
         const OptionalPath& path, int width, int height, double azimuth, double elevation, const std::string& up,
         double zoom, const ArrayLike& center, bool wireframe, const std::string& colormap, const ArrayLike& range,
         const std::string& title, const std::string& field_name) -> py::object {
        const Mesh mesh = mesh_arg(V, F);
        if (width < 16 || height < 16 || width > 8192 || height > 8192)
          throw InputError(fmt::format("width, height: expected 16..8192 pixels, got {} x {}", width, height));
        RenderOptions o;
        o.width = width;
        o.height = height;
        o.azimuth_deg = azimuth;
        o.elevation_deg = elevation;
        o.up_axis = parse_up_axis(up);
        o.zoom = zoom;
        if (!center.is_none()) o.center = Eigen::Vector3d(vector_arg(center, "center", 3));
        o.wireframe = wireframe;
        o.colormap = parse_colormap(colormap);
        o.title = title;
        o.field_name = field_name;
        if (!field.is_none()) o.field = vector_arg(field, "field", mesh.num_vertices());
        if (!vectors.is_none()) o.vectors = Eigen::MatrixX3d(field_arg(vectors, "vectors", mesh.num_vertices(), 3));
        if (!range.is_none()) {
          const Eigen::VectorXd r = vector_arg(range, "range", 2);
          o.range = std::make_pair(r[0], r[1]);
        }
        const std::optional<std::filesystem::path> png =
            path.is_none() ? std::nullopt : std::optional(path.cast<std::filesystem::path>());
        Image img;
        {
          py::gil_scoped_release release;
          img = render(mesh.positions(), mesh.triangles(), o);
          if (png) write_png(*png, img);
        }
        if (png) return py::none();
        py::array_t<std::uint8_t> a({img.height, img.width, 3});
        std::copy(img.rgb.begin(), img.rgb.end(), a.mutable_data());
        return a;
      },
      R"doc(render(V, F, field=None, vectors=None, path=None, ...) -> (height, width, 3) uint8 or None

A headless picture: shading, a colour map of `field` (n,) with its legend, arrows of
`vectors` (n, 3). With `path` writes a PNG and returns None.)doc",
      py::arg("V"), py::arg("F"), py::arg("field") = py::none(), py::arg("vectors") = py::none(),
      py::arg("path") = py::none(), py::arg("width") = 960, py::arg("height") = 720, py::arg("azimuth") = 30.0,
      py::arg("elevation") = 20.0, py::arg("up") = "y", py::arg("zoom") = 1.0, py::arg("center") = py::none(),
      py::arg("wireframe") = false, py::arg("colormap") = "viridis", py::arg("range") = py::none(),
      py::arg("title") = "", py::arg("field_name") = "");

#ifdef MESHPDE_HAVE_MEDICAL
  m.def(
      "read_volume",
      [](const std::filesystem::path& path, const SeriesChoice& series) {
        require_file(path);
        VolumeReadOptions options;
        if (!series.is_none()) options.series = py::str(py::handle(series));
        Volume v;
        {
          py::gil_scoped_release release;
          v = read_volume(path, options);
        }
        // values[i, j, k]: the file's i-fastest order is numpy's Fortran order.
        py::array_t<float, py::array::f_style> a({v.dims[0], v.dims[1], v.dims[2]});
        std::copy(v.values.begin(), v.values.end(), a.mutable_data());
        Eigen::Matrix4d affine = Eigen::Matrix4d::Identity();
        affine.topLeftCorner<3, 3>() = v.direction * v.spacing.asDiagonal();
        affine.topRightCorner<3, 1>() = v.origin;
        return py::make_tuple(std::move(a), to_numpy(Eigen::MatrixXd(affine)));
      },
      R"doc(read_volume(path, series=None) -> (values, affine)

values[i, j, k] float32 and the 4 x 4 affine from voxel indices to LPS millimetres.
.mha/.mhd, .nii/.nii.gz (sform, else qform), .nrrd/.nhdr, or DICOM: a folder holding
a series (searched recursively) or one file of it, slices ordered along their normal,
rescale slope and intercept applied (CT in HU). `series` chooses one of several series
in a folder by SeriesInstanceUID or series number; without it a folder of several
raises InputError listing them.)doc",
      py::arg("path"), py::arg("series") = py::none());
#endif

  py::module_ g = m.def_submodule("generate", "Meshes the project generates (the table of `meshpde generate`).");
  const GeneratorParams d;
  g.def("names", [] { return generator_names(); });
  g.def(
      "latlong",
      [](int n, double radius) {
        GeneratorParams p;
        p.n = n;
        p.radius = radius;
        return generated(generate("latlong", p));
      },
      py::arg("n") = d.n, py::arg("radius") = d.radius);
  g.def(
      "icosphere",
      [](int level, double radius) {
        GeneratorParams p;
        p.level = level;
        p.radius = radius;
        return generated(generate("icosphere", p));
      },
      py::arg("level") = d.level, py::arg("radius") = d.radius);
  g.def(
      "geodesic",
      [](const std::string& base, int frequency, double radius) {
        GeneratorParams p;
        if (base != "icosahedron" && base != "tetrahedron")
          throw InputError(fmt::format("base: expected 'icosahedron' or 'tetrahedron', got '{}'", base));
        p.base = base == "tetrahedron" ? BaseSolid::Tetrahedron : BaseSolid::Icosahedron;
        p.frequency = frequency;
        p.radius = radius;
        return generated(generate("geodesic", p));
      },
      py::arg("base") = "icosahedron", py::arg("frequency") = d.frequency, py::arg("radius") = d.radius);
  g.def(
      "tube",
      [](double radius, double length, int rings, int segments) {
        GeneratorParams p;
        p.radius = radius;
        p.length = length;
        p.rings = rings;
        p.segments = segments;
        return generated(generate("tube", p));
      },
      py::arg("radius") = d.radius, py::arg("length") = d.length, py::arg("rings") = d.rings,
      py::arg("segments") = d.segments);
  g.def(
      "plane",
      [](int nx, int ny, double size) {
        GeneratorParams p;
        p.nx = nx;
        p.ny = ny;
        p.size = size;
        return generated(generate("plane", p));
      },
      py::arg("nx") = d.nx, py::arg("ny") = d.ny, py::arg("size") = d.size);
  g.def(
      "fins",
      [](int k, int n) {
        GeneratorParams p;
        p.k = k;
        p.n = n;
        return generated(generate("fins", p));
      },
      py::arg("k") = d.k, py::arg("n") = d.n);
  const BifurcationParams b = d.bifurcation;
  g.def(
      "bifurcation",
      [](double cell, bool dent, double trunk_radius, double branch_radius, double trunk_length, double branch_length,
         double angle_deg, double dent_depth, double dent_radius) {
        GeneratorParams p;
        p.bifurcation.cell = cell;
        p.bifurcation.dent = dent;
        p.bifurcation.trunk_radius = trunk_radius;
        p.bifurcation.branch_radius = branch_radius;
        p.bifurcation.trunk_length = trunk_length;
        p.bifurcation.branch_length = branch_length;
        p.bifurcation.angle_deg = angle_deg;
        p.bifurcation.dent_depth = dent_depth;
        p.bifurcation.dent_radius = dent_radius;
        GeneratedMesh mesh;
        {
          py::gil_scoped_release release;
          mesh = generate("bifurcation", p);
        }
        return generated(mesh);
      },
      py::arg("cell") = b.cell, py::arg("dent") = b.dent, py::arg("trunk_radius") = b.trunk_radius,
      py::arg("branch_radius") = b.branch_radius, py::arg("trunk_length") = b.trunk_length,
      py::arg("branch_length") = b.branch_length, py::arg("angle_deg") = b.angle_deg,
      py::arg("dent_depth") = b.dent_depth, py::arg("dent_radius") = b.dent_radius);
  g.def(
      "subdivide",
      [](const ArrayLike& V, const ArrayLike& F) {
        const Mesh mesh = mesh_arg(V, F);
        return generated(subdivide_midpoint(mesh.positions(), mesh.triangles()));
      },
      py::arg("V"), py::arg("F"));
}

}  // namespace meshpde::python
