// A PolyData as read from a .vtp or .vtk file, turned into a triangle mesh.
#include "polydata.h"

#include <fmt/format.h>

#include <array>
#include <cmath>

#include "meshpde/core/errors.h"

namespace meshpde::detail {
namespace {

Eigen::MatrixXd rows_of(const NamedArray& a, const std::vector<std::size_t>& rows) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), a.components);
  const auto nc = static_cast<std::size_t>(a.components);
  for (std::size_t r = 0; r < rows.size(); ++r)
    for (std::size_t c = 0; c < nc; ++c)
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = a.values[rows[r] * nc + c];
  return m;
}

}  // namespace

std::string detect_space(std::string_view text) {
  if (text.find("SPACE=LPS") != std::string_view::npos) return "LPS";
  if (text.find("SPACE=RAS") != std::string_view::npos) return "RAS";
  return {};
}

std::vector<std::int64_t> integer_ids(const std::vector<double>& v, const std::string& what) {
  std::vector<std::int64_t> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!(v[i] >= -9.0e18 && v[i] <= 9.0e18) || v[i] != std::floor(v[i]))
      throw InputError(fmt::format("{}: value {} ({}) is not an integer id", what, i, v[i]));
    out[i] = static_cast<std::int64_t>(v[i]);
  }
  return out;
}

MeshData mesh_from_polydata(PolyData&& pd, const std::string& name) {
  MeshData d;
  d.space = pd.space;
  d.points_type = pd.points_type;
  for (const auto& [key, value] : pd.field_strings) d.field_strings[key] = value;
  for (const NamedArray& a : pd.field_arrays) {
    Eigen::MatrixXd m(static_cast<Eigen::Index>(a.tuples()), a.components);
    for (std::size_t t = 0; t < a.tuples(); ++t)
      for (int c = 0; c < a.components; ++c)
        m(static_cast<Eigen::Index>(t), c) = a.values[t * static_cast<std::size_t>(a.components) + c];
    d.field_arrays[a.name] = DataArray{m, a.type};
  }
  d.warnings = std::move(pd.warnings);
  const std::size_t np = pd.point_count();
  if (np == 0) throw InputError(fmt::format("{}: contains no points", name));
  d.V.resize(static_cast<Eigen::Index>(np), 3);
  for (std::size_t i = 0; i < np; ++i) {
    const double* p = &pd.points[3 * i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw InputError(fmt::format("{}: point {} has a non-finite coordinate", name, i));
    d.V.row(static_cast<Eigen::Index>(i)) << p[0], p[1], p[2];
  }

  // Cell data are numbered verts, lines, polys, strips (VTK's PolyData order).
  const std::size_t first_poly = pd.verts.size() + pd.lines.size();
  const std::size_t first_strip = first_poly + pd.polys.size();
  const std::size_t cells = first_strip + pd.strips.size();
  std::vector<std::array<int, 3>> tris;
  std::vector<std::size_t> source_cell;
  long long polygons = 0;
  auto id = [&](std::size_t cell, std::int64_t v) {
    if (v < 0 || static_cast<std::uint64_t>(v) >= np)
      throw InputError(fmt::format("{}: cell {} refers to point {} (the file has {} points)", name, cell, v, np));
    return static_cast<int>(v);
  };
  for (std::size_t c = 0; c < pd.polys.size(); ++c) {
    const std::int64_t* p = pd.polys.connectivity.data() + pd.polys.offsets[c];
    const std::int64_t n = pd.polys.offsets[c + 1] - pd.polys.offsets[c];
    const std::size_t cell = first_poly + c;
    if (n < 3) throw InputError(fmt::format("{}: polygon {} has {} corners", name, cell, n));
    if (n > 3) ++polygons;
    for (std::int64_t k = 1; k + 1 < n; ++k) {
      tris.push_back({id(cell, p[0]), id(cell, p[k]), id(cell, p[k + 1])});
      source_cell.push_back(cell);
    }
  }
  for (std::size_t c = 0; c < pd.strips.size(); ++c) {
    const std::int64_t* p = pd.strips.connectivity.data() + pd.strips.offsets[c];
    const std::int64_t n = pd.strips.offsets[c + 1] - pd.strips.offsets[c];
    const std::size_t cell = first_strip + c;
    for (std::int64_t k = 0; k + 2 < n; ++k) {
      // Every other triangle of a strip is reversed to keep one orientation.
      if (k % 2 == 0)
        tris.push_back({id(cell, p[k]), id(cell, p[k + 1]), id(cell, p[k + 2])});
      else
        tris.push_back({id(cell, p[k + 1]), id(cell, p[k]), id(cell, p[k + 2])});
      source_cell.push_back(cell);
    }
  }
  if (tris.empty())
    throw InputError(fmt::format("{}: contains no polygons ({} vertex and {} line cells; a surface is needed)", name,
                                 pd.verts.size(), pd.lines.size()));
  d.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    d.F.row(static_cast<Eigen::Index>(t)) << tris[t][0], tris[t][1], tris[t][2];
  if (polygons)
    d.warnings.push_back(fmt::format("{}: triangulated {} polygons with more than three corners{}", name, polygons,
                                     pd.cell_arrays.empty() ? "" : " (their cell data repeated per triangle)"));
  if (pd.strips.size() > 0)
    d.warnings.push_back(fmt::format("{}: unrolled {} triangle strips", name, pd.strips.size()));
  if (first_poly > 0)
    d.warnings.push_back(
        fmt::format("{}: ignored {} vertex and {} line cells", name, pd.verts.size(), pd.lines.size()));

  std::vector<std::size_t> all_points(np);
  for (std::size_t i = 0; i < np; ++i) all_points[i] = i;
  for (const NamedArray& a : pd.point_arrays) {
    if (a.tuples() != np || a.values.size() != np * static_cast<std::size_t>(a.components))
      throw InputError(fmt::format("{}: point array '{}' has {} values for {} points of {} components", name, a.name,
                                   a.values.size(), np, a.components));
    const Eigen::MatrixXd values = rows_of(a, all_points);
    if (values.cols() == 1) {
      d.vertex_scalars[a.name] = values.col(0);
      d.scalar_types[a.name] = a.type;
    } else if (values.cols() == 3) {
      const char* suffix[3] = {"_x", "_y", "_z"};
      for (int c = 0; c < 3; ++c) {
        d.vertex_scalars[a.name + suffix[c]] = values.col(c);
        d.scalar_types[a.name + suffix[c]] = a.type;
      }
    } else {
      d.point_arrays[a.name] = DataArray{values, a.type};
    }
  }
  for (const NamedArray& a : pd.cell_arrays) {
    if (a.tuples() != cells || a.values.size() != cells * static_cast<std::size_t>(a.components))
      throw InputError(fmt::format("{}: cell array '{}' has {} values for {} cells of {} components", name, a.name,
                                   a.values.size(), cells, a.components));
    d.cell_arrays[a.name] = DataArray{rows_of(a, source_cell), a.type};
  }
  return d;
}

}  // namespace meshpde::detail
