// meshpde render
#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "meshpde/core/errors.h"
#include "meshpde/viz/render.h"

namespace meshpde::cli {

Eigen::MatrixX3d vector_field(const MeshData& d, const std::string& name, const std::string& file) {
  Eigen::MatrixX3d vec(d.V.rows(), 3);
  const char* comp[3] = {"_x", "_y", "_z"};
  for (int c = 0; c < 3; ++c) {
    const auto it = d.vertex_scalars.find(name + comp[c]);
    if (it == d.vertex_scalars.end())
      throw InputError(
          fmt::format("{}: no vertex property '{}{}' (a vector field NAME is stored as NAME_x, "
                      "NAME_y, NAME_z)",
                      file, name, comp[c]));
    vec.col(c) = it->second;
  }
  return vec;
}

void add_view_options(CLI::App* cmd, RenderOptions& r, std::string& view, std::string& up, std::string& size) {
  cmd->add_option("--view", view, "Camera azimuth,elevation in degrees")->capture_default_str();
  cmd->add_option("--up", up, "Up axis: x, y (Stanford models) or z (medical)")
      ->check(CLI::IsMember({"x", "y", "z"}))
      ->capture_default_str();
  cmd->add_option("--size", size, "Image size WxH")->capture_default_str();
  cmd->add_flag("--wireframe", r.wireframe, "Draw the triangle edges");
  cmd->add_option("--zoom", r.zoom, "Magnification around the centre")->capture_default_str();
}

void apply_view_options(RenderOptions& r, const std::string& view, const std::string& up, const std::string& size) {
  if (std::sscanf(view.c_str(), "%lf,%lf", &r.azimuth_deg, &r.elevation_deg) != 2)
    throw InputError(fmt::format("--view '{}' must be AZ,EL in degrees, e.g. 30,20", view));
  if (std::sscanf(size.c_str(), "%dx%d", &r.width, &r.height) != 2)
    throw InputError(fmt::format("--size '{}' must be WxH, e.g. 960x720", size));
  r.up_axis = parse_up_axis(up);
}

void add_render_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "Render a mesh to PNG (headless): shading, field colours, arrows");
  struct Args {
    std::string mesh, out, field, vectors, title, colormap = "viridis", range, center;
    std::string view = "30,20", up = "y", size = "960x720";
    RenderOptions r;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Mesh file (.ply, .vtp and .vtk keep vertex fields)")->required();
  cmd->add_option("-o,--output", a->out, "Output .png")->required();
  cmd->add_option("--field", a->field, "Vertex property to colour");
  cmd->add_option("--vectors", a->vectors, "Vector field NAME (vertex properties NAME_x, NAME_y, NAME_z) as arrows");
  cmd->add_option("--title", a->title, "Title at the top left");
  cmd->add_option("--colormap", a->colormap, "viridis | coolwarm")
      ->check(CLI::IsMember({"viridis", "coolwarm"}))
      ->capture_default_str();
  cmd->add_option("--range", a->range, "Colour range MIN,MAX (default: the field's)");
  add_view_options(cmd, a->r, a->view, a->up, a->size);
  cmd->add_option("--center", a->center, "Point at the middle of the picture: a vertex (index or @X,Y,Z)");
  cmd->callback([=] {
    MeshData d;
    const Mesh mesh = load_mesh(a->mesh, &d);
    RenderOptions r = a->r;
    if (!a->center.empty()) r.center = mesh.positions().row(parse_vertex(mesh, a->center, "--center")).transpose();
    apply_view_options(r, a->view, a->up, a->size);
    r.title = a->title;
    r.colormap = parse_colormap(a->colormap);
    if (!a->field.empty()) {
      const auto it = d.vertex_scalars.find(a->field);
      if (it == d.vertex_scalars.end()) {
        std::string names;
        for (const auto& [k, v] : d.vertex_scalars) names += (names.empty() ? "" : ", ") + k;
        throw InputError(fmt::format("{}: no vertex property '{}' (available: {})", a->mesh, a->field,
                                     names.empty() ? "none" : names));
      }
      r.field = it->second;
      r.field_name = a->field;
    }
    if (!a->range.empty()) {
      double lo = 0, hi = 0;
      if (std::sscanf(a->range.c_str(), "%lf,%lf", &lo, &hi) != 2 || !(hi > lo))
        throw InputError(fmt::format("--range '{}' must be MIN,MAX with MIN < MAX", a->range));
      r.range = std::make_pair(lo, hi);
    }
    if (!a->vectors.empty()) r.vectors = vector_field(d, a->vectors, a->mesh);
    write_png(a->out, render(d.V, d.F, r));
    fmt::print("wrote {} ({}x{})\n", a->out, r.width, r.height);
  });
}

}  // namespace meshpde::cli
