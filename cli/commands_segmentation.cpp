// meshpde extract | voxelize: a segment of a segmentation to its closed surface and back.
#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "meshpde/apps/segment_surface.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/io/segmentation_io.h"
#include "meshpde/mesh/units.h"

namespace meshpde::cli {

namespace {

nlohmann::json segment_json(const Segment& s) {
  return {{"name", s.name},   {"id", s.id},       {"label", s.label},
          {"layer", s.layer}, {"index", s.index}, {"color", {s.color.x(), s.color.y(), s.color.z()}}};
}

struct ExtractArgs {
  std::string input, segment, out, space = "lps", units = "mm";
  double smoothing = kDefaultSegmentSmoothing;
  bool json = false;
};

void run_extract(const ExtractArgs& a) {
  const Segmentation seg = read_segmentation(a.input);
  const Segment& s = find_segment(seg, a.segment);
  MeshData surface = extract_surface(seg, s, a.smoothing);
  // Written in the frame and unit asked for (LPS millimetres by default).
  const Space space = parse_space(a.space);
  const LengthUnit unit = parse_length_unit(a.units);
  if (space == Space::RAS) {
    surface.V.col(0) *= -1;
    surface.V.col(1) *= -1;
    surface.space = "RAS";
    surface.F.col(1).swap(surface.F.col(2));  // a reflection: keep the triangles facing out
  }
  surface.V /= millimetres_per(unit);
  std::size_t voxels = 0;
  for (std::size_t v = 0; v < seg.num_voxels(); ++v) voxels += seg.at(v, s.layer) == s.label;
  for (const auto& w : write_mesh(a.out, surface)) fmt::print(stderr, "warning: {}\n", w);
  const Mesh mesh(surface.V, surface.F);
  const MeshReport r = analyze(mesh);
  const double mm3 = std::pow(millimetres_per(unit), 3);
  if (a.json) {
    print_json({{"segment", segment_json(s)},
                {"voxels", voxels},
                {"voxel_volume_mm3", static_cast<double>(voxels) * seg.geometry.spacing.prod()},
                {"vertices", mesh.num_vertices()},
                {"faces", mesh.num_faces()},
                {"closed", r.boundary_edges == 0},
                {"surface_volume_mm3", std::abs(r.signed_volume) * mm3},
                {"smoothing", a.smoothing},
                {"space", to_string(space)},
                {"units", to_string(unit)},
                {"output", a.out}});
    return;
  }
  fmt::print("segment '{}' (label {}, layer {}): {} voxels, {:.6g} mm3\n", s.name, s.label, s.layer, voxels,
             static_cast<double>(voxels) * seg.geometry.spacing.prod());
  fmt::print("surface: {} vertices, {} triangles, {}, {:.6g} mm3 inside (smoothing {})\n", mesh.num_vertices(),
             mesh.num_faces(), r.boundary_edges == 0 ? "closed" : "open", std::abs(r.signed_volume) * mm3, a.smoothing);
  fmt::print("wrote {} ({} {})\n", a.out, to_string(space), to_string(unit));
}

struct VoxelizeArgs {
  std::string surface, reference, series, segment, out, space, units = "mm";
  int oversampling = 1;
  bool full = false, json = false;
};

void run_voxelize(const VoxelizeArgs& a) {
  MeshData surface;
  load_mesh(a.surface, &surface);
  VolumeReadOptions options;
  options.series = a.series;
  bool is_image = false;
  Segmentation seg = voxelize_reference(a.reference, options, &is_image);
  const Segment s = segment_for_surface(seg, a.segment, surface);
  const Space space = mesh_space(a.space, surface);
  const LengthUnit unit = parse_length_unit(a.units);
  const SurfaceInLps lps = surface_in_lps(surface, space, unit);
  const VoxelizeReport r =
      voxelize_into(seg, s, lps.V, surface.F, lps.displacement, {.oversampling = a.oversampling, .full = a.full});
  if (r.vertices_outside_grid > 0)
    fmt::print(stderr, "warning: {}: {} vertices lie outside the grid of {}; the voxels there are not written\n",
               a.surface, r.vertices_outside_grid, a.reference);
  if (r.change.conflicts > 0)
    fmt::print(stderr, "warning: {} voxels inside the surface hold another segment of layer {} and were left to it\n",
               r.change.conflicts, s.layer);
  write_segmentation(a.out, seg);
  std::size_t voxels = 0;
  for (std::size_t v = 0; v < seg.num_voxels(); ++v) voxels += seg.at(v, s.layer) == s.label;
  if (a.json) {
    print_json({{"segment", segment_json(s)},
                {"partial", r.partial},
                {"moved_vertices", r.moved_vertices},
                {"added", r.change.added},
                {"removed", r.change.removed},
                {"conflicts", r.change.conflicts},
                {"decided_voxels", r.decided_voxels},
                {"voxels", voxels},
                {"box", {r.box.lo[0], r.box.hi[0], r.box.lo[1], r.box.hi[1], r.box.lo[2], r.box.hi[2]}},
                {"vertices_outside_grid", r.vertices_outside_grid},
                {"reference", a.reference},
                {"reference_format", is_image ? "image" : to_string(seg.format)},
                {"oversampling", a.oversampling},
                {"space", to_string(space)},
                {"units", to_string(unit)},
                {"output", a.out}});
    return;
  }
  fmt::print("segment '{}' (label {}, layer {}): {} voxels added, {} removed{} ({})\n", s.name, s.label, s.layer,
             r.change.added, r.change.removed,
             r.change.conflicts ? fmt::format(", {} left to other segments", r.change.conflicts) : "",
             r.partial ? fmt::format("only where {} moved vertices swept", r.moved_vertices)
                       : "every voxel decided from the surface");
  fmt::print("wrote {}\n", a.out);
}

}  // namespace

void add_segmentation_commands(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand(
        "extract",
        "The closed surface of one segment of a segmentation (3D Slicer .seg.nrrd, or a label map), as Slicer's "
        "closed-surface conversion makes it");
    auto a = std::make_shared<ExtractArgs>();
    cmd->add_option("SEGMENTATION", a->input, "Segmentation: .seg.nrrd, or a label map .nii .nii.gz .nrrd .nhdr .mha")
        ->required();
    cmd->add_option("--segment", a->segment,
                    "The segment: its name, ID or label value (needed when the file holds several)");
    cmd->add_option("-o,--output", a->out, "Surface file (.vtp keeps the segment's name, label and colour)")
        ->required();
    cmd->add_option("--smoothing", a->smoothing,
                    "Windowed-sinc smoothing factor, 0 (none) to 1 (strong), as 3D Slicer's (Slicer's default is 0.5)")
        ->capture_default_str();
    cmd->add_option("--space", a->space, "Frame of the output coordinates: lps | ras")
        ->check(CLI::IsMember({"lps", "ras"}))
        ->capture_default_str();
    cmd->add_option("--units", a->units, "Unit of the output coordinates: mm | cm | m")
        ->check(CLI::IsMember({"mm", "cm", "m"}))
        ->capture_default_str();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] { run_extract(*a); });
  }
  {
    auto* cmd = app.add_subcommand(
        "voxelize",
        "A closed surface back into a label map on the exact grid of a reference segmentation or image; a surface "
        "that carries its displacement (meshpde correct's output) changes only the voxels it swept");
    auto a = std::make_shared<VoxelizeArgs>();
    cmd->add_option("SURFACE", a->surface, "Closed surface (.vtp .vtk .ply .obj .off .stl)")->required();
    cmd->add_option("--reference", a->reference,
                    "Segmentation (.seg.nrrd or label map: its other segments are kept) or image (.mha .nii .nrrd, "
                    "DICOM: a new label map on its grid)")
        ->required();
    cmd->add_option("--series", a->series, "DICOM folder of several series: the one to take the grid of");
    cmd->add_option("--segment", a->segment,
                    "The segment to replace: name, ID or label value (default: the surface's Segment_Name or "
                    "Segment_LabelValue, else the only segment; a new label value adds a segment)");
    cmd->add_option("--oversampling", a->oversampling,
                    "Sub-samples along each axis of a voxel, 1..8 (inside when more than half are)")
        ->capture_default_str();
    cmd->add_flag("--full", a->full,
                  "Decide every voxel of the segment from the surface, even when it carries its "
                  "displacement");
    cmd->add_option("--space", a->space,
                    "Frame of the surface coordinates: lps | ras (default: the file's SPACE tag, else lps)");
    cmd->add_option("--units", a->units, "Unit of the surface coordinates: mm | cm | m")
        ->check(CLI::IsMember({"mm", "cm", "m"}))
        ->capture_default_str();
    cmd->add_option("-o,--output", a->out, "Output (.seg.nrrd .nrrd .nii .nii.gz .mha)")->required();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] { run_voxelize(*a); });
  }
}

}  // namespace meshpde::cli
