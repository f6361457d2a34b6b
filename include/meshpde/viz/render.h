// Headless rendering of a mesh to an image: no display, no GPU. A software
// rasterizer with a z-buffer, two-sided Lambert shading, a colormap with a legend
// for a per-vertex field, arrows for a per-vertex vector field and an optional
// wireframe, supersampled for smooth edges. Target: meshpde::viz (needs libpng).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< row-major, 3 bytes per pixel, top row first
};

enum class Colormap { Viridis, Coolwarm };
/// "viridis" or "coolwarm". \throw InputError otherwise.
Colormap parse_colormap(const std::string& name);
/// The up axis by name: "x" 0, "y" 1, "z" 2. \throw InputError otherwise.
int parse_up_axis(const std::string& name);

struct RenderOptions {
  int width = 960;
  int height = 720;
  double azimuth_deg = 30;                  ///< camera rotation about the up axis
  double elevation_deg = 20;                ///< camera tilt towards the up axis
  int up_axis = 1;                          ///< 0: x, 1: y (Stanford models), 2: z (medical RAS/LPS)
  double zoom = 1.0;                        ///< > 1 magnifies around the centre
  std::optional<Eigen::Vector3d> center{};  ///< point at the middle of the picture (default: the bounding-box centre)
  bool wireframe = false;
  Eigen::VectorXd field{};  ///< per-vertex values to colour (empty: plain grey-blue surface)
  std::string field_name{};
  std::optional<std::pair<double, double>> range{};  ///< colour range (default: field min..max)
  Colormap colormap = Colormap::Viridis;
  Eigen::MatrixX3d vectors{};         ///< per-vertex arrows (#V x 3), empty: none
  std::vector<int> arrow_vertices{};  ///< draw arrows only here (empty: every vertex with a non-zero vector)
  int max_arrows = 400;               ///< when arrow_vertices is empty, an even stride keeps at most this many
  double arrow_scale = 0;             ///< world length per unit vector; 0: longest arrow = 10% of the mesh size
  Eigen::Vector3d arrow_color{0.85, 0.1, 0.1};
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> extra_arrows{};  ///< (start, vector) in world units
  std::string title{};
  int supersample = 2;  ///< render at this multiple, then box-filter down
};

/// \throw InputError on a size mismatch (field, vectors) or a non-positive image size.
Image render(const Positions& V, const Triangles& F, const RenderOptions& options);

/// Colour of t in [0, 1] (clamped), components in [0, 1].
Eigen::Vector3d colormap(Colormap map, double t);

/// Places images left to right (heights may differ; the shorter ones are padded white).
Image side_by_side(const std::vector<Image>& images);

/// Writes a PNG atomically. \throw Error if it cannot be written.
void write_png(const std::filesystem::path& path, const Image& image);

/// Reads a PNG written by write_png (8-bit RGB). For tests and tools.
Image read_png(const std::filesystem::path& path);

}  // namespace meshpde
