// A mesh cut into parts for a distributed run (target meshpde::distributed): each part
// a file of its own, so that no process of the run reads the whole mesh.
//
// The partitioned folder (written by `meshpde partition MESH --parts N -o DIR`):
//   DIR/partition.json  {"format": "meshpde-partition", "version": 1, "parts": N,
//                        "vertices": n, "faces": m, "source": "MESH",
//                        "offsets": [0, n_0, n_0 + n_1, ..., n],  (part p owns global
//                        vertices offsets[p] .. offsets[p+1]-1)
//                        "files": ["part-0.ply", ...], "ghosts": [...], "part_faces": [...]}
//   DIR/part-P.ply      the part's vertices, the ones it owns first (in global order),
//                       then its ghosts (vertices of other parts that its triangles
//                       touch), and every triangle with a corner it owns; vertex
//                       properties `global_id` (the run's numbering) and `original_id`
//                       (the input mesh's vertex index).
// The global numbering is the input's, reordered so that each part's vertices are
// contiguous; results are written back in the input's numbering.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/mesh.h"

namespace meshpde {

/// Which part each vertex of `mesh` goes to (#V entries in [0, parts)): PT-Scotch's
/// partition of the vertex adjacency graph, through PETSc's MatPartitioning, balanced
/// in vertex count with few cut edges. parts = 1 puts every vertex in part 0.
/// Initializes PETSc (and MPI) in this process when it is not yet.
/// \throw InputError for parts < 1 or more parts than vertices; SolverError if PETSc fails.
std::vector<int> partition_vertices(const Mesh& mesh, int parts);

/// What write_partition wrote: counts for the report.
struct PartitionSummary {
  int parts = 0;
  std::vector<int> owned;   ///< vertices each part owns
  std::vector<int> ghosts;  ///< ghost vertices each part holds
  std::vector<int> faces;   ///< triangles in each part (a triangle across parts is in each)
  int cut_edges = 0;        ///< edges between vertices of different parts
};

/// Writes `data` cut by `part_of` (one entry a vertex) into `dir` (created; files
/// written atomically, partition.json last). `source` is recorded as the input's name.
/// \throw InputError for a bad part_of; Error if a file cannot be written.
PartitionSummary write_partition(const MeshData& data, const std::vector<int>& part_of,
                                 const std::filesystem::path& dir, const std::string& source);

/// A partitioned folder's index (DIR/partition.json), checked for agreement.
struct PartitionIndex {
  int parts = 0;
  long long global_vertices = 0;
  std::vector<long long> offsets;  ///< parts + 1 entries
  std::vector<std::string> files;  ///< each part's file, a name in the folder
};

/// Reads and checks DIR/partition.json. \throw InputError naming it.
PartitionIndex read_partition_index(const std::filesystem::path& dir);

/// One part as a process of a distributed run reads it.
struct MeshPart {
  int part = 0, parts = 0;
  long long global_vertices = 0;       ///< n of the whole mesh
  long long first = 0;                 ///< global id of the first owned vertex
  int owned = 0;                       ///< vertices 0 .. owned-1 of `mesh` are this part's
  Mesh mesh;                           ///< owned vertices, then ghosts; local numbering
  std::vector<long long> global_id;    ///< local vertex -> global id
  std::vector<long long> original_id;  ///< local vertex -> the input mesh's index
  std::vector<long long> offsets;      ///< parts + 1 entries: part p owns [offsets[p], offsets[p+1])
};

/// Reads part `part` of the partitioned folder `dir` and checks it against the index:
/// its owned vertices are the range the index gives it, its ghosts belong to other
/// parts and its ids are in range.
/// \throw InputError naming the file and what is wrong.
MeshPart read_partition_part(const std::filesystem::path& dir, int part);

/// The whole mesh again from the parts of `dir`, in the input's vertex numbering (each
/// part's `original_id`), each triangle once (kept by the part that owns its first
/// corner), grouped by part: the input's triangles, perhaps in another order. One
/// process reads every part: the inverse of write_partition, for joining a run's
/// results into one mesh.
/// \throw InputError naming the part file when a part is unreadable or the parts
/// disagree (a vertex owned twice or by none).
MeshData read_partitioned_mesh(const std::filesystem::path& dir);

}  // namespace meshpde
