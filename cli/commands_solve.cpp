// meshpde correct | demo
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <memory>
#include <optional>
#include <sstream>

#include "commands.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/selection.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/image/volume.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/medical_io.h"
#endif
#include "meshpde/core/errors.h"
#include "meshpde/core/warnings.h"
#include "meshpde/mesh/caps.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "meshpde/operators/fem_operators.h"

namespace meshpde::cli {

namespace {

struct DragReport {
  DragResult result;
  double setup_ms = 0, solve_ms = 0;
  LaplacianKind laplacian = LaplacianKind::Cotan;
};

// The drag on the operators of `kind` (intrinsic: on its operator mesh, whose vertices
// and positions are the input's, so the result applies to the input triangles).
DragReport run_drag(const Mesh& mesh, const DragParams& p, LaplacianKind kind) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const MeshOperators mo = build_mesh_operators(mesh, kind);
  const auto t1 = clock::now();
  DragReport r{drag_vertex(mo.mesh, mo.ops, p)};
  r.laplacian = mo.kind;
  const auto t2 = clock::now();
  r.setup_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  r.solve_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  return r;
}

nlohmann::json drag_json(const DragReport& r) {
  return {{"moved_vertices", r.result.moved_vertices},
          {"max_displacement", r.result.max_displacement},
          {"region_vertices", r.result.region.size()},
          {"time_ms", r.setup_ms + r.solve_ms},
          {"operator_setup_ms", r.setup_ms},
          {"solve_ms", r.solve_ms},
          {"cg_iterations", r.result.cg.iterations},
          {"relative_residual", r.result.cg.relative_residual},
          {"converged", r.result.cg.converged()},
          {"handle_force", {r.result.reaction.x(), r.result.reaction.y(), r.result.reaction.z()}},
          {"laplacian", to_string(r.laplacian)}};
}

void print_drag(const DragReport& r, const std::string& out) {
  fmt::print("moved {} vertices (region of {} free vertices), largest displacement {:.4g}\n", r.result.moved_vertices,
             r.result.region.size(), r.result.max_displacement);
  const std::string how = r.result.cg.iterations > 0 ? fmt::format("{} CG iterations", r.result.cg.iterations)
                                                     : std::string("direct solve");
  fmt::print("time {:.1f} ms (operators {:.1f} ms, solve {:.1f} ms, {}, relative residual {:.2g})\n",
             r.setup_ms + r.solve_ms, r.setup_ms, r.solve_ms, how, r.result.cg.relative_residual);
  fmt::print("wrote {}\n", out);
}

std::map<std::string, Eigen::VectorXd> displacement_fields(const DragResult& r) {
  return {{"displacement", r.displacement.rowwise().norm()}};
}

// The library's defaults (CorrectionParams), which the options start from and show.
const CorrectionParams& correction_defaults() {
  static const CorrectionParams d;
  return d;
}

std::string number_text(double x) {
  return fmt::format("{:g}", x);
}

struct CorrectArgs {
  std::string mesh, out, method = to_string(correction_defaults().method),
                         boundary = to_string(correction_defaults().boundary),
                         laplacian = to_string(correction_defaults().laplacian), stiffness, image, series, space,
                         solver = to_string(correction_defaults().solver), units = "mm", caps = "labels";
  std::vector<std::string> vertices, points, moves, brushes;
  double handle_radius = correction_defaults().handle_radius;
  int rings = 0, steps = correction_defaults().steps, cube = correction_defaults().image.cube_size,
      passes = correction_defaults().image.passes;
  double radius = 0, g1 = correction_defaults().g1, g2 = correction_defaults().g2,
         tol = correction_defaults().cg.tolerance, image_weight = correction_defaults().image.weight,
         image_sigma = kEdgeSigmaMm, search = correction_defaults().image.search_radius;
  // A number or a vertex field's name.
  std::string mass = number_text(correction_defaults().tissue.mass),
              elasticity = number_text(correction_defaults().tissue.elasticity),
              viscosity = number_text(correction_defaults().tissue.viscosity);
  bool json = false, dynamic = false, allow_intersections = false;
};

// A vertex field of the mesh named by an option, or an error listing the fields.
const Eigen::VectorXd& vertex_field(const MeshData& d, const std::string& mesh, const std::string& option,
                                    const std::string& name) {
  const auto it = d.vertex_scalars.find(name);
  if (it != d.vertex_scalars.end()) return it->second;
  std::string names;
  for (const auto& [k, v] : d.vertex_scalars) names += (names.empty() ? "" : ", ") + k;
  throw InputError(
      fmt::format("{}: no vertex field '{}' for {} (fields: {})", mesh, name, option, names.empty() ? "none" : names));
}

// --mass, --elasticity, --viscosity: a number for the whole region, else the name of a
// vertex field of the mesh.
void tissue_option(const MeshData& d, const std::string& mesh, const std::string& option, const std::string& text,
                   double& scalar, Eigen::VectorXd& field) {
  double x = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), x);
  if (ec == std::errc() && end == text.data() + text.size()) {
    scalar = x;
    return;
  }
  field = vertex_field(d, mesh, option, text);
}

