// meshpde heat | wave
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <thread>

#include "commands.h"
#include "meshpde/apps/fairing.h"
#include "meshpde/apps/haptics.h"
#include "meshpde/apps/heat_wave.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/viz/render.h"
#include "progress.h"

namespace meshpde::cli {

int parse_vertex(const Mesh& mesh, const std::string& spec, const char* what) {
  try {
    return parse_vertex_spec(mesh, spec);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", what, e.what()));
  }
}

std::pair<int, double> parse_vertex_value(const Mesh& mesh, const std::string& spec, const char* what) {
  const auto colon = spec.rfind(':');
  if (colon == std::string::npos) throw InputError(fmt::format("{} '{}' must be VERTEX:VALUE", what, spec));
  const int v = parse_vertex(mesh, spec.substr(0, colon), what);
  char* end = nullptr;
  const std::string value = spec.substr(colon + 1);
  const double x = std::strtod(value.c_str(), &end);
  if (value.empty() || *end != '\0' || !std::isfinite(x))
    throw InputError(fmt::format("{} '{}': '{}' is not a number", what, spec, value));
  return {v, x};
}

void add_laplacian_option(CLI::App* cmd, std::string& value, const std::string& note) {
  value = "auto";
  cmd->add_option("--laplacian", value,
                  "auto (intrinsic Delaunay on badly shaped or non-manifold meshes) | cotan | intrinsic" +
                      (note.empty() ? "" : "; " + note))
      ->check(CLI::IsMember({"auto", "cotan", "intrinsic"}))
      ->capture_default_str();
}

namespace {

void write_values_csv(const std::filesystem::path& path, const Eigen::VectorXd& u) {
  std::string s;
  s.reserve(static_cast<std::size_t>(24 * u.size()));
  for (Eigen::Index i = 0; i < u.size(); ++i) fmt::format_to(std::back_inserter(s), "{}\n", u[i]);
  write_file_atomically(path, s);
}

void add_propagation_command(CLI::App& app, Propagation eq) {
  const bool heat = eq == Propagation::Heat;
  auto* cmd = app.add_subcommand(heat ? "heat" : "wave",
                                 heat ? "Heat diffusion u_t = k lap(u) from fixed-value sources or fluxes"
                                      : "Wave propagation u_tt + b u_t = c^2 lap(u) from sources, fluxes or impulses");
  struct Args {
    std::string mesh, out, png, frames, initial, view = "30,20", up = "y", size = "960x720", laplacian = "auto";
    std::vector<std::string> sources, fluxes, impulses;
    double dt = 1e-3, k = 1, c = 1, b = 0;
    int steps = 100, every = 10;
    bool json = false, local = false;
    RenderOptions r;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Mesh file")->required();
  cmd->add_option("--source", a->sources, "Fixed-value source VERTEX:VALUE (VERTEX: index or @X,Y,Z); repeatable");
  cmd->add_option("--flux", a->fluxes, "Point flux VERTEX:RATE (value x area / s); repeatable");
  if (!heat) cmd->add_option("--impulse", a->impulses, "Initial velocity VERTEX:VELOCITY; repeatable");
  cmd->add_option("--initial", a->initial, "Initial values from this vertex property of a .ply input");
  cmd->add_option("--dt", a->dt, "Time step (s)")->capture_default_str();
  cmd->add_option("--steps", a->steps, "Number of steps")->capture_default_str();
  if (heat) cmd->add_option("--diffusivity", a->k, "Diffusivity k (length^2/s)")->capture_default_str();
  if (!heat) {
    cmd->add_option("--speed", a->c, "Wave speed c (length/s)")->capture_default_str();
    cmd->add_option("--damping", a->b, "Mass-proportional damping b (1/s)")->capture_default_str();
  }
  cmd->add_flag("--local", a->local, "Solve on a self-adjusting active domain instead of the whole mesh");
  add_laplacian_option(cmd, a->laplacian);
  cmd->add_option("--frames", a->frames, "Directory for frame_NNNNN.csv files (one value per vertex)");
  cmd->add_option("--every", a->every, "Write a frame every N steps")->capture_default_str();
  cmd->add_option("-o,--output", a->out, "Final mesh with the field 'u' (.ply)");
  cmd->add_option("--png", a->png, "Final picture");
  add_view_options(cmd, a->r, a->view, a->up, a->size);
  cmd->add_flag("--json", a->json, "Print a JSON report");
  cmd->callback([=] {
    if (!a->out.empty() && format_from_path(a->out) != MeshFormat::Ply)
      throw InputError(fmt::format("{}: the field needs a .ply output", a->out));
    MeshData d;
    const Mesh mesh = load_mesh(a->mesh, &d);
    // The intrinsic operators live on their own connectivity (same vertices): the
    // solve runs there, pictures and outputs on the input triangles.
    const MeshOperators mo = build_mesh_operators(mesh, parse_laplacian_kind(a->laplacian));
    const FemOperators& ops = mo.ops;
    PropagationParams p{.equation = heat ? Propagation::Heat : Propagation::Wave,
                        .dt = a->dt,
                        .steps = a->steps,
                        .diffusivity = a->k,
                        .wave_speed = a->c,
                        .damping = a->b,
                        .local = a->local};
    for (const auto& s : a->sources) p.fixed.push_back(parse_vertex_value(mesh, s, "--source"));
    for (const auto& s : a->fluxes) p.flux.push_back(parse_vertex_value(mesh, s, "--flux"));
    if (!a->initial.empty()) {
      const auto it = d.vertex_scalars.find(a->initial);
      if (it == d.vertex_scalars.end())
        throw InputError(fmt::format("{}: no vertex property '{}'", a->mesh, a->initial));
      p.initial = it->second;
    }
    if (!a->impulses.empty()) {
      p.initial_velocity = Eigen::VectorXd::Zero(mesh.num_vertices());
      for (const auto& s : a->impulses) {
        const auto [v, x] = parse_vertex_value(mesh, s, "--impulse");
        p.initial_velocity[v] += x;
      }
    }
    if (p.fixed.empty() && p.flux.empty() && p.initial.size() == 0 && p.initial_velocity.size() == 0)
      fmt::print(stderr, "warning: no source, flux, impulse or initial values: the field stays zero\n");
    if (!a->frames.empty()) std::filesystem::create_directories(a->frames);
    std::vector<double> energy;
    Progress progress(a->steps, heat ? "heat" : "wave", !a->json);
    const auto t0 = std::chrono::steady_clock::now();
    const PropagationResult r =
        propagate(mo.mesh, ops, p, [&](int k, const Eigen::VectorXd& u, const Eigen::VectorXd& ut) {
          if (!heat) energy.push_back(wave_energy(mo.mesh, ops, u, ut, a->c));
          if (!a->frames.empty() && (k % std::max(1, a->every) == 0 || k == a->steps))
            write_values_csv(std::filesystem::path(a->frames) / fmt::format("frame_{:05d}.csv", k), u);
          progress.update(k);
        });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!a->out.empty()) save_mesh(a->out, mesh.positions(), mesh.triangles(), {{"u", r.values}});
    if (!a->png.empty()) {
      RenderOptions ro = a->r;
      apply_view_options(ro, a->view, a->up, a->size);
      ro.field = r.values;
      ro.field_name = "u";
      ro.colormap = heat ? Colormap::Viridis : Colormap::Coolwarm;
      if (!heat) {
        const double m = std::max(1e-300, r.values.cwiseAbs().maxCoeff());
        ro.range = std::make_pair(-m, m);
      }
      ro.title = fmt::format("{} t = {:.4g} s", heat ? "heat" : "wave", a->dt * a->steps);
      write_png(a->png, render(mesh.positions(), mesh.triangles(), ro));
    }
    const double total = ops.mass.dot(r.values);
    if (a->json) {
      nlohmann::json j{{"steps", a->steps},
                       {"time", a->dt * a->steps},
                       {"seconds", seconds},
                       {"cg_iterations", r.cg_iterations},
                       {"max_free_vertices", r.max_free_vertices},
                       {"min", r.values.minCoeff()},
                       {"max", r.values.maxCoeff()},
                       {"mass_weighted_total", total},
                       {"laplacian", to_string(mo.kind)},
                       {"laplacian_reason", mo.reason}};
      if (!heat) j["energy"] = energy;
      print_json(j);
    } else {
      fmt::print("{} steps of {} s in {:.3f} s ({} CG iterations); u in [{:.6g}, {:.6g}], integral {:.6g}\n", a->steps,
                 a->dt, seconds, r.cg_iterations, r.values.minCoeff(), r.values.maxCoeff(), total);
      if (!energy.empty()) fmt::print("energy: start {:.6g}, end {:.6g}\n", energy.front(), energy.back());
    }
  });
}

nlohmann::json quality_json(const TriangleQuality& q) {
  nlohmann::json hist = nlohmann::json::array();
  const auto& e = TriangleQuality::bin_edges();
  for (std::size_t b = 0; b + 1 < e.size(); ++b)
    hist.push_back({{"from", e[b]},
                    {"to", std::isinf(e[b + 1]) ? nlohmann::json("inf") : nlohmann::json(e[b + 1])},
                    {"count", q.area_histogram[b]}});
  return {{"min_angle_deg", q.min_angle_deg}, {"area_ratio", q.area_ratio}, {"area_histogram", hist}};
}

void print_quality(const char* when, const TriangleQuality& q) {
  fmt::print("{}: smallest angle {:.3g} deg, area ratio {:.3g}; A / mean A histogram:", when, q.min_angle_deg,
             q.area_ratio);
  const auto& e = TriangleQuality::bin_edges();
  for (std::size_t b = 0; b + 1 < e.size(); ++b) fmt::print(" [{:g},{:g}) {}", e[b], e[b + 1], q.area_histogram[b]);
  fmt::print("\n");
}

void add_fair_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "fair", "Fair the free part of a mesh: membrane (--order 1) or thin plate (--order 2), selection held fixed");
  struct Args {
    std::string mesh, out, png, view = "30,20", up = "y", size = "960x720", solver = "auto", laplacian = "auto";
    std::vector<std::string> fixed;
    FairParams p;
    bool json = false;
    RenderOptions r;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Mesh file")->required();
  cmd->add_option("--fixed", a->fixed,
                  "Vertices held in place: file:PATH, rings:V:K, radius:V:R, halfspace:NX,NY,NZ:D, "
                  "field:NAME<X, field:NAME>X, boundary, all (V: index or @X,Y,Z); repeatable, united")
      ->required();
  cmd->add_option("--order", a->p.order, "1: Laplacian (membrane), 2: bi-Laplacian (thin plate)")
      ->check(CLI::IsMember({1, 2}))
      ->capture_default_str();
  cmd->add_flag("--regularize", a->p.regularize,
                "Re-assemble area-weighted stiffness every step (Kim and Rossignac 2004, Fig. 7)");
  cmd->add_option("--solver", a->solver,
                  fmt::format("Static solve: auto (--order 2: the multigrid on meshes of {} free vertices or more "
                              "without angles under {} degrees, kept where it converges; else direct) | "
                              "direct (sparse Cholesky) | global (multigrid or Laplacian-factor CG, large meshes, "
                              "--order 2) | iterative (Jacobi-CG)",
                              kAutoGlobalFromFreeVertices, kAutoMultigridMinAngleDeg))
      ->check(CLI::IsMember({"auto", "direct", "global", "iterative"}))
      ->capture_default_str();
  add_laplacian_option(cmd, a->laplacian, "--regularize always re-assembles area-weighted cotangent operators");
  cmd->add_option("--tolerance", a->p.cg.tolerance,
                  "CG relative residual tolerance (--solver iterative, and the --regularize steps)")
      ->capture_default_str();
  cmd->add_option("--dt", a->p.dt, "Regularization step (unit-free)")->capture_default_str();
  cmd->add_option("--steps", a->p.steps, "Regularization steps")->capture_default_str();
  cmd->add_option("--damping", a->p.damping, "Regularization damping relative to the mean area (0: quasi-static)")
      ->capture_default_str();
  cmd->add_option("-o,--output", a->out, "Faired mesh")->required();
  cmd->add_option("--png", a->png, "Picture of the result (free part coloured)");
  add_view_options(cmd, a->r, a->view, a->up, a->size);
  cmd->add_flag("--json", a->json, "Print a JSON report");
  cmd->callback([=] {
    MeshData d;
    const Mesh mesh = load_mesh(a->mesh, &d);
    const auto fixed = select_vertices(mesh, a->fixed, d.vertex_scalars);
    if (fixed.empty()) throw InputError("the --fixed selection is empty");
    if (static_cast<int>(fixed.size()) == mesh.num_vertices())
      throw InputError("every vertex is fixed: nothing to fair");
    const auto t0 = std::chrono::steady_clock::now();
    FairParams params = a->p;
    check_tolerance(params.cg.tolerance, "--tolerance");
    params.solver = parse_steady_solver(a->solver);
    params.laplacian = parse_laplacian_kind(a->laplacian);
    const FairResult r = fair(mesh, fixed, params);
    if (!r.converged) throw SolverError(fmt::format("fairing did not converge: {}", r.message));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    // Everything the input carried (point and cell arrays, face labels, the frame) with
    // the faired positions, and which vertices were free where the format holds fields.
    Eigen::VectorXd free_mask = Eigen::VectorXd::Ones(mesh.num_vertices());
    for (int v : fixed) free_mask[v] = 0;
    d.V = r.V;
    for (const auto& name : refresh_normal_fields(d))
      fmt::print(stderr, "note: {}: normals '{}' recomputed on the faired surface\n", a->mesh, name);
    std::string ext = std::filesystem::path(a->out).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".ply" || ext == ".vtp" || ext == ".vtk") d.vertex_scalars["free"] = free_mask;
    for (const auto& w : write_mesh(a->out, d)) fmt::print(stderr, "warning: {}\n", w);
    if (!a->png.empty()) {
      RenderOptions ro = a->r;
      apply_view_options(ro, a->view, a->up, a->size);
      ro.title =
          fmt::format("{}{}", a->p.order == 1 ? "membrane" : "thin plate", a->p.regularize ? ", regularized" : "");
      write_png(a->png, render(r.V, mesh.triangles(), ro));
    }
    if (a->json) {
      print_json({{"fixed_vertices", fixed.size()},
                  {"free_vertices", mesh.num_vertices() - static_cast<int>(fixed.size())},
                  {"seconds", seconds},
                  {"cg_iterations", r.cg_iterations},
                  {"relative_residual", r.worst_residual},
                  {"solver", to_string(r.solver)},
                  {"laplacian", to_string(r.laplacian)},
                  {"laplacian_reason", r.laplacian_reason},
                  {"before", quality_json(r.before)},
                  {"after", quality_json(r.after)}});
    } else {
      fmt::print("{} fixed, {} free vertices; {:.3f} s, {} CG iterations (worst relative residual {:.2g})\n",
                 fixed.size(), mesh.num_vertices() - static_cast<int>(fixed.size()), seconds, r.cg_iterations,
                 r.worst_residual);
      print_quality("before", r.before);
      print_quality("after ", r.after);
      fmt::print("wrote {}\n", a->out);
    }
  });
}

