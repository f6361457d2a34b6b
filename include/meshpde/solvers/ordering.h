// Fill-reducing orderings for the Cholesky factors of operators on a mesh region,
// computed from the mesh (positions and adjacency), never from an assembled matrix.
//
// mesh_nested_dissection() is the ordering of whole-mesh and large solves
// (SteadyDirectSolver uses it for K D K from kMeshOrderingFrom free vertices): the
// vertex set is grouped into patches of about 16 vertices (breadth-first), METIS finds
// a vertex separator of the graph of patches, the separating patches' vertices join
// the nearer side, and the vertices the operator couples across (one layer for K; two
// for K D K, with the couplings through held vertices and separators above) are the
// separator; each side is dissected the same way, parts of at most 64 vertices are
// ordered by AMD. METIS works on a sixteenth of the vertices, which is why this costs a
// tenth of CHOLMOD's analysis of K D K; the factor has 1.0-1.26x the fill of CHOLMOD's
// order on the meshes measured (docs/solvers-measurements.md).
//
// nested_dissection_order() bisects the region by planes through the median vertex
// along the longest side of its bounding box, takes out the vertices that couple the
// two halves (the separator), orders each half the same way (recursively) and the
// separator last. It reads positions and adjacency only, no matrix: a drag region's
// order is known before its matrix is assembled, and the matrix is assembled once, in
// that order. On the bench's 10k-vertex disc of K D K it gives a factor with 5 % less
// fill and 23 % fewer flops than AMD and costs about 2 ms, where AMD on the assembled
// matrix costs 4 ms and METIS (through CHOLMOD) 50 ms (docs/solvers-measurements.md).
//
// Separators: row i of K couples i with its neighbours; row i of K D K couples i with
// every vertex two edges away (through any vertex, held or free). A separator must cut
// every such coupling between the halves, so it is one layer of vertices for K
// (separator_hops = 1: the vertices of one half with a neighbour in the other) and two
// for K D K (separator_hops = 2: the vertices of both halves with a neighbour across).
#pragma once

#include <vector>

#include "meshpde/mesh/mesh.h"

namespace meshpde {

struct NestedDissectionParams {
  /// How far apart (in edges) two vertices coupled by one matrix row can be: 1 for K
  /// and M (the Laplacian, mass), 2 for K D K and g1 K + g2 K D K.
  int separator_hops = 2;
  /// Parts of at most this many vertices are not split further; they keep the order
  /// given. On the 10k-vertex disc: factor nonzeros 900k with 16, 903k with 32, 953k
  /// with 64, 1,037k with 128; 32 makes fewer, larger supernodes than 16.
  int leaf_size = 32;
};

/// A permutation of `vertices` (mesh vertex ids, distinct) in nested dissection order:
/// out[k] is the vertex eliminated k-th. \throw InputError for a vertex that does not
/// exist, a repeated vertex, separator_hops not 1 or 2, or leaf_size < 1.
std::vector<int> nested_dissection_order(const Mesh& mesh, const std::vector<int>& vertices,
                                         const NestedDissectionParams& params = {});

/// The same order with its top level: order is part 1 (parts[0] vertices), then part 2
/// (parts[1]), then their separator, and no matrix row couples the two parts (what
/// SplitCholesky needs). parts = {#vertices, 0} when the region was not split (at most
/// leaf_size vertices, or no cut splits it).
struct NestedDissection {
  std::vector<int> order;
  std::size_t parts[2] = {0, 0};
};
NestedDissection nested_dissection(const Mesh& mesh, const std::vector<int>& vertices,
                                   const NestedDissectionParams& params = {});

struct MeshOrderingParams {
  /// As NestedDissectionParams: 1 for K and M, 2 for K D K and g1 K + g2 K D K.
  int separator_hops = 2;
  /// Vertices per patch of the graph the separators are found on. Smaller patches
  /// place separators more finely and cost more; 16 gave the least fill of 8, 16, 24
  /// and 32 on fertility-4k subdivided three times.
  int patch_size = 16;
  /// Parts of at most this many vertices are ordered by AMD on their own couplings.
  int leaf_size = 64;
};

/// A permutation of `vertices` (mesh vertex ids, distinct) in nested dissection order,
/// out[k] eliminated k-th. The same input gives the same order on any number of threads
/// (the two top-level halves are ordered on two threads). Without METIS in the build
/// (mesh_ordering_available() false) this is nested_dissection_order() by planes.
/// \throw InputError for a vertex that does not exist, a repeated vertex,
///        separator_hops not 1 or 2, or a size below 1.
std::vector<int> mesh_nested_dissection_order(const Mesh& mesh, const std::vector<int>& vertices,
                                              const MeshOrderingParams& params = {});
/// The same order with its top level (as nested_dissection): part 1, part 2, their
/// separator, no matrix row coupling the parts (what SparseCholesky's split factor needs).
NestedDissection mesh_nested_dissection(const Mesh& mesh, const std::vector<int>& vertices,
                                        const MeshOrderingParams& params = {});
/// Whether meshpde was built with METIS (libmetis-dev), which mesh_nested_dissection_order uses.
bool mesh_ordering_available();

/// An order of `vertices` made from `previous`, an elimination order of another vertex
/// set of the same mesh (a factor's: SteadyDirectSolver::vertex_order()), for a free
/// set that changed by a few vertices: the vertices in both keep previous's relative
/// order, and those new to it are eliminated last, with the top-level separator.
/// Dropping a vertex from an elimination order never adds fill, and a vertex eliminated
/// last adds at most a row across the separators above its neighbours, so the order of
/// the rest is reused at the cost of a pass over the vertices instead of a new ordering
/// (numbers: docs/solvers-measurements.md). The top level's parts keep their vertices
/// still in the set (parts = {#vertices, 0}, not split, when previous was not or one of
/// them empties): whether two vertices are coupled does not depend on which others are
/// free, so the parts stay uncoupled. `changed` (optional) gets the number of vertices
/// added plus dropped. \throw InputError for a vertex outside 0..num_vertices-1 or
/// repeated, in either list.
NestedDissection reuse_ordering(const NestedDissection& previous, const std::vector<int>& vertices, int num_vertices,
                                int* changed = nullptr);

}  // namespace meshpde