// The per-vertex tissue: --stiffness and the tissue options, then the brushes in their
// order. A brush is [PROPERTY:]V:RADIUS:VALUE (PROPERTY stiffness by default); its radius
// is in millimetres like every length the user gives, so `mm_per_unit` converts it to
// the mesh's units (its @X,Y,Z is a point of the mesh, in its units).
void tissue_fields(const Mesh& mesh, const MeshData& d, const CorrectArgs& a, double mm_per_unit, CorrectionParams& p) {
  if (!a.stiffness.empty()) p.stiffness = vertex_field(d, a.mesh, "--stiffness", a.stiffness);
  tissue_option(d, a.mesh, "--mass", a.mass, p.tissue.mass, p.tissue.mass_field);
  tissue_option(d, a.mesh, "--elasticity", a.elasticity, p.tissue.elasticity, p.tissue.elasticity_field);
  tissue_option(d, a.mesh, "--viscosity", a.viscosity, p.tissue.viscosity, p.tissue.viscosity_field);
  for (const auto& b : a.brushes) paint_tissue(mesh, p, b, mm_per_unit);
}

void run_correct(const CorrectArgs& a) {
  if (a.radius <= 0 && a.rings <= 0) throw InputError("give --radius MM or --rings K");
  if (a.vertices.size() + a.points.size() != a.moves.size())
    throw InputError(fmt::format("{} --vertex and {} --point but {} --move: give one displacement per handle",
                                 a.vertices.size(), a.points.size(), a.moves.size()));
  if (a.vertices.empty() && a.points.empty()) throw InputError("give a handle: --vertex V or --point X,Y,Z");
  MeshData data;
  const Mesh mesh = load_mesh(a.mesh, &data);
  warn_about_shape(mesh, a.mesh);
  CorrectionParams p;
  p.units = parse_length_unit(a.units);
  if (const std::string w = units_warning(mesh, p.units, a.mesh, "--units "); !w.empty())
    fmt::print(stderr, "warning: {}\n", w);
  std::vector<int> handle_vertices;
  {
    // A far @X,Y,Z is warned about by the correction itself (handle_warning, against
    // the region's reach), not twice.
    const WarningCollector handled;
    for (const auto& spec : a.vertices) handle_vertices.push_back(parse_vertex(mesh, spec, "--vertex"));
  }
  // Moves pair with the --vertex handles first, then the --point handles.
  const std::vector<std::string> vertex_moves(a.moves.begin(), a.moves.begin() + static_cast<long>(a.vertices.size())),
      point_moves(a.moves.begin() + static_cast<long>(a.vertices.size()), a.moves.end());
  std::vector<Eigen::Vector3d> points;
  for (const auto& spec : a.points) {
    try {
      points.push_back(parse_point_spec(spec));
    } catch (const InputError& e) {
      throw InputError(fmt::format("--point: {}", e.what()));
    }
  }
  try {
    p.handles = parse_handles(mesh, handle_vertices, vertex_moves);
    for (std::size_t k = 0; k < a.vertices.size(); ++k)  // @X,Y,Z: the nearest vertex, warned about when far
      if (a.vertices[k].starts_with('@')) p.handles[k].given = parse_point_spec(a.vertices[k].substr(1));
    for (auto& h : parse_point_handles(mesh, points, point_moves)) p.handles.push_back(std::move(h));
  } catch (const InputError& e) {
    throw InputError(fmt::format("--move: {}", e.what()));
  }
  p.handle_radius = a.handle_radius;
  p.radius = a.radius;
  p.rings = a.rings;
  p.method = parse_correction_method(a.method);
  p.boundary = parse_region_boundary(a.boundary);
  p.g1 = a.g1;
  p.g2 = a.g2;
  p.laplacian = parse_laplacian_kind(a.laplacian);
  tissue_fields(mesh, data, a, millimetres_per(p.units), p);
  p.dynamic = a.dynamic;
  p.steps = a.steps;
  p.prevent_intersections = !a.allow_intersections;
  std::string label_array;
  const std::vector<Cap> caps = find_caps(mesh, face_labels(data, &label_array), parse_cap_rule(a.caps));
  p.held = cap_vertices(caps);
  const Space space = mesh_space(a.space, data);
  if (!a.image.empty()) {
#ifdef MESHPDE_HAVE_MEDICAL
    VolumeReadOptions options;
    options.series = a.series;
    const Volume volume = read_volume(a.image, options);
    p.image.edges = edge_map(volume, a.image_sigma);
#else
    throw InputError("--image needs meshpde built with meshpde::medical (VTK)");
#endif
    p.image.space = space;
    p.image.weight = a.image_weight;
    p.image.search_radius = a.search;
    p.image.cube_size = a.cube;
    p.image.passes = a.passes;
  }

  p.solver = parse_steady_solver(a.solver);
  check_tolerance(a.tol, "--tolerance");
  p.cg.tolerance = a.tol;
  nlohmann::json j;
  Positions V;
  Field disp;
  {
    const CorrectionResult r = correct_vessel(mesh, p);
    if (!r.converged) throw SolverError(fmt::format("the correction's solve did not converge: {}", r.solver_message));
    V = r.V;
    disp = r.displacement;
    if (!r.accuracy_warning.empty()) fmt::print(stderr, "warning: {}\n", r.accuracy_warning);
    if (!r.region_warning.empty()) fmt::print(stderr, "warning: {}: {}\n", a.mesh, r.region_warning);
    if (!r.handle_warning.empty()) fmt::print(stderr, "warning: {}: {}\n", a.mesh, r.handle_warning);
    if (r.image_outside_vertices > 0)
      fmt::print(stderr,
                 "note: {}: {} of the region's vertices lie outside the image; they follow the drag unguided "
                 "(image.outside_vertices)\n",
                 a.mesh, r.image_outside_vertices);
    if (r.applied_fraction < 1)
      fmt::print(stderr,
                 "warning: {}: only {:.3f} of the displacement was applied: the whole of it would make the surface "
                 "intersect itself ({}; --allow-intersections applies it all)\n",
                 a.mesh, r.applied_fraction, r.intersection_action);
    j = nlohmann::json::parse(
        correction_report_json(mesh.positions(), mesh.triangles(), p, r, CorrectionCaps{a.caps, label_array, caps}));
  }
  // Keep everything the input carried; add the displacement (vector and length). A
  // frame given with --space is written too (SPACE= in .vtk, SPACE field data in .vtp).
  data.V = V;
  if (!a.space.empty()) data.space = space == Space::RAS ? "RAS" : "LPS";
  for (const auto& name : refresh_normal_fields(data))
    fmt::print(stderr, "note: {}: point normals '{}' recomputed on the corrected surface\n", a.mesh, name);
  const char* comp[3] = {"displacement_x", "displacement_y", "displacement_z"};
  for (int c = 0; c < 3; ++c) data.vertex_scalars[comp[c]] = disp.col(c);
  data.vertex_scalars["displacement_magnitude"] = disp.rowwise().norm();
  for (const auto& w : write_mesh(a.out, data)) fmt::print(stderr, "warning: {}\n", w);
  if (a.json) {
    print_json(j);
    return;
  }
  fmt::print("moved {} vertices (region of {} vertices), largest displacement {:.4g} mm, {} new self-intersections\n",
             j["moved_vertices"].get<int>(), j["region_vertices"].get<std::size_t>(),
             j["max_displacement"].get<double>(), j["new_self_intersections"].get<int>());
  if (j.contains("intersection_action") && j["intersection_action"] != "none")
    fmt::print("to avoid self-intersections: {}\n", j["intersection_action"].get<std::string>());
  fmt::print("time {:.1f} ms, relative residual {:.2g}\n", j["time_ms"].get<double>(),
             j["relative_residual"].get<double>());
  fmt::print("wrote {}\n", a.out);
}

}  // namespace

