// Wavefront OBJ and Geomview OFF, both text.
#include <fmt/format.h>

#include <limits>

#include "io_detail.h"

namespace meshpde::detail {

namespace {

std::string polygon_warning(int polygons, const std::string& name) {
  return fmt::format("{}: triangulated {} polygon{} with more than three corners", name, polygons,
                     polygons == 1 ? "" : "s");
}

void append_vertex(std::string& out, double x, double y, double z, const char* prefix) {
  fmt::format_to(std::back_inserter(out), "{}{} {} {}\n", prefix, x, y, z);
}

}  // namespace

MeshData read_obj(std::string_view text, const std::string& name) {
  TextCursor in(text, name);
  std::vector<double> xyz;
  std::vector<int> tris;
  std::vector<int> poly;
  int polygons = 0, skipped_lines = 0;
  while (in.next_content_line()) {
    const auto key = in.token();
    if (key == "v") {
      for (int c = 0; c < 3; ++c) xyz.push_back(in.real("a vertex coordinate"));
    } else if (key == "f") {
      poly.clear();
      const long long nv = static_cast<long long>(xyz.size() / 3);
      while (in.has_token()) {
        const auto t = in.token();
        const auto slash = t.find('/');
        TextCursor sub(t.substr(0, slash), name);
        sub.next_line();
        long long idx = 0;
        try {
          idx = sub.integer("a vertex index");
        } catch (const InputError&) {
          in.error(fmt::format("expected a vertex index but found '{}'", TextCursor::clip(t)));
        }
        // OBJ indices are 1-based; negative ones count back from the latest vertex.
        const long long k = idx > 0 ? idx - 1 : nv + idx;
        if (idx == 0 || k < 0 || k >= nv)
          in.error(fmt::format("face index {} does not refer to one of the {} vertices read so far", idx, nv));
        poly.push_back(static_cast<int>(k));
      }
      if (poly.size() < 3) in.error(fmt::format("a face needs at least 3 corners, found {}", poly.size()));
      if (poly.size() > 3) ++polygons;
      add_polygon(tris, poly);
    } else if (key == "vt" || key == "vn" || key == "vp" || key == "o" || key == "g" || key == "s" || key == "usemtl" ||
               key == "mtllib") {
      // Texture coordinates, normals, groups and materials do not affect the PDEs.
    } else if (key == "l" || key == "p") {
      ++skipped_lines;
    } else {
      in.error(fmt::format("unknown OBJ statement '{}'", TextCursor::clip(key)));
    }
  }
  MeshData d;
  d.V = to_positions(xyz);
  d.F = to_triangles(tris);
  if (polygons) d.warnings.push_back(polygon_warning(polygons, name));
  if (skipped_lines) d.warnings.push_back(fmt::format("{}: ignored {} line/point elements", name, skipped_lines));
  return d;
}

MeshData read_off(std::string_view text, const std::string& name) {
  TextCursor in(text, name);
  if (!in.next_content_line()) fail(name, "line 1", "empty file (expected an OFF header)");
  auto key = in.token();
  bool color = false;
  if (key == "COFF" || key == "NOFF" || key == "CNOFF") {
    color = true;  // Trailing per-vertex attributes are ignored below.
  } else if (key != "OFF") {
    in.error(fmt::format("expected 'OFF' header, found '{}'", TextCursor::clip(key)));
  }
  (void)color;
  if (!in.has_token() && !in.next_content_line()) in.error("missing vertex/face counts");
  const long long nv = in.integer("the vertex count");
  const long long nf = in.integer("the face count");
  if (in.has_token()) in.integer("the edge count");
  if (nv < 0 || nf < 0) in.error(fmt::format("negative counts ({} vertices, {} faces)", nv, nf));
  // Each vertex needs at least 6 bytes of text ("0 0 0\n") and each face 8: a count
  // the file cannot possibly hold is rejected before anything is allocated.
  const long long remaining = static_cast<long long>(text.size() - in.position());
  if (nv > remaining / 6 + 1 || nf > remaining / 8 + 1)
    in.error(fmt::format("header claims {} vertices and {} faces, more than the {} bytes that follow can hold", nv, nf,
                         remaining));
  std::vector<double> xyz;
  xyz.reserve(static_cast<std::size_t>(3 * nv));
  for (long long v = 0; v < nv; ++v) {
    if (!in.next_content_line())
      fail(name, fmt::format("vertex {}", v), fmt::format("file ends after {} of {} vertices", v, nv));
    for (int c = 0; c < 3; ++c) xyz.push_back(in.real("a vertex coordinate"));
  }
  std::vector<int> tris, poly;
  tris.reserve(static_cast<std::size_t>(3 * nf));
  int polygons = 0;
  for (long long f = 0; f < nf; ++f) {
    if (!in.next_content_line())
      fail(name, fmt::format("face {}", f), fmt::format("file ends after {} of {} faces", f, nf));
    const long long n = in.integer("the corner count");
    if (n < 3 || n > 1'000'000) in.error(fmt::format("face {} has {} corners", f, n));
    poly.clear();
    for (long long k = 0; k < n; ++k) {
      const long long idx = in.integer("a vertex index");
      if (idx < 0 || idx >= nv) in.error(fmt::format("face {}: vertex index {} outside [0, {})", f, idx, nv));
      poly.push_back(static_cast<int>(idx));
    }
    if (n > 3) ++polygons;
    add_polygon(tris, poly);
  }
  MeshData d;
  d.V = to_positions(xyz);
  d.F = to_triangles(tris);
  if (polygons) d.warnings.push_back(polygon_warning(polygons, name));
  return d;
}

std::string write_obj(const MeshData& d) {
  std::string out = "# written by meshpde\n";
  out.reserve(static_cast<std::size_t>(40 * d.V.rows() + 30 * d.F.rows()));
  for (Eigen::Index i = 0; i < d.V.rows(); ++i) append_vertex(out, d.V(i, 0), d.V(i, 1), d.V(i, 2), "v ");
  for (Eigen::Index f = 0; f < d.F.rows(); ++f)
    fmt::format_to(std::back_inserter(out), "f {} {} {}\n", d.F(f, 0) + 1, d.F(f, 1) + 1, d.F(f, 2) + 1);
  return out;
}

std::string write_off(const MeshData& d) {
  std::string out = fmt::format("OFF\n{} {} 0\n", d.V.rows(), d.F.rows());
  for (Eigen::Index i = 0; i < d.V.rows(); ++i) append_vertex(out, d.V(i, 0), d.V(i, 1), d.V(i, 2), "");
  for (Eigen::Index f = 0; f < d.F.rows(); ++f)
    fmt::format_to(std::back_inserter(out), "3 {} {} {}\n", d.F(f, 0), d.F(f, 1), d.F(f, 2));
  return out;
}

}  // namespace meshpde::detail
