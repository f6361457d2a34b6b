// meshpde command-line tool: mesh diagnostics, generators, curvature, local drags
// and benchmarks. Exit codes: 0 success, 1 bad input or failed solve, 2 usage error.
#include <fmt/format.h>

#include <cstdlib>
#include <iostream>

#include "commands.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"
#include "usage.h"

namespace meshpde::cli {

Mesh load_mesh(const std::filesystem::path& path, MeshData* out) {
  MeshData d = read_mesh(path);
  for (const auto& w : d.warnings) fmt::print(stderr, "warning: {}\n", w);
  try {
    Mesh m(d.V, d.F);
    if (out) *out = std::move(d);
    return m;
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

void save_mesh(const std::filesystem::path& path, const Positions& V, const Triangles& F,
               const std::map<std::string, Eigen::VectorXd>& fields) {
  MeshData d;
  d.V = V;
  d.F = F;
  d.vertex_scalars = fields;
  for (const auto& w : write_mesh(path, d)) fmt::print(stderr, "warning: {}\n", w);
}

MeshReport warn_about_shape(const Mesh& mesh, const std::string& name) {
  MeshReport r = analyze(mesh);
  for (const auto& w : r.warnings) fmt::print(stderr, "warning: {}: {}\n", name, w);
  return r;
}

Space mesh_space(const std::string& option, const MeshData& data) {
  if (!option.empty()) return parse_space(option);
  return data.space == "RAS" ? Space::RAS : Space::LPS;
}

void print_json(const nlohmann::json& j) {
  std::cout << j.dump(2) << std::endl;
}

std::filesystem::path bench_data_dir(const std::string& option) {
  std::filesystem::path dir = option;
  if (dir.empty()) {
    const char* env = std::getenv("MESHPDE_DATA_DIR");
    if (!env || !*env) {
      fmt::print(stderr,
                 "warning: no data folder (--data-dir or MESHPDE_DATA_DIR): the figures on real meshes are skipped\n");
      return {};
    }
    dir = env;
  }
  if (!std::filesystem::is_directory(dir)) throw InputError(fmt::format("{}: not a folder", dir.string()));
  return dir;
}

}  // namespace meshpde::cli

int main(int argc, char** argv) {
  CLI::App app{"meshpde: localized Laplacian and bi-Laplacian PDE solvers on triangle meshes"};
  app.set_version_flag("--version", MESHPDE_VERSION);
  app.require_subcommand(1);
  meshpde::cli::add_mesh_commands(app);
  meshpde::cli::add_solve_commands(app);
  meshpde::cli::add_bench_command(app);
  meshpde::cli::add_render_command(app);
  meshpde::cli::add_app_commands(app);
  meshpde::cli::add_partition_command(app);
#ifdef MESHPDE_HAVE_MEDICAL
  meshpde::cli::add_segmentation_commands(app);
#endif
#ifdef MESHPDE_HAVE_SERVER
  meshpde::cli::add_serve_command(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return meshpde::cli::usage_error(app, e, "meshpde", argc, argv);
  } catch (const meshpde::Error& e) {
    fmt::print(stderr, "meshpde: error: {}\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "meshpde: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "meshpde: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