/// Reads an interpolation constraints file (CSV or JSON: parse_constraints).
std::vector<InterpolationConstraint> read_constraints(const std::string& path, const Mesh& mesh, int m) {
  return parse_constraints(mesh, read_file(path), m, path);
}

void add_interpolate_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("interpolate",
                                 "Spread values given at a few vertices: scalars, displacements or tangent vectors");
  struct Args {
    std::string mesh, constraints, kind = "scalar", method = "componentwise", out, png, solver = "auto",
                                   laplacian = "auto";
    std::string view = "30,20", up = "y", size = "960x720";
    double g1 = 0, g2 = 1;
    CgOptions cg = InterpolationParams{}.cg;
    bool json = false;
    RenderOptions r;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Mesh file")->required();
  cmd->add_option("--constraints", a->constraints,
                  "CSV (vertex,value[,value,value]) or JSON ({\"constraints\": [{\"vertex\": V, \"value\": X}]})")
      ->required();
  cmd->add_option("--kind", a->kind, "scalar | displacement | tangent")
      ->check(CLI::IsMember({"scalar", "displacement", "tangent"}))
      ->capture_default_str();
  cmd->add_option("--g1", a->g1, "Laplacian weight")->capture_default_str();
  cmd->add_option("--g2", a->g2, "bi-Laplacian weight")->capture_default_str();
  cmd->add_option("--solver", a->solver,
                  fmt::format("auto (g2 > 0: the multigrid on meshes of {} free vertices or more without angles "
                              "under {} degrees, kept where it converges; else direct) | direct (sparse Cholesky) | "
                              "global (multigrid or Laplacian-factor CG, large meshes, g2 > 0) | iterative (Jacobi-CG)",
                              kAutoGlobalFromFreeVertices, kAutoMultigridMinAngleDeg))
      ->check(CLI::IsMember({"auto", "direct", "global", "iterative"}))
      ->capture_default_str();
  add_laplacian_option(cmd, a->laplacian, "tangent fields always use cotan");
  cmd->add_option("--tolerance", a->cg.tolerance, "CG relative residual tolerance (--solver iterative)")
      ->capture_default_str();
  cmd->add_option("--method", a->method, "tangent fields: componentwise (seed) | connection | both")
      ->check(CLI::IsMember({"componentwise", "connection", "both"}))
      ->capture_default_str();
  cmd->add_option("-o,--output", a->out,
                  "Output .ply: field 'u'; displacements move the mesh and add d_x, d_y, d_z; "
                  "tangent fields add NAME_x, NAME_y, NAME_z (NAME: componentwise, connection)")
      ->required();
  cmd->add_option("--png", a->png, "Picture (for --method both: the two side by side)");
  add_view_options(cmd, a->r, a->view, a->up, a->size);
  cmd->add_flag("--json", a->json, "Print a JSON report");
  cmd->callback([=] {
    if (format_from_path(a->out) != MeshFormat::Ply)
      throw InputError(fmt::format("{}: fields need a .ply output", a->out));
    check_tolerance(a->cg.tolerance, "--tolerance");
    const Mesh mesh = load_mesh(a->mesh);
    warn_about_shape(mesh, a->mesh);
    const FieldKind kind = a->kind == "scalar"         ? FieldKind::Scalar
                           : a->kind == "displacement" ? FieldKind::Displacement
                                                       : FieldKind::Tangent;
    const auto cons = read_constraints(a->constraints, mesh, kind == FieldKind::Scalar ? 1 : 3);
    std::vector<std::pair<std::string, TangentMethod>> runs;
    if (kind != FieldKind::Tangent || a->method == "componentwise" || a->method == "both")
      runs.emplace_back("componentwise", TangentMethod::Componentwise);
    if (kind == FieldKind::Tangent && (a->method == "connection" || a->method == "both"))
      runs.emplace_back("connection", TangentMethod::Connection);
    std::map<std::string, Eigen::VectorXd> fields;
    Positions out_V = mesh.positions();
    std::vector<Image> pictures;
    nlohmann::json report{{"constraints", cons.size()}, {"g1", a->g1}, {"g2", a->g2}};
    for (const auto& [name, method] : runs) {
      const auto t0 = std::chrono::steady_clock::now();
      const InterpolationResult r = interpolate(mesh, kind, cons,
                                                InterpolationParams{.g1 = a->g1,
                                                                    .g2 = a->g2,
                                                                    .method = method,
                                                                    .solver = parse_steady_solver(a->solver),
                                                                    .cg = a->cg,
                                                                    .laplacian = parse_laplacian_kind(a->laplacian)});
      if (!r.cg.converged()) throw SolverError(fmt::format("interpolation did not converge: {}", r.cg.message));
      report["laplacian"] = to_string(r.laplacian);
      report["laplacian_reason"] = r.laplacian_reason;
      report["solver"] = to_string(r.solver);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      RenderOptions ro = a->r;
      apply_view_options(ro, a->view, a->up, a->size);
      if (kind == FieldKind::Scalar) {
        fields["u"] = r.values.col(0);
        ro.field = r.values.col(0);
        ro.field_name = "u";
      } else if (kind == FieldKind::Displacement) {
        out_V += r.values;
        for (int c = 0; c < 3; ++c) fields[std::string("d_") + "xyz"[c]] = r.values.col(c);
        ro.field = r.values.rowwise().norm();
        ro.field_name = "|d|";
      } else {
        for (int c = 0; c < 3; ++c) fields[name + "_" + "xyz"[c]] = r.values.col(c);
        ro.field = r.values.rowwise().norm();
        ro.field_name = "|v|";
        ro.vectors = r.values;
        ro.arrow_color = Eigen::Vector3d(0.05, 0.05, 0.05);
        ro.title = name;
      }
      report[kind == FieldKind::Tangent ? name : "result"] = {{"seconds", seconds},
                                                              {"cg_iterations", r.cg.iterations},
                                                              {"relative_residual", r.cg.relative_residual},
                                                              {"min_magnitude", r.values.rowwise().norm().minCoeff()},
                                                              {"max_magnitude", r.values.rowwise().norm().maxCoeff()}};
      if (!a->png.empty()) pictures.push_back(render(out_V, mesh.triangles(), ro));
      if (!a->json)
        fmt::print("{}: {:.3f} s, {} CG iterations (relative residual {:.2g}), |value| in [{:.4g}, {:.4g}]\n", name,
                   seconds, r.cg.iterations, r.cg.relative_residual, r.values.rowwise().norm().minCoeff(),
                   r.values.rowwise().norm().maxCoeff());
    }
    save_mesh(a->out, out_V, mesh.triangles(), fields);
    if (!a->png.empty()) write_png(a->png, side_by_side(pictures));
    if (a->json) print_json(report);
  });
}

