// Methods, region boundaries, handles and their moves as users write them.
#include <fmt/format.h>

#include <cmath>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "correction_internal.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

CorrectionMethod parse_correction_method(const std::string& text) {
  if (text == "fem") return CorrectionMethod::Fem;
  if (text == "springs") return CorrectionMethod::Springs;
  throw InputError(fmt::format("unknown correction method '{}' (expected fem or springs)", text));
}

const char* to_string(CorrectionMethod method) {
  return method == CorrectionMethod::Springs ? "springs" : "fem";
}

namespace {

// "DX,DY,DZ": exactly three finite numbers.
Eigen::Vector3d parse_displacement(const std::string& s) {
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
      throw InputError(fmt::format("move '{}': '{}' is not a number", s, item));
    }
    ++k;
  }
  if (k != 3 || ss.rdbuf()->in_avail() > 0)
    throw InputError(fmt::format("move '{}' must be three comma-separated numbers, e.g. 1.5,0,-2, or normal:D", s));
  return v;
}

// One move as the user writes it: "DX,DY,DZ" or "normal:D" along `normal()` (a unit
// vector, or zero where there is none: then `where` names the place in the error).
template <class Normal>
Eigen::Vector3d parse_move(const std::string& text, Normal&& normal, const std::string& where) {
  if (text.rfind("normal:", 0) != 0) return parse_displacement(text);
  double dist = 0;
  try {
    std::size_t used = 0;
    dist = std::stod(text.substr(7), &used);
    if (used != text.size() - 7 || !std::isfinite(dist)) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw InputError(fmt::format("move '{}': expected normal:DISTANCE, e.g. normal:2.5", text));
  }
  const Eigen::Vector3d n = normal();
  if (!(n.norm() > 0)) throw InputError(fmt::format("{} has no normal (no incident area)", where));
  return dist * n;
}

void check_counts(std::size_t handles, std::size_t moves) {
  if (handles != moves)
    throw InputError(fmt::format("{} handles but {} moves: give one move per handle", handles, moves));
}

}  // namespace

CorrectionHandle::CorrectionHandle(const Mesh& mesh, const SurfacePoint& p, const Eigen::Vector3d& d)
    : displacement(d), point(p) {
  // The triangle here (vertex needs it); the coordinates with the correction (validate).
  check_surface_point(mesh, SurfacePoint{p.face}, "handle point");
  vertex = nearest_corner(mesh, p);
}

std::vector<CorrectionHandle> parse_handles(const Mesh& mesh, const std::vector<int>& vertices,
                                            const std::vector<std::string>& moves) {
  check_counts(vertices.size(), moves.size());
  std::optional<Eigen::MatrixX3d> normals;  // computed once, if a move is along a normal
  std::vector<CorrectionHandle> handles;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const int v = vertices[k];
    if (v < 0 || v >= mesh.num_vertices())
      throw InputError(
          fmt::format("handle vertex {} is out of range (the mesh has {} vertices)", v, mesh.num_vertices()));
    auto normal = [&]() -> Eigen::Vector3d {
      if (!normals) normals = outward_vertex_normals(mesh);
      return normals->row(v).transpose();
    };
    handles.push_back({v, parse_move(moves[k], normal, fmt::format("vertex {}", v))});
  }
  return handles;
}

std::vector<CorrectionHandle> parse_point_handles(const Mesh& mesh, const std::vector<Eigen::Vector3d>& points,
                                                  const std::vector<std::string>& moves) {
  check_counts(points.size(), moves.size());
  const std::vector<SurfacePoint> at = closest_surface_points(mesh, points);
  std::optional<Eigen::MatrixX3d> normals;
  std::vector<CorrectionHandle> handles;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const SurfacePoint& sp = at[k];
    auto normal = [&]() -> Eigen::Vector3d {
      if (!normals) normals = outward_vertex_normals(mesh);
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      for (int c = 0; c < 3; ++c) n += sp.bary[c] * normals->row(mesh.triangles()(sp.face, c)).transpose();
      return n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : n;
    };
    handles.emplace_back(
        mesh, sp,
        parse_move(moves[k], normal,
                   fmt::format("the point ({:g}, {:g}, {:g})", points[k].x(), points[k].y(), points[k].z())));
    handles.back().given = points[k];
  }
  return handles;
}

}  // namespace meshpde
