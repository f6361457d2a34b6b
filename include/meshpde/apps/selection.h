// Vertex selections, written the same way everywhere (CLI, bindings, server):
//
//   file:PATH               vertex indices in a text file (whitespace or commas, # comments)
//   rings:V:K               K rings of neighbours around vertex V
//   radius:V:R              edge-path distance < R from vertex V (mesh units)
//   halfspace:NX,NY,NZ:D    vertices with NX x + NY y + NZ z <= D
//   field:NAME<X  field:NAME>X   a threshold on a per-vertex field
//   boundary                vertices on boundary edges
//   all
//
// V is an index or @X,Y,Z (the vertex nearest to that point). Several selections
// are combined by union.
#pragma once

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/regions.h"

namespace meshpde {

using VertexFields = std::map<std::string, Eigen::VectorXd>;

/// Sorted, unique vertex indices. \throw InputError naming the selection and what is wrong.
std::vector<int> select_vertices(const Mesh& mesh, const std::string& spec, const VertexFields& fields = {});

/// Union of several selections.
std::vector<int> select_vertices(const Mesh& mesh, const std::vector<std::string>& specs,
                                 const VertexFields& fields = {});

/// The vertex indices of a `file:` selection's text: whitespace or commas between
/// them, `#` starts a comment; `name` (the file) is quoted in errors with the line.
/// \throw InputError for a token that is not a vertex of the mesh.
std::vector<int> parse_vertex_list(const Mesh& mesh, const std::string& text, const std::string& name);

/// A point "@X,Y,Z" farther than this many times the longest edge at its nearest vertex
/// from that vertex is warned about (core/warnings.h): a point on the surface lies
/// within an edge of its nearest vertex.
inline constexpr int kFarPointEdges = 3;

/// Vertex given as an index or @X,Y,Z (the vertex nearest the point; a point far from
/// it is warned about, see kFarPointEdges). \throw InputError
int parse_vertex_spec(const Mesh& mesh, const std::string& spec);

/// A point written "X,Y,Z" (three finite numbers). \throw InputError quoting the text.
Eigen::Vector3d parse_point_spec(const std::string& spec);

/// A brush written "V:RADIUS:VALUE" (V an index or @X,Y,Z; radius in mesh units), as
/// `--brush` and the editor take it. \throw InputError quoting the text.
Brush parse_brush(const Mesh& mesh, const std::string& text);

/// Vertices on boundary edges (edges with one incident triangle).
std::vector<int> boundary_vertices(const Mesh& mesh);

}  // namespace meshpde