void add_poke_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("poke", "Replay a probe path on a haptic session: forces, latency, domain size");
  struct Args {
    std::string mesh, vertex = "0", path, png, view = "30,20", up = "y", size = "960x720", solver = "factored",
                      laplacian;
    double settle = 0.3, depth = 0.5;
    bool json = false, realtime = true;
    HapticParams h;
    RenderOptions r;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Mesh file")->required();
  cmd->add_option("--vertex", a->vertex, "Contact vertex (index or @X,Y,Z)")->capture_default_str();
  cmd->add_option("--path", a->path,
                  "Probe path CSV t,dx,dy,dz (s; offset from the rest position). Default: press along the inward "
                  "normal to --depth mean edge lengths over 0.5 s, hold 0.2 s");
  cmd->add_option("--depth", a->depth, "Default path: depth in mean edge lengths")->capture_default_str();
  cmd->add_option("--rate", a->h.rate_hz, "Servo rate (Hz)")->capture_default_str();
  cmd->add_option("--settle", a->settle, "Seconds to keep stepping after the release")->capture_default_str();
  cmd->add_option(
         "--influence", a->h.influence,
         fmt::format("Decay length of a poke (mesh units; 0: {} mean edges)", HapticParams::default_influence_edges))
      ->capture_default_str();
  cmd->add_option("--stiffness", a->h.stiffness, "Foundation stiffness g0 (g2 = g0 influence^4)")
      ->capture_default_str();
  cmd->add_option("--solver", a->solver,
                  "Step solver: factored (a factor of the active domain, rebuilt on a second thread; bounded steps) "
                  "or cg (Jacobi-CG every step)")
      ->check(CLI::IsMember({"factored", "cg"}))
      ->capture_default_str();
  add_laplacian_option(cmd, a->laplacian);
  cmd->add_flag("!--no-realtime", a->realtime,
                "Step as fast as possible instead of on the real-time servo thread (the factored solver then waits "
                "for each factor: the same forces every run)");
  cmd->add_option("--png", a->png, "Picture at the end of the path: displacement and the force arrow");
  add_view_options(cmd, a->r, a->view, a->up, a->size);
  cmd->add_flag("--json", a->json, "Print a JSON report with every step");
  cmd->callback([=] {
    const Mesh mesh = load_mesh(a->mesh);
    const int v = parse_vertex(mesh, a->vertex, "--vertex");
    // The intrinsic operators live on their own connectivity (same vertices): the
    // probe runs there, the path and the picture on the input triangles.
    const MeshOperators mo = build_mesh_operators(mesh, parse_laplacian_kind(a->laplacian));
    std::vector<ProbePathPoint> path;
    if (!a->path.empty()) {
      std::ifstream in(a->path, std::ios::binary);
      if (!in) throw InputError(fmt::format("{}: cannot open", a->path));
      std::stringstream text;
      text << in.rdbuf();
      path = parse_probe_path(text.str(), a->path);
    } else {
      path = press_path(mesh, v, a->depth);
    }
    a->h.solver = a->solver == "cg" ? HapticSolver::Cg : HapticSolver::Factored;
    a->h.wait_for_factors = !a->realtime;  // steps back to back: keep the domain up with them
    HapticSession s(mo.mesh, mo.ops, a->h);
    s.touch(v);
    const double period = 1.0 / a->h.rate_hz;
    const double t_end = path.back().t;
    Eigen::VectorXd picture_field;
    Positions picture_V;
    Eigen::Vector3d picture_force = Eigen::Vector3d::Zero();
    auto snapshot = [&] {
      picture_V = mesh.positions() + s.pde().values();
      picture_field = s.pde().values().rowwise().norm();
      picture_force = s.latest_force();
    };
    Progress progress(static_cast<long long>((t_end + a->settle) * 1000), "poke", !a->json && a->realtime);
    if (a->realtime) {
      s.start();
      const auto t0 = std::chrono::steady_clock::now();
      for (;;) {
        const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (t > t_end) break;
        s.move_probe(probe_path_at(path, t));
        progress.update(static_cast<long long>(t * 1000));
        std::this_thread::sleep_for(std::chrono::microseconds(250));
      }
      s.stop();
      snapshot();
      s.release();
      s.start();
      std::this_thread::sleep_for(std::chrono::duration<double>(a->settle));
      s.stop();
      progress.update(static_cast<long long>((t_end + a->settle) * 1000));
    } else {
      for (double t = period; t <= t_end + 1e-12; t += period) {
        s.move_probe(probe_path_at(path, t));
        s.step(period);
      }
      snapshot();
      s.release();
      for (double t = 0; t < a->settle; t += period) s.step(period);
    }
    const auto log = s.log();
    std::vector<double> lat;
    for (const auto& x : log) lat.push_back(x.latency_us);
    std::sort(lat.begin(), lat.end());
    auto pct = [&](double q) {
      return lat.empty() ? 0.0 : lat[std::min(lat.size() - 1, static_cast<std::size_t>(q * lat.size()))];
    };
    int max_free = 0;
    for (const auto& x : log) max_free = std::max(max_free, x.free_vertices);
    if (!a->png.empty()) {
      RenderOptions ro = a->r;
      apply_view_options(ro, a->view, a->up, a->size);
      ro.field = picture_field;
      ro.field_name = "|d|";
      const double L = 0.1 * (mesh.positions().colwise().maxCoeff() - mesh.positions().colwise().minCoeff()).norm();
      if (picture_force.norm() > 0)
        ro.extra_arrows.emplace_back(picture_V.row(v).transpose(), L * picture_force.normalized());
      ro.title = fmt::format("poke: force {:.3g}", picture_force.norm());
      write_png(a->png, render(picture_V, mesh.triangles(), ro));
    }
    if (a->json) {
      nlohmann::json samples = nlohmann::json::array();
      for (const auto& x : log)
        samples.push_back({{"t", x.time},
                           {"probe", {x.probe.x(), x.probe.y(), x.probe.z()}},
                           {"force", {x.force.x(), x.force.y(), x.force.z()}},
                           {"latency_us", x.latency_us},
                           {"free_vertices", x.free_vertices},
                           {"cg_iterations", x.cg_iterations},
                           {"factored", x.factored},
                           {"new_factor", x.new_factor},
                           {"install_us", x.install_us},
                           {"solve_us", x.solve_us},
                           {"propose_us", x.propose_us},
                           {"publish_us", x.publish_us},
                           {"missed", x.missed}});
      print_json({{"vertex", v},
                  {"solver", a->h.solver == HapticSolver::Cg ? "cg" : "factored"},
                  {"laplacian", to_string(mo.kind)},
                  {"factorizations", s.factorizations()},
                  {"rate", a->h.rate_hz},
                  {"realtime", a->realtime},
                  {"steps", log.size()},
                  {"deadline_misses", s.misses()},
                  {"latency_us", {{"p50", pct(0.5)}, {"p99", pct(0.99)}, {"max", lat.empty() ? 0.0 : lat.back()}}},
                  {"max_free_vertices", max_free},
                  {"final_free_vertices", log.empty() ? 0 : log.back().free_vertices},
                  {"samples", samples}});
    } else {
      fmt::print("{} steps at {} Hz ({}): latency p50 {:.0f} us, p99 {:.0f} us, max {:.0f} us; {} deadline misses\n",
                 log.size(), a->h.rate_hz, a->h.solver == HapticSolver::Cg ? "cg" : "factored", pct(0.5), pct(0.99),
                 lat.empty() ? 0.0 : lat.back(), s.misses());
      fmt::print(
          "active domain: up to {} vertices, {} after the release settled; force at the end of the path {:.4g}\n",
          max_free, log.empty() ? 0 : log.back().free_vertices, picture_force.norm());
    }
  });
}

}  // namespace

void add_app_commands(CLI::App& app) {
  add_poke_command(app);
  add_interpolate_command(app);
  add_propagation_command(app, Propagation::Heat);
  add_propagation_command(app, Propagation::Wave);
  add_fair_command(app);
}

}  // namespace meshpde::cli
