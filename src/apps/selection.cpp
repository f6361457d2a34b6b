#include "meshpde/apps/selection.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "meshpde/core/errors.h"
#include "meshpde/core/warnings.h"
#include "meshpde/io/text_records.h"

namespace meshpde {

namespace {

double parse_number(const std::string& s, const std::string& spec) {
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || !std::isfinite(x))
    throw InputError(fmt::format("selection '{}': '{}' is not a number", spec, s));
  return x;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

}  // namespace

std::vector<int> parse_vertex_list(const Mesh& mesh, const std::string& text, const std::string& name) {
  std::vector<int> out;
  for_each_text_record(text, FieldSeparator::CommaOrSpace, [&](int line, const std::vector<std::string>& fields) {
    for (const std::string& f : fields) {
      try {
        out.push_back(parse_vertex_spec(mesh, f));
      } catch (const InputError& e) {
        throw InputError(fmt::format("{}: line {}: {}", name, line, e.what()));
      }
    }
  });
  return out;
}

Eigen::Vector3d parse_point_spec(const std::string& spec) {
  const auto parts = split(spec, ',');
  if (parts.size() != 3) throw InputError(fmt::format("point '{}': 'X,Y,Z' needs three numbers", spec));
  return {parse_number(parts[0], spec), parse_number(parts[1], spec), parse_number(parts[2], spec)};
}

int parse_vertex_spec(const Mesh& mesh, const std::string& spec) {
  if (!spec.empty() && spec[0] == '@') {
    const auto parts = split(spec.substr(1), ',');
    if (parts.size() != 3) throw InputError(fmt::format("vertex '{}': '@X,Y,Z' needs three numbers", spec));
    const Eigen::Vector3d p(parse_number(parts[0], spec), parse_number(parts[1], spec), parse_number(parts[2], spec));
    int v = 0;
    const double distance =
        std::sqrt((mesh.positions().rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&v));
    // A point on the surface lies within an edge of its nearest vertex; one much farther
    // off was probably typed in another frame (LPS against RAS) or unit.
    double longest = 0;
    for (const int w : mesh.neighbors(v))
      longest = std::max(longest, (mesh.positions().row(w) - mesh.positions().row(v)).norm());
    if (distance > kFarPointEdges * longest)
      warn(
          fmt::format("vertex '{}': the point lies {:.3g} from its nearest vertex {} (more than {} times the longest "
                      "edge there, {:.3g}, in the mesh's units): is it in the mesh's frame and unit?",
                      spec, distance, v, kFarPointEdges, longest));
    return v;
  }
  const double x = parse_number(spec, spec);
  if (x != std::floor(x) || x < 0 || x >= mesh.num_vertices())
    throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", spec, mesh.num_vertices()));
  return static_cast<int>(x);
}

std::vector<int> boundary_vertices(const Mesh& mesh) {
  std::vector<int> count(mesh.num_edges(), 0);
  const auto& F = mesh.triangles();
  for (int f = 0; f < mesh.num_faces(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int a = F(f, c), b = F(f, (c + 1) % 3);
      if (a != b) ++count[mesh.edge_ids()[mesh.find_slot(a, b)]];
    }
  std::vector<int> out;
  for (int e = 0; e < mesh.num_edges(); ++e)
    if (count[e] == 1) {
      out.push_back(mesh.edges()(e, 0));
      out.push_back(mesh.edges()(e, 1));
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<int> select_vertices(const Mesh& mesh, const std::string& spec, const VertexFields& fields) {
  const auto colon = spec.find(':');
  const std::string kind = spec.substr(0, colon);
  const std::string rest = colon == std::string::npos ? "" : spec.substr(colon + 1);
  std::vector<int> out;
  const auto& V = mesh.positions();
  if (kind == "all") {
    for (int v = 0; v < mesh.num_vertices(); ++v) out.push_back(v);
  } else if (kind == "boundary") {
    out = boundary_vertices(mesh);
  } else if (kind == "file") {
    std::ifstream in(rest, std::ios::binary);
    if (!in) throw InputError(fmt::format("selection '{}': cannot open {}", spec, rest));
    std::stringstream text;
    text << in.rdbuf();
    out = parse_vertex_list(mesh, text.str(), rest);
  } else if (kind == "rings" || kind == "radius") {
    const auto last = rest.rfind(':');
    if (last == std::string::npos)
      throw InputError(fmt::format("selection '{}' must be {}:VERTEX:{}", spec, kind, kind == "rings" ? "K" : "R"));
    const int v = parse_vertex_spec(mesh, rest.substr(0, last));
    const double x = parse_number(rest.substr(last + 1), spec);
    if (kind == "rings") {
      if (x < 0 || x != std::floor(x))
        throw InputError(fmt::format("selection '{}': rings must be a whole number", spec));
      // More rings than vertices reach no further: clamped, so a huge count is no overflow.
      out = ring_ball(mesh, v, static_cast<int>(std::min(x, static_cast<double>(mesh.num_vertices()))));
    } else {
      if (!(x > 0)) throw InputError(fmt::format("selection '{}': the radius must be positive", spec));
      out = geodesic_ball(mesh, v, x);
    }
  } else if (kind == "halfspace") {
    const auto last = rest.rfind(':');
    const auto n = split(rest.substr(0, last), ',');
    if (last == std::string::npos || n.size() != 3)
      throw InputError(fmt::format("selection '{}' must be halfspace:NX,NY,NZ:D", spec));
    const Eigen::Vector3d normal(parse_number(n[0], spec), parse_number(n[1], spec), parse_number(n[2], spec));
    const double d = parse_number(rest.substr(last + 1), spec);
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (V.row(v).dot(normal) <= d) out.push_back(v);
  } else if (kind == "field") {
    const auto op = rest.find_first_of("<>");
    if (op == std::string::npos)
      throw InputError(fmt::format("selection '{}' must be field:NAME<X or field:NAME>X", spec));
    const std::string name = rest.substr(0, op);
    const auto it = fields.find(name);
    if (it == fields.end()) throw InputError(fmt::format("selection '{}': no vertex field '{}'", spec, name));
    const double x = parse_number(rest.substr(op + 1), spec);
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (rest[op] == '<' ? it->second[v] < x : it->second[v] > x) out.push_back(v);
  } else {
    throw InputError(
        fmt::format("unknown selection '{}' (use file:, rings:, radius:, halfspace:, field:, "
                    "boundary or all)",
                    spec));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<int> select_vertices(const Mesh& mesh, const std::vector<std::string>& specs, const VertexFields& fields) {
  std::vector<int> out;
  for (const auto& s : specs) {
    const auto part = select_vertices(mesh, s, fields);
    out.insert(out.end(), part.begin(), part.end());
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

Brush parse_brush(const Mesh& mesh, const std::string& text) {
  const auto last = text.rfind(':');
  const auto mid = last == std::string::npos || last == 0 ? std::string::npos : text.rfind(':', last - 1);
  if (mid == std::string::npos) throw InputError(fmt::format("brush '{}' must be V:RADIUS:VALUE", text));
  Brush b;
  b.vertex = parse_vertex_spec(mesh, text.substr(0, mid));
  try {
    std::size_t used = 0;
    const std::string r = text.substr(mid + 1, last - mid - 1), v = text.substr(last + 1);
    b.radius = std::stod(r, &used);
    if (used != r.size()) throw std::invalid_argument(r);
    b.value = std::stod(v, &used);
    if (used != v.size()) throw std::invalid_argument(v);
  } catch (const std::exception&) {
    throw InputError(fmt::format("brush '{}': radius and value must be numbers", text));
  }
  if (!(b.radius > 0) || !(b.value > 0))
    throw InputError(fmt::format("brush '{}': radius and value must be > 0", text));
  return b;
}

}  // namespace meshpde
