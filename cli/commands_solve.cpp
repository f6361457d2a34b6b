// meshpde correct | demo
#include <fmt/format.h>

#include <chrono>
#include <memory>
#include <sstream>

#include "commands.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"

namespace meshpde::cli {

namespace {

Eigen::Vector3d parse_vector(const std::string& s, const char* what) {
  Eigen::Vector3d v;
  std::stringstream ss(s);
  std::string item;
  int k = 0;
  while (std::getline(ss, item, ',')) {
    if (k >= 3) break;
    try {
      std::size_t used = 0;
      v[k] = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(v[k])) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw InputError(fmt::format("{} '{}': '{}' is not a number", what, s, item));
    }
    ++k;
  }
  if (k != 3 || ss.rdbuf()->in_avail() > 0)
    throw InputError(fmt::format("{} '{}' must be three comma-separated numbers, e.g. 1.5,0,-2", what, s));
  return v;
}

struct DragReport {
  DragResult result;
  double setup_ms = 0, solve_ms = 0;
};

DragReport run_drag(const Mesh& mesh, const DragParams& p) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const FemOperators ops = build_operators(mesh);
  const auto t1 = clock::now();
  DragReport r{drag_vertex(mesh, ops, p)};
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
          {"handle_force", {r.result.reaction.x(), r.result.reaction.y(), r.result.reaction.z()}}};
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

}  // namespace

void add_solve_commands(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand(
        "correct", "Drag one vertex by a displacement; the region around it follows (bi-Laplacian, static)");
    struct Args {
      std::string mesh, move, out, solver = "direct";
      int vertex = -1, rings = 0;
      double radius = 0, g1 = 0, g2 = 1, tol = 1e-10;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("MESH", a->mesh, "Mesh file")->required();
    cmd->add_option("--vertex", a->vertex, "Handle vertex index (0-based)")->required();
    cmd->add_option("--move", a->move, "Displacement DX,DY,DZ in mesh units (mm)")->required();
    auto* radius = cmd->add_option("--radius", a->radius, "Region of influence: edge-path distance in mesh units");
    auto* rings = cmd->add_option("--rings", a->rings, "Region of influence in rings of neighbours");
    radius->excludes(rings);
    cmd->add_option("--g1", a->g1, "Membrane (Laplacian) stiffness")->capture_default_str();
    cmd->add_option("--g2", a->g2, "Plate (bi-Laplacian) stiffness")->capture_default_str();
    cmd->add_option("--solver", a->solver, "direct (sparse Cholesky of the region) | iterative (Jacobi-CG)")
        ->check(CLI::IsMember({"direct", "iterative"}))
        ->capture_default_str();
    cmd->add_option("--tolerance", a->tol, "CG relative residual tolerance (iterative)")->capture_default_str();
    cmd->add_option("-o,--output", a->out, "Corrected mesh (.ply keeps a 'displacement' magnitude field)")->required();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] {
      if (a->radius <= 0 && a->rings <= 0) throw InputError("give --radius MM or --rings K");
      const Mesh mesh = load_mesh(a->mesh);
      warn_about_shape(mesh, a->mesh);
      DragParams p{.vertex = a->vertex,
                   .displacement = parse_vector(a->move, "--move"),
                   .radius = a->radius,
                   .rings = a->rings,
                   .g1 = a->g1,
                   .g2 = a->g2};
      p.cg.tolerance = a->tol;
      p.solver = a->solver == "direct" ? SteadySolver::Direct : SteadySolver::Iterative;
      const DragReport r = run_drag(mesh, p);
      if (!r.result.cg.converged()) fmt::print(stderr, "warning: {}\n", r.result.cg.message);
      save_mesh(a->out, r.result.V, mesh.triangles(),
                format_from_path(a->out) == MeshFormat::Ply ? displacement_fields(r.result)
                                                            : std::map<std::string, Eigen::VectorXd>{});
      if (a->json)
        print_json(drag_json(r));
      else
        print_drag(r, a->out);
      if (!r.result.cg.converged()) throw SolverError("the solve did not converge; the output is approximate");
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "demo", "Main job: generate a dented Y bifurcation and drag the dented wall back out (bi-Laplacian, local)");
    struct Args {
      std::string outdir = "meshpde-demo";
      double radius = 8.0;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("-o,--output-dir", a->outdir, "Where to write the input and corrected meshes")
        ->capture_default_str();
    cmd->add_option("--radius", a->radius, "Region of influence in mm")->capture_default_str();
    cmd->add_flag("--json", a->json, "Print a JSON report");
    cmd->callback([=] {
      const BifurcationParams bp{.dent = true};
      const GeneratedMesh g = y_bifurcation(bp);
      const Mesh mesh(g.V, g.F);
      // The handle: the wall vertex nearest the bottom of the dent.
      const Eigen::Vector3d target(bp.trunk_radius - bp.dent_depth, 0, -0.5 * bp.trunk_length);
      int handle = 0;
      (mesh.positions().rowwise() - target.transpose()).rowwise().squaredNorm().minCoeff(&handle);
      const Eigen::Vector3d p = mesh.positions().row(handle).transpose();
      const double r_xy = std::hypot(p.x(), p.y());
      const Eigen::Vector3d outward(p.x() / r_xy, p.y() / r_xy, 0);
      const Eigen::Vector3d move = (bp.trunk_radius - r_xy) * outward;
      std::filesystem::create_directories(a->outdir);
      const auto in_path = std::filesystem::path(a->outdir) / "bifurcation-dented.ply";
      const auto out_path = std::filesystem::path(a->outdir) / "bifurcation-corrected.ply";
      save_mesh(in_path, mesh.positions(), mesh.triangles());
      const MeshReport rep = analyze(mesh);
      const DragReport r = run_drag(mesh, DragParams{.vertex = handle, .displacement = move, .radius = a->radius});
      save_mesh(out_path, r.result.V, mesh.triangles(), displacement_fields(r.result));
      if (a->json) {
        auto j = drag_json(r);
        j["mesh_vertices"] = mesh.num_vertices();
        j["handle"] = handle;
        j["move"] = {move.x(), move.y(), move.z()};
        j["input"] = in_path.string();
        j["output"] = out_path.string();
        print_json(j);
      } else {
        fmt::print("generated a dented Y bifurcation: {} vertices, {} triangles, smallest angle {:.1f} deg\n",
                   mesh.num_vertices(), mesh.num_faces(), rep.min_angle_deg);
        fmt::print("dragged wall vertex {} by ({:.3f}, {:.3f}, {:.3f}) mm, region radius {} mm\n", handle, move.x(),
                   move.y(), move.z(), a->radius);
        print_drag(r, out_path.string());
      }
      if (!r.result.cg.converged()) throw SolverError(r.result.cg.message);
    });
  }
}

}  // namespace meshpde::cli