void add_solve_commands(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand(
        "correct",
        "Vessel-wall correction: move handle vertices by displacements (mm); the wall around them follows like tissue "
        "(bi-Laplacian on the region of influence), never folding through itself");
    auto a = std::make_shared<CorrectArgs>();
    cmd->add_option("MESH", a->mesh, "Mesh file (.obj .off .ply .stl .vtp .vtk)")->required();
    cmd->add_option("--vertex", a->vertices,
                    "Handle vertex: index (0-based) or @X,Y,Z (nearest; in the mesh's units); repeat for several");
    cmd->add_option("--point", a->points,
                    "Handle at the surface point nearest to X,Y,Z (in the mesh's units): that point moves, not a "
                    "vertex; repeatable, mixable with --vertex (moves pair with the --vertex handles first)");
    cmd->add_option("--handle-radius", a->handle_radius,
                    "Handle size in mm: the surface within it carries the drag's force as a smooth bump; 0: a single "
                    "point. Default: a quarter of --radius with the smooth boundary, 0 with clamp and fade");
    cmd->add_option("--units", a->units,
                    "Unit of the mesh's coordinates: mm | cm | m. Lengths on the command line stay in mm; the output "
                    "is written in the mesh's unit")
        ->check(CLI::IsMember({"mm", "cm", "m"}))
        ->capture_default_str();
    cmd->add_option("--move", a->moves,
                    "Displacement DX,DY,DZ in mm, or normal:D (D mm along the outward normal), one per --vertex and "
                    "--point")
        ->required();
    auto* radius = cmd->add_option("--radius", a->radius, "Region of influence: distance in mm from a handle");
    auto* rings =
        cmd->add_option("--rings", a->rings, "Region of influence in rings (the thesis's level of influence)");
    radius->excludes(rings);
    cmd->add_option("--method", a->method, "fem (bi-Laplacian, ours) | springs (the thesis's mass-spring baseline)")
        ->check(CLI::IsMember({"fem", "springs"}))
        ->capture_default_str();
    cmd->add_option("--boundary", a->boundary,
                    "How a fem region ends: smooth (the surface within R, measured on the surface; the displacement "
                    "and its slope fall to zero at R, the same on any triangulation) | clamp (held beyond R - h by "
                    "edge paths: the rule before smooth) | fade (an elastic foundation from 0.6 R, free to 2 R)")
        ->check(CLI::IsMember({"smooth", "clamp", "fade"}))
        ->capture_default_str();
    cmd->add_flag("--dynamic", a->dynamic,
                  "Settle like tissue (mass, viscosity, elasticity) instead of a static solve (springs: the thesis's "
                  "dynamic version)");
    cmd->add_option("--steps", a->steps, "Time steps of --dynamic")->capture_default_str();
    cmd->add_option("--mass", a->mass,
                    "Tissue mass in [0, 1] (thesis default 0.1), or the name of a vertex field of MESH (per vertex)")
        ->capture_default_str();
    cmd->add_option("--elasticity", a->elasticity, "Tissue elasticity in [0, 1], or a vertex field's name")
        ->capture_default_str();
    cmd->add_option("--viscosity", a->viscosity,
                    "Tissue viscosity in [0, 1] (1: critical damping), or a vertex field's name")
        ->capture_default_str();
    cmd->add_option("--stiffness", a->stiffness, "Per-vertex stiffness multiplier: name of a vertex field in MESH");
    cmd->add_option("--brush", a->brushes,
                    "Brush [PROPERTY:]V:RADIUS:VALUE painting stiffness (default), mass, elasticity or viscosity "
                    "(vertex index or @X,Y,Z; radius in mm; tissue values in [0, 1]), applied after the options; "
                    "repeatable");
    cmd->add_option("--g1", a->g1, "Membrane (Laplacian) stiffness")->capture_default_str();
    cmd->add_option("--g2", a->g2, "Plate (bi-Laplacian) stiffness")->capture_default_str();
    add_laplacian_option(cmd, a->laplacian);
    cmd->add_option("--caps", a->caps,
                    "Flat caps on the open ends stay put: labels (the flat patches of the face labels ModelFaceID, "
                    "CellEntityIds or MaterialIds) | auto (labels, else flat patches with a sharp rim found by shape) "
                    "| off")
        ->check(CLI::IsMember({"labels", "auto", "off"}))
        ->capture_default_str();
    cmd->add_flag("--allow-intersections", a->allow_intersections,
                  "Do not split or limit a correction that would make the surface intersect itself");
    cmd->add_option("--image", a->image,
                    "Volume (.mha .mhd .nii .nii.gz .nrrd .nhdr) or DICOM series (a folder, or one file of it): pull "
                    "the wall onto image edges");
    cmd->add_option("--series", a->series, "DICOM folder of several series: the one to read (UID or series number)");
    cmd->add_option("--space", a->space,
                    "Frame of the mesh coordinates: lps | ras (default: the file's SPACE= header, else lps)");
    cmd->add_option("--image-weight", a->image_weight, "Strength of the pull towards edges")->capture_default_str();
    cmd->add_option("--image-sigma", a->image_sigma, "Gaussian scale (mm) of the edge map")->capture_default_str();
    cmd->add_option("--search-radius", a->search,
                    "Distance (mm) searched for an edge along each vertex normal, both ways")
        ->capture_default_str();
    cmd->add_option("--cube", a->cube,
                    "Thesis direction cube (odd, >= 3) instead of the search along the normal (needed by --method "
                    "springs --image: the thesis's image step)");
    cmd->add_option("--passes", a->passes, "Image fixed-point passes")->capture_default_str();
    cmd->add_option(
           "--solver", a->solver,
           fmt::format("auto (a static fem region of {} free vertices or more without angles under {} "
                       "degrees: the multigrid, kept where it converges; else direct) | direct | global "
                       "(multigrid-CG, for very large regions) | iterative (Jacobi-CG, for comparison); global "
                       "and iterative: static fem without --image",
                       kAutoGlobalFromFreeVertices, kAutoMultigridMinAngleDeg))
        ->check(CLI::IsMember({"auto", "direct", "global", "iterative"}))
        ->capture_default_str();
    cmd->add_option("--tolerance", a->tol, "CG relative residual tolerance (iterative)")->capture_default_str();
    cmd->add_option("-o,--output", a->out,
                    "Corrected mesh; its fields and data arrays are kept, a displacement field is added")
        ->required();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] { run_correct(*a); });
  }
  {
    auto* cmd = app.add_subcommand(
        "demo", "Main job: generate a dented Y bifurcation and drag the dented wall back out (bi-Laplacian, local)");
    struct Args {
      std::string outdir = "meshpde-demo", laplacian = "auto";
      double radius = 8.0;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    add_laplacian_option(cmd, a->laplacian);
    cmd->add_option("-o,--output-dir", a->outdir, "Where to write the input and corrected meshes")
        ->capture_default_str();
    cmd->add_option("--radius", a->radius, "Region of influence in mm")->capture_default_str();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] {
      const BifurcationParams bp{.dent = true};
      const GeneratedMesh g = y_bifurcation(bp);
      const Mesh mesh(g.V, g.F);
      const DentHandle dent = dent_handle(mesh.positions(), bp);
      const int handle = dent.vertex;
      const Eigen::Vector3d move = dent.move;
      std::filesystem::create_directories(a->outdir);
      const auto in_path = std::filesystem::path(a->outdir) / "bifurcation-dented.ply";
      const auto out_path = std::filesystem::path(a->outdir) / "bifurcation-corrected.ply";
      save_mesh(in_path, mesh.positions(), mesh.triangles());
      const MeshReport rep = analyze(mesh);
      const DragReport r = run_drag(mesh, DragParams{.vertex = handle, .displacement = move, .radius = a->radius},
                                    parse_laplacian_kind(a->laplacian));
      // A drag that stopped short is reported, not written as if it were the answer.
      if (!r.result.cg.converged())
        throw SolverError(fmt::format("the demo's drag did not converge ({}); {} not written", r.result.cg.message,
                                      out_path.string()));
      save_mesh(out_path, r.result.V, mesh.triangles(), displacement_fields(r.result));
      if (a->json) {
        auto j = drag_json(r);
        j["mesh_vertices"] = mesh.num_vertices();
        j["handle"] = handle;
        j["move"] = {move.x(), move.y(), move.z()};
        j["boundary"] = to_string(DragParams{}.boundary);
        j["input"] = in_path.string();
        j["output"] = out_path.string();
        print_json(j);
      } else {
        fmt::print("generated a dented Y bifurcation: {} vertices, {} triangles, smallest angle {:.1f} deg\n",
                   mesh.num_vertices(), mesh.num_faces(), rep.min_angle_deg);
        fmt::print("dragged wall vertex {} by ({:.3f}, {:.3f}, {:.3f}) mm, region radius {} mm ({} boundary)\n", handle,
                   move.x(), move.y(), move.z(), a->radius, to_string(DragParams{}.boundary));
        print_drag(r, out_path.string());
      }
    });
  }
}

}  // namespace meshpde::cli
