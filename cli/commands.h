// Subcommands of the meshpde tool. Each registers itself on the CLI11 app; the
// front end holds no numerics of its own, it calls the library.
#pragma once

#include <CLI/CLI.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "meshpde/image/volume.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {
struct RenderOptions;
}

namespace meshpde::cli {

void add_mesh_commands(CLI::App& app);          // info, generate, curvature
void add_solve_commands(CLI::App& app);         // correct, demo
void add_bench_command(CLI::App& app);          // bench
void add_render_command(CLI::App& app);         // render
void add_app_commands(CLI::App& app);           // heat, wave, fair, interpolate, poke
void add_partition_command(CLI::App& app);      // partition (the distributed component's input)
void add_segmentation_commands(CLI::App& app);  // extract, voxelize (with meshpde::medical)

/// Shared --view/--up/--size/--wireframe/--zoom options of commands that draw pictures.
void add_view_options(CLI::App* cmd, RenderOptions& r, std::string& view, std::string& up, std::string& size);
void apply_view_options(RenderOptions& r, const std::string& view, const std::string& up, const std::string& size);

/// The shared --laplacian auto|cotan|intrinsic option (default auto); `note` is added
/// to its help when the command treats some case its own way.
void add_laplacian_option(CLI::App* cmd, std::string& value, const std::string& note = "");

/// A vertex given as an index or as @X,Y,Z (the nearest vertex). \throw InputError
int parse_vertex(const Mesh& mesh, const std::string& spec, const char* what);
/// VERTEX:VALUE. \throw InputError
std::pair<int, double> parse_vertex_value(const Mesh& mesh, const std::string& spec, const char* what);

/// Reads the vector field NAME stored as vertex properties NAME_x, NAME_y, NAME_z.
Eigen::MatrixX3d vector_field(const MeshData& d, const std::string& name, const std::string& file);

/// meshpde serve (the browser editor), when built with websocketpp.
void add_serve_command(CLI::App& app);

/// Reads a mesh, prints reader warnings to stderr, builds connectivity.
Mesh load_mesh(const std::filesystem::path& path, MeshData* data = nullptr);

/// Writes a mesh with optional vertex fields, printing writer warnings to stderr.
void save_mesh(const std::filesystem::path& path, const Positions& V, const Triangles& F,
               const std::map<std::string, Eigen::VectorXd>& fields = {});

/// Prints the shape warnings a solver's user must see (badly shaped, degenerate,
/// non-manifold) to stderr; returns the report they came from.
MeshReport warn_about_shape(const Mesh& mesh, const std::string& name);

/// The frame of a mesh's coordinates: the --space option when given, else the
/// file's 3D Slicer SPACE= header, else LPS. \throw InputError for a bad option.
Space mesh_space(const std::string& option, const MeshData& data);

/// Prints JSON to stdout (2-space indent).
void print_json(const nlohmann::json& j);

/// The bench's folder of real meshes: `option` (--data-dir) when given, else the
/// environment variable MESHPDE_DATA_DIR, else none (a warning; real-mesh figures are
/// skipped). A path that is not a folder is an InputError.
std::filesystem::path bench_data_dir(const std::string& option);

}  // namespace meshpde::cli
