// meshpde info | generate | curvature
#include <fmt/format.h>

#include <limits>
#include <memory>
#include <optional>

#include "commands.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/dicom.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/segmentation_io.h"
#endif
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "meshpde/operators/curvature.h"
#include "meshpde/operators/fem_operators.h"

namespace meshpde::cli {

namespace {

nlohmann::json report_json(const MeshReport& r) {
  return nlohmann::json::parse(to_json(r));
}

void print_report(const std::string& name, const MeshReport& r) {
  fmt::print("{}\n", name);
  fmt::print("  vertices {}  faces {}  edges {}\n", r.vertices, r.faces, r.edges);
  fmt::print("  components {}  boundary loops {}  Euler characteristic {}\n", r.components, r.boundary_loops,
             r.euler_characteristic);
  fmt::print("  non-manifold edges {}  non-manifold vertices {}\n", r.nonmanifold_edges, r.nonmanifold_vertices);
  fmt::print("  degenerate faces {}  duplicate vertices {}  unreferenced vertices {}\n", r.degenerate_faces,
             r.duplicate_vertices, r.unreferenced_vertices);
  fmt::print("  orientation {}  signed volume {:.6g}{}\n",
             r.orientation_consistent ? "consistent" : fmt::format("inconsistent ({} edges)", r.inconsistent_edges),
             r.signed_volume,
             r.boundary_loops == 0 && r.orientation_consistent
                 ? (r.signed_volume < 0 ? " (normals point inward)" : " (normals point outward)")
                 : "");
  fmt::print("  area {:.6g}  mean edge length {:.6g}\n", r.area, r.mean_edge_length);
  fmt::print("  angles {:.4g} .. {:.4g} deg  area ratio {:.4g}\n", r.min_angle_deg, r.max_angle_deg, r.area_ratio);
  fmt::print("  bounding box ({:.6g}, {:.6g}, {:.6g}) .. ({:.6g}, {:.6g}, {:.6g})\n", r.bbox_min.x(), r.bbox_min.y(),
             r.bbox_min.z(), r.bbox_max.x(), r.bbox_max.y(), r.bbox_max.z());
  for (const auto& w : r.warnings) fmt::print("  warning: {}\n", w);
}

nlohmann::json vec3(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

// A 3 x 3 matrix as a list of its rows (a direction's columns are the voxel axes).
nlohmann::json matrix3(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back(vec3(m.row(r).transpose()));
  return rows;
}

nlohmann::json volume_report_json(const VolumeReport& r) {
  return nlohmann::json::parse(to_json(r));
}

void print_volume_report(const std::string& path, const VolumeReport& r) {
  fmt::print("{}: volume of {} x {} x {} voxels\n", path, r.dims[0], r.dims[1], r.dims[2]);
  fmt::print("  spacing      {:.6g} x {:.6g} x {:.6g} mm\n", r.spacing.x(), r.spacing.y(), r.spacing.z());
  fmt::print("  origin       ({:.6g}, {:.6g}, {:.6g}) mm, LPS\n", r.origin.x(), r.origin.y(), r.origin.z());
  for (int c = 0; c < 3; ++c)
    fmt::print("  axis {}       ({:.6g}, {:.6g}, {:.6g}) LPS\n", "ijk"[c], r.direction(0, c), r.direction(1, c),
               r.direction(2, c));
  fmt::print("  orientation  {}{} (the patient direction of i, j, k)\n", r.orientation, r.oblique ? ", oblique" : "");
  fmt::print("  extent       ({:.6g}, {:.6g}, {:.6g}) .. ({:.6g}, {:.6g}, {:.6g}) mm, LPS\n", r.bbox_min.x(),
             r.bbox_min.y(), r.bbox_min.z(), r.bbox_max.x(), r.bbox_max.y(), r.bbox_max.z());
  fmt::print("  values       {:.6g} .. {:.6g}, mean {:.6g}{}\n", r.min, r.max, r.mean,
             r.nonfinite ? fmt::format(", {} not finite", r.nonfinite) : std::string());
}

#ifdef MESHPDE_HAVE_MEDICAL
nlohmann::json series_json(const DicomSeries& s) {
  nlohmann::json files = nlohmann::json::array();
  for (const auto& f : s.files) files.push_back(f.string());
  nlohmann::json j = {{"uid", s.uid},
                      {"number", s.number},
                      {"description", s.description},
                      {"modality", s.modality},
                      {"size", {s.size[0], s.size[1], s.size[2]}},
                      {"spacing", vec3(s.spacing)},
                      {"origin", vec3(s.origin)},
                      {"direction", matrix3(s.direction)},
                      {"files", files}};
  if (!s.problem.empty()) j["problem"] = s.problem;
  return j;
}

// meshpde info on a segmentation with a segment table: its grid and its segments.
void segmentation_info(const std::string& path, bool json) {
  const Segmentation seg = read_segmentation(path);
  std::vector<std::size_t> voxels(seg.segments.size(), 0);
  for (std::size_t k = 0; k < seg.segments.size(); ++k)
    for (std::size_t v = 0; v < seg.num_voxels(); ++v)
      voxels[k] += seg.at(v, seg.segments[k].layer) == seg.segments[k].label;
  const auto& g = seg.geometry;
  if (json) {
    nlohmann::json segments = nlohmann::json::array();
    for (std::size_t k = 0; k < seg.segments.size(); ++k) {
      const Segment& s = seg.segments[k];
      segments.push_back({{"index", s.index},
                          {"id", s.id},
                          {"name", s.name},
                          {"label", s.label},
                          {"layer", s.layer},
                          {"color", vec3(s.color)},
                          {"voxels", voxels[k]}});
    }
    print_json({{"kind", "segmentation"},
                {"format", to_string(seg.format)},
                {"dims", {g.dims[0], g.dims[1], g.dims[2]}},
                {"spacing", vec3(g.spacing)},
                {"origin", vec3(g.origin)},
                {"direction", matrix3(g.direction)},
                {"frame", "LPS"},
                {"layers", seg.layers},
                {"segments", segments}});
    return;
  }
  fmt::print("{}: segmentation of {} x {} x {} voxels of {:.4g} x {:.4g} x {:.4g} mm, {} layer{}, {} segment{}\n", path,
             g.dims[0], g.dims[1], g.dims[2], g.spacing.x(), g.spacing.y(), g.spacing.z(), seg.layers,
             seg.layers == 1 ? "" : "s", seg.segments.size(), seg.segments.size() == 1 ? "" : "s");
  fmt::print("  origin ({:.6g}, {:.6g}, {:.6g}) mm, LPS\n", g.origin.x(), g.origin.y(), g.origin.z());
  for (std::size_t k = 0; k < seg.segments.size(); ++k) {
    const Segment& s = seg.segments[k];
    fmt::print("  segment {}: '{}' (ID {}), label {} in layer {}, {} voxels\n", s.index, s.name, s.id, s.label, s.layer,
               voxels[k]);
  }
}

// meshpde info on DICOM input: every series, and the volume of the one chosen (or the only one).
void dicom_info(const std::string& path, const std::string& choice, bool json) {
  const DicomListing listing = list_dicom_series(path);
  const DicomSeries* chosen = nullptr;
  if (listing.series.size() == 1 || !choice.empty()) chosen = &choose_dicom_series(listing, choice, path);
  std::optional<VolumeReport> volume;
  if (chosen && chosen->problem.empty()) volume = describe(read_dicom_series(path, chosen->uid));
  if (json) {
    nlohmann::json j = {{"kind", "dicom"}, {"path", path}, {"series", nlohmann::json::array()}};
    for (const auto& s : listing.series) j["series"].push_back(series_json(s));
    j["skipped"] = listing.skipped;
    if (volume) {
      j["volume"] = volume_report_json(*volume);
      j["volume"]["series"] = chosen->uid;
    }
    print_json(j);
    return;
  }
  const std::size_t skipped = listing.skipped.size();
  fmt::print("{}: {} DICOM series{}\n", path, listing.series.size(),
             skipped ? fmt::format(" ({} file{} passed over)", skipped, skipped == 1 ? "" : "s") : "");
  for (const auto& s : listing.series) {
    fmt::print("  series {} ({}){}{}: {} file{}, ", s.number, s.uid, s.modality.empty() ? "" : " " + s.modality,
               s.description.empty() ? "" : " '" + s.description + "'", s.files.size(), s.files.size() == 1 ? "" : "s");
    if (s.problem.empty())
      fmt::print("{} x {} x {} voxels of {:.4g} x {:.4g} x {:.4g} mm\n", s.size[0], s.size[1], s.size[2], s.spacing.x(),
                 s.spacing.y(), s.spacing.z());
    else
      fmt::print("not readable as one volume: {}\n", s.problem);
  }
  for (const auto& w : listing.skipped) fmt::print("  passed over: {}\n", w);
  if (volume)
    print_volume_report(path, *volume);
  else if (!chosen)
    fmt::print("choose a series with --series UID|NUMBER (info --series shows its volume)\n");
}
#endif

struct GenerateArgs {
  std::string kind, out, base = "icosahedron";
  GeneratorParams p;  // defaults: the library's one table
};

}  // namespace

void add_mesh_commands(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand("info", "Report counts, topology, defects and shape quality of a mesh");
    auto path = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    auto series = std::make_shared<std::string>();
    cmd->add_option("FILE", *path,
                    "Mesh (.obj .off .ply .stl .vtp .vtk) or, with the medical component, volume (.mha .mhd .nii "
                    ".nii.gz .nrrd .nhdr) or DICOM (a folder, searched recursively, or one file)")
        ->required();
    cmd->add_flag("--json", *json, "Print a JSON object");
    cmd->add_option("--series", *series, "DICOM: the series to describe as a volume, by UID or series number");
    cmd->callback([=] {
#ifdef MESHPDE_HAVE_MEDICAL
      if (!is_volume_path(*path) && is_dicom_path(*path)) {
        dicom_info(*path, *series, *json);
        return;
      }
      if (holds_segments(*path)) {
        segmentation_info(*path, *json);
        return;
      }
      if (is_volume_path(*path)) {
        const VolumeReport r = describe(read_volume(*path));
        if (*json)
          print_json(volume_report_json(r));
        else
          print_volume_report(*path, r);
        return;
      }
#endif
      const Mesh mesh = load_mesh(*path);
      const MeshReport r = analyze(mesh);
      // A model whose sizes look like another unit than millimetres (mesh/units.h's rule).
      const std::string units = units_warning(mesh, LengthUnit::Millimetre, *path, "--units ");
      if (*json) {
        nlohmann::json j = report_json(r);
        j["units_warning"] = units.empty() ? nlohmann::json() : nlohmann::json(units);
        print_json(j);
      } else {
        print_report(*path, r);
        if (!units.empty()) fmt::print("  warning: {}\n", units);
      }
    });
  }
  {
    auto* cmd = app.add_subcommand("convert",
                                   "Convert a mesh between formats, keeping its vertex fields and data arrays "
                                   "where the output format can hold them");
    auto in = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    cmd->add_option("IN", *in, "Input mesh (.obj .off .ply .stl .vtp .vtk)")->required();
    cmd->add_option("OUT", *out, "Output mesh; the format follows the extension")->required();
    cmd->callback([=] {
      MeshData d = read_mesh(*in);
      for (const auto& w : d.warnings) fmt::print(stderr, "warning: {}\n", w);
      Mesh(d.V, d.F);  // validates indices and coordinates before anything is written
      for (const auto& w : write_mesh(*out, d)) fmt::print(stderr, "warning: {}\n", w);
      fmt::print("{}: {} vertices, {} triangles, {} vertex fields\n", *out, d.V.rows(), d.F.rows(),
                 d.vertex_scalars.size() + d.point_arrays.size());
    });
  }
#ifdef MESHPDE_HAVE_MEDICAL
  {
    auto* cmd =
        app.add_subcommand("sample",
                           "Sample a volume (CT/MR image, level set) at the mesh vertices: checks that mesh and "
                           "image are registered, and writes the values as a vertex field");
    struct Args {
      std::string mesh, image, series, space, field = "image", out;
      double sigma = -1;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("MESH", a->mesh, "Mesh file (.obj .off .ply .stl .vtp .vtk)")->required();
    cmd->add_option("--image", a->image,
                    "Volume (.mha .mhd .nii .nii.gz .nrrd .nhdr) or DICOM series (a folder, or one file of it)")
        ->required();
    cmd->add_option("--series", a->series, "DICOM folder of several series: the one to read (UID or series number)");
    cmd->add_option("--space", a->space,
                    "Frame of the mesh coordinates: lps | ras (default: the file's SPACE= header, "
                    "else lps)");
    cmd->add_option("--edges", a->sigma, "Sample the edge strength |grad(G_sigma * I)| at this sigma (mm) instead");
    cmd->add_option("--field", a->field, "Name of the written field")->capture_default_str();
    cmd->add_option("-o,--output", a->out, "Mesh with the sampled field (NaN where a vertex is outside the image)");
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] {
      MeshData d;
      const Mesh mesh = load_mesh(a->mesh, &d);
      const Space space = mesh_space(a->space, d);
      VolumeReadOptions options;
      options.series = a->series;
      Volume v = read_volume(a->image, options);
      if (a->sigma >= 0) v = gradient_magnitude(v, a->sigma);
      Eigen::VectorXd values(mesh.num_vertices());
      int outside = 0;
      double lo = std::numeric_limits<double>::infinity(), hi = -lo, mean_abs = 0;
      for (int i = 0; i < mesh.num_vertices(); ++i) {
        const auto s = v.sample(mesh.positions().row(i).transpose(), space);
        values[i] = s ? *s : std::numeric_limits<double>::quiet_NaN();
        if (!s) {
          ++outside;
          continue;
        }
        lo = std::min(lo, *s);
        hi = std::max(hi, *s);
        mean_abs += std::abs(*s);
      }
      const int inside = mesh.num_vertices() - outside;
      if (inside) mean_abs /= inside;
      if (!a->out.empty()) {
        d.vertex_scalars[a->field] = values;
        for (const auto& w : write_mesh(a->out, d)) fmt::print(stderr, "warning: {}\n", w);
      }
      nlohmann::json j = {{"vertices", mesh.num_vertices()}, {"outside", outside},       {"space", to_string(space)},
                          {"min", inside ? lo : 0.0},        {"max", inside ? hi : 0.0}, {"mean_abs", mean_abs}};
      if (a->json) {
        print_json(j);
      } else {
        fmt::print("{} vertices sampled in {} ({}): {} outside the image\n", mesh.num_vertices(), a->image,
                   to_string(space), outside);
        if (inside) fmt::print("values {:.4g} .. {:.4g}, mean |value| {:.4g}\n", lo, hi, mean_abs);
      }
      if (outside == mesh.num_vertices())
        throw InputError(fmt::format("every vertex lies outside {}: wrong --space (lps/ras)?", a->image));
    });
  }
#endif
  {
    auto* cmd = app.add_subcommand("generate", "Generate a test mesh");
    auto a = std::make_shared<GenerateArgs>();
    cmd->add_option("KIND", a->kind, "latlong | icosphere | geodesic | tube | bifurcation | plane | fins")
        ->required()
        ->check(CLI::IsMember(generator_names()));
    cmd->add_option("-o,--output", a->out, "Output mesh file")->required();
    cmd->add_option("--n", a->p.n,
                    "latlong: rings of latitude n (n-1 rings plus 2 poles, 2n meridians); fins: quads per side")
        ->capture_default_str();
    cmd->add_option("--level", a->p.level, "icosphere: subdivision level (5: 10,242 vertices, 8: 655,362)")
        ->capture_default_str();
    cmd->add_option("--base", a->base, "geodesic: icosahedron | tetrahedron")
        ->check(CLI::IsMember({"icosahedron", "tetrahedron"}))
        ->capture_default_str();
    cmd->add_option("--frequency", a->p.frequency, "geodesic: each base edge split into this many")
        ->capture_default_str();
    cmd->add_option("--radius", a->p.radius, "sphere or tube radius")->capture_default_str();
    cmd->add_option("--length", a->p.length, "tube length")->capture_default_str();
    cmd->add_option("--rings", a->p.rings, "tube: rings along the axis")->capture_default_str();
    cmd->add_option("--segments", a->p.segments, "tube: vertices per ring")->capture_default_str();
    cmd->add_option("--nx", a->p.nx, "plane: quads along x")->capture_default_str();
    cmd->add_option("--ny", a->p.ny, "plane: quads along y")->capture_default_str();
    cmd->add_option("--size", a->p.size, "plane: side length")->capture_default_str();
    cmd->add_option("--k", a->p.k, "fins: number of sheets sharing the axis edge")->capture_default_str();
    cmd->add_option("--cell", a->p.bifurcation.cell, "bifurcation: grid spacing in mm (about the edge length)")
        ->capture_default_str();
    cmd->add_flag("--dent", a->p.bifurcation.dent, "bifurcation: push a dent into the trunk wall");
    cmd->add_flag("--caps", a->p.caps,
                  "tube, bifurcation: flat caps on the open ends, labelled in the cell array CellEntityIds (wall 1, "
                  "caps 2, 3, ...; kept by .vtp and .vtk)");
    cmd->callback([=] {
      GeneratorParams p = a->p;
      p.base = a->base == "tetrahedron" ? BaseSolid::Tetrahedron : BaseSolid::Icosahedron;
      const GeneratedMesh g = generate(a->kind, p);
      MeshData d;
      d.V = g.V;
      d.F = g.F;
      if (g.face_labels.size() > 0) d.cell_arrays["CellEntityIds"] = DataArray{g.face_labels.cast<double>(), "Int32"};
      for (const auto& w : write_mesh(a->out, d)) fmt::print(stderr, "warning: {}\n", w);
      fmt::print("wrote {}: {} vertices, {} triangles\n", a->out, g.V.rows(), g.F.rows());
    });
  }
  {
    auto* cmd = app.add_subcommand("curvature",
                                   "Per-vertex mean curvature H = 1/2 c |row(K x)| (Kim and Rossignac 2004, Table 1)");
    auto path = std::make_shared<std::string>();
    auto scale = std::make_shared<std::string>("area");
    auto out = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    auto laplacian = std::make_shared<std::string>("auto");
    cmd->add_option("MESH", *path, "Mesh file")->required();
    add_laplacian_option(cmd, *laplacian);
    cmd->add_option("--scale", *scale, "area: c = 3/A (Meyer et al.); valence: c = 4 cos^2(pi/n)/A")
        ->check(CLI::IsMember({"area", "valence"}))
        ->capture_default_str();
    cmd->add_option("-o,--output", *out, "Write the mesh with a 'mean_curvature' vertex property (.ply)");
    cmd->add_flag("--json", *json, "Print JSON: mean_curvature array and summary statistics");
    cmd->callback([=] {
      if (!out->empty() && format_from_path(*out) != MeshFormat::Ply)
        throw InputError(fmt::format("{}: vertex properties need a .ply output", *out));
      const Mesh mesh = load_mesh(*path);
      warn_about_shape(mesh, *path);
      const CurvatureResult c = mean_curvature(
          mesh, *scale == "valence" ? CurvatureScale::Valence : CurvatureScale::Area, parse_laplacian_kind(*laplacian));
      const Eigen::VectorXd& H = c.H;
      const double mean = H.mean();
      const double sd = std::sqrt((H.array() - mean).square().mean());
      Eigen::VectorXd rho = H.cwiseInverse();
      if (*json) {
        print_json({{"scale", *scale},
                    {"laplacian", to_string(c.laplacian)},
                    {"laplacian_reason", c.reason},
                    {"mean_curvature", std::vector<double>(H.data(), H.data() + H.size())},
                    {"mean", mean},
                    {"std", sd},
                    {"min", H.minCoeff()},
                    {"max", H.maxCoeff()},
                    {"mean_radius", rho.mean()},
                    {"radius_range", rho.maxCoeff() - rho.minCoeff()}});
      } else {
        fmt::print(
            "mean curvature ({} scaling, {} Laplacian) over {} vertices: mean {:.6g}, std {:.3g}, range [{:.6g}, "
            "{:.6g}]\n",
            *scale, to_string(c.laplacian), H.size(), mean, sd, H.minCoeff(), H.maxCoeff());
        fmt::print("radius 1/H: mean {:.6g}, max - min {:.3g}\n", rho.mean(), rho.maxCoeff() - rho.minCoeff());
      }
      if (!out->empty()) save_mesh(*out, mesh.positions(), mesh.triangles(), {{"mean_curvature", H}});
    });
  }
}

}  // namespace meshpde::cli
