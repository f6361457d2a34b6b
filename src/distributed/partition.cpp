#include "meshpde/distributed/partition.h"

#include <fmt/format.h>
#include <petscmat.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <numeric>

#include "meshpde/core/errors.h"
#include "petsc_check.h"

namespace meshpde {

namespace {

constexpr auto check = detail::petsc_check;

// An id held in a double vertex field: an integer in [0, limit), exactly.
long long id_from(double x, long long limit, const std::string& file, const char* field, int v) {
  if (!(x >= 0) || !(x < static_cast<double>(limit)) || x != std::floor(x))
    throw InputError(fmt::format("{}: vertex {}: {} {} is not a vertex index of the whole mesh (0 to {})", file, v,
                                 field, x, limit - 1));
  return static_cast<long long>(x);
}

}  // namespace

std::vector<int> partition_vertices(const Mesh& mesh, int parts) {
  const int n = mesh.num_vertices();
  if (parts < 1) throw InputError(fmt::format("the number of parts must be at least 1 (got {})", parts));
  if (parts > n) throw InputError(fmt::format("{} parts for {} vertices: give at most one part a vertex", parts, n));
  if (parts == 1) return std::vector<int>(static_cast<std::size_t>(n), 0);
  PetscBool up = PETSC_FALSE;
  check(PetscInitialized(&up), "PetscInitialized");
  if (!up) check(PetscInitializeNoArguments(), "PetscInitialize");
  // The vertex adjacency graph, rows sorted and without the diagonal, in PETSc's
  // memory: MatCreateMPIAdj takes the arrays over.
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  PetscInt *ia = nullptr, *ja = nullptr;
  check(PetscMalloc1(n + 1, &ia), "PetscMalloc1");
  check(PetscMalloc1(std::max<PetscInt>(1, off[n]), &ja), "PetscMalloc1");
  PetscInt k = 0;
  ia[0] = 0;
  for (int v = 0; v < n; ++v) {
    const PetscInt begin = k;
    for (int q = off[v]; q < off[v + 1]; ++q)
      if (nbr[q] != v) ja[k++] = nbr[q];
    std::sort(ja + begin, ja + k);
    k = static_cast<PetscInt>(std::unique(ja + begin, ja + k) - ja);
    ia[v + 1] = k;
  }
  Mat adj = nullptr;
  MatPartitioning mp = nullptr;
  IS is = nullptr;
  std::vector<int> out(static_cast<std::size_t>(n));
  try {
    check(MatCreateMPIAdj(PETSC_COMM_SELF, n, n, ia, ja, nullptr, &adj), "MatCreateMPIAdj");
    check(MatPartitioningCreate(PETSC_COMM_SELF, &mp), "MatPartitioningCreate");
    check(MatPartitioningSetAdjacency(mp, adj), "MatPartitioningSetAdjacency");
    check(MatPartitioningSetNParts(mp, parts), "MatPartitioningSetNParts");
    check(MatPartitioningSetType(mp, MATPARTITIONINGPTSCOTCH), "MatPartitioningSetType(ptscotch)");
    check(MatPartitioningApply(mp, &is), "MatPartitioningApply");
    const PetscInt* idx = nullptr;
    check(ISGetIndices(is, &idx), "ISGetIndices");
    for (int v = 0; v < n; ++v) out[static_cast<std::size_t>(v)] = static_cast<int>(idx[v]);
    check(ISRestoreIndices(is, &idx), "ISRestoreIndices");
  } catch (...) {
    ISDestroy(&is);
    MatPartitioningDestroy(&mp);
    MatDestroy(&adj);
    throw;
  }
  ISDestroy(&is);
  MatPartitioningDestroy(&mp);
  MatDestroy(&adj);
  return out;
}

PartitionSummary write_partition(const MeshData& data, const std::vector<int>& part_of,
                                 const std::filesystem::path& dir, const std::string& source) {
  const Mesh mesh(data.V, data.F);
  const int n = mesh.num_vertices();
  if (static_cast<int>(part_of.size()) != n)
    throw InputError(fmt::format("a partition of {} entries for {} vertices", part_of.size(), n));
  const int parts = n ? *std::max_element(part_of.begin(), part_of.end()) + 1 : 0;
  if (parts < 1 || *std::min_element(part_of.begin(), part_of.end()) < 0)
    throw InputError("a partition's parts are numbered 0, 1, ...");
  // Global numbering: part by part, each in the input's order.
  std::vector<int> owned(static_cast<std::size_t>(parts), 0);
  for (int p : part_of) ++owned[static_cast<std::size_t>(p)];
  std::vector<long long> offsets(static_cast<std::size_t>(parts) + 1, 0);
  for (int p = 0; p < parts; ++p) offsets[p + 1] = offsets[p] + owned[p];
  std::vector<long long> global(static_cast<std::size_t>(n));
  {
    std::vector<long long> next(offsets.begin(), offsets.end() - 1);
    for (int v = 0; v < n; ++v) global[v] = next[static_cast<std::size_t>(part_of[v])]++;
  }
  PartitionSummary s;
  s.parts = parts;
  s.owned = owned;
  for (int v = 0; v < n; ++v)
    for (int w : mesh.neighbors(v))
      if (w > v && part_of[v] != part_of[w]) ++s.cut_edges;
  std::filesystem::create_directories(dir);
  nlohmann::json files = nlohmann::json::array();
  // Each part's vertices and triangles in one pass over the mesh (a triangle whose
  // corners lie in several parts goes to each), so that the cost does not grow with
  // the number of parts.
  std::vector<std::vector<int>> mine_of(static_cast<std::size_t>(parts)), tris_of(static_cast<std::size_t>(parts));
  for (int v = 0; v < n; ++v) mine_of[static_cast<std::size_t>(part_of[v])].push_back(v);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int a = part_of[mesh.triangles()(f, 0)], b = part_of[mesh.triangles()(f, 1)],
              c = part_of[mesh.triangles()(f, 2)];
    tris_of[static_cast<std::size_t>(a)].push_back(f);
    if (b != a) tris_of[static_cast<std::size_t>(b)].push_back(f);
    if (c != a && c != b) tris_of[static_cast<std::size_t>(c)].push_back(f);
  }
  std::vector<int> local_of(static_cast<std::size_t>(n), -1);  // reset after each part
  for (int p = 0; p < parts; ++p) {
    // p's vertices first, in global order, then the ghosts its triangles touch, in
    // global order.
    const std::vector<int>& tris = tris_of[static_cast<std::size_t>(p)];
    const std::vector<int>& mine = mine_of[static_cast<std::size_t>(p)];
    for (std::size_t k = 0; k < mine.size(); ++k) local_of[mine[k]] = static_cast<int>(k);
    std::vector<int> ghosts;
    for (int f : tris)
      for (int c = 0; c < 3; ++c)
        if (const int v = mesh.triangles()(f, c); local_of[v] < 0) {
          local_of[v] = 0;  // seen; numbered below
          ghosts.push_back(v);
        }
    std::sort(ghosts.begin(), ghosts.end(), [&](int a, int b) { return global[a] < global[b]; });
    const std::vector<int>* const lists[] = {&mine, &ghosts};
    MeshData out;
    out.V.resize(static_cast<Eigen::Index>(mine.size() + ghosts.size()), 3);
    Eigen::VectorXd gid(out.V.rows()), oid(out.V.rows());
    int k = 0;
    for (const std::vector<int>* list : lists)
      for (const int v : *list) {
        local_of[v] = k;
        out.V.row(k) = data.V.row(v);
        gid[k] = static_cast<double>(global[v]);
        oid[k] = v;
        ++k;
      }
    out.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (std::size_t t = 0; t < tris.size(); ++t)
      for (int c = 0; c < 3; ++c) out.F(static_cast<Eigen::Index>(t), c) = local_of[mesh.triangles()(tris[t], c)];
    out.vertex_scalars["global_id"] = gid;
    out.vertex_scalars["original_id"] = oid;
    const std::string name = fmt::format("part-{}.ply", p);
    write_mesh(dir / name, out);
    files.push_back(name);
    s.ghosts.push_back(static_cast<int>(ghosts.size()));
    s.faces.push_back(static_cast<int>(tris.size()));
    for (const std::vector<int>* list : lists)
      for (const int v : *list) local_of[v] = -1;
  }
  nlohmann::json index = {{"format", "meshpde-partition"},
                          {"version", 1},
                          {"parts", parts},
                          {"vertices", n},
                          {"faces", mesh.num_faces()},
                          {"source", source},
                          {"offsets", offsets},
                          {"files", files},
                          {"owned", s.owned},
                          {"ghosts", s.ghosts},
                          {"part_faces", s.faces},
                          {"cut_edges", s.cut_edges}};
  write_file_atomically(dir / "partition.json", index.dump(2) + "\n");
  return s;
}

PartitionIndex read_partition_index(const std::filesystem::path& dir) {
  const auto index_path = dir / "partition.json";
  if (!std::filesystem::is_regular_file(index_path))
    throw InputError(fmt::format("{}: cannot read the partition's index (is {} a folder `meshpde partition` wrote?)",
                                 index_path.string(), dir.string()));
  const std::string text = read_file(index_path);
  PartitionIndex x;
  try {
    const auto j = nlohmann::json::parse(text);
    if (j.value("format", "") != "meshpde-partition")
      throw InputError(fmt::format("{}: not a meshpde partition index (\"format\" is not \"meshpde-partition\")",
                                   index_path.string()));
    x.parts = j.at("parts").get<int>();
    x.global_vertices = j.at("vertices").get<long long>();
    x.offsets = j.at("offsets").get<std::vector<long long>>();
    x.files = j.at("files").get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: {}", index_path.string(), e.what()));
  }
  if (x.parts < 1 || static_cast<int>(x.offsets.size()) != x.parts + 1 || static_cast<int>(x.files.size()) != x.parts ||
      x.offsets.front() != 0 || x.offsets.back() != x.global_vertices ||
      !std::is_sorted(x.offsets.begin(), x.offsets.end()))
    throw InputError(fmt::format("{}: parts, offsets, files and vertices do not agree", index_path.string()));
  for (const auto& file : x.files)
    if (file.find('/') != std::string::npos || file.find("..") != std::string::npos)
      throw InputError(fmt::format("{}: part file \"{}\" is not a name in the folder", index_path.string(), file));
  return x;
}

MeshPart read_partition_part(const std::filesystem::path& dir, int part) {
  const PartitionIndex index = read_partition_index(dir);
  if (part < 0 || part >= index.parts)
    throw InputError(fmt::format("{}: the partition has {} parts, not a part {} (run as many processes as parts)",
                                 (dir / "partition.json").string(), index.parts, part));
  MeshPart m;
  m.parts = index.parts;
  m.global_vertices = index.global_vertices;
  m.offsets = index.offsets;
  const std::string& file = index.files[static_cast<std::size_t>(part)];
  m.part = part;
  m.first = m.offsets[static_cast<std::size_t>(part)];
  const long long owned = m.offsets[static_cast<std::size_t>(part) + 1] - m.first;
  const std::string path = (dir / file).string();
  MeshData d = read_mesh(dir / file);
  for (const char* field : {"global_id", "original_id"})
    if (!d.vertex_scalars.count(field))
      throw InputError(fmt::format("{}: no vertex property {} (write parts with `meshpde partition`)", path, field));
  const int nl = static_cast<int>(d.V.rows());
  if (owned > nl)
    throw InputError(fmt::format("{}: the index gives part {} {} vertices, the file holds {}", path, part, owned, nl));
  m.owned = static_cast<int>(owned);
  m.global_id.resize(static_cast<std::size_t>(nl));
  m.original_id.resize(static_cast<std::size_t>(nl));
  const auto& gid = d.vertex_scalars.at("global_id");
  const auto& oid = d.vertex_scalars.at("original_id");
  for (int v = 0; v < nl; ++v) {
    m.global_id[v] = id_from(gid[v], m.global_vertices, path, "global_id", v);
    m.original_id[v] = id_from(oid[v], m.global_vertices, path, "original_id", v);
    const bool mine = m.global_id[v] >= m.first && m.global_id[v] < m.first + owned;
    if (v < owned && m.global_id[v] != m.first + v)
      throw InputError(fmt::format("{}: vertex {} has global_id {}, the part's vertex {} should be {}", path, v,
                                   m.global_id[v], v, m.first + v));
    if (v >= owned && mine)
      throw InputError(
          fmt::format("{}: ghost vertex {} has global_id {}, which this part owns", path, v, m.global_id[v]));
  }
  m.mesh = Mesh(std::move(d.V), std::move(d.F));
  return m;
}

MeshData read_partitioned_mesh(const std::filesystem::path& dir) {
  MeshPart first = read_partition_part(dir, 0);
  const long long n = first.global_vertices;
  MeshData out;
  out.V.resize(static_cast<Eigen::Index>(n), 3);
  std::vector<char> seen(static_cast<std::size_t>(n), 0);
  std::vector<Eigen::Vector3i> tris;
  for (int p = 0; p < first.parts; ++p) {
    const MeshPart part = p == 0 ? std::move(first) : read_partition_part(dir, p);
    for (int v = 0; v < part.owned; ++v) {
      const long long o = part.original_id[static_cast<std::size_t>(v)];
      if (seen[static_cast<std::size_t>(o)])
        throw InputError(fmt::format("{}: part {}'s vertex {} has original_id {}, which an earlier part owns",
                                     dir.string(), p, v, o));
      seen[static_cast<std::size_t>(o)] = 1;
      out.V.row(static_cast<Eigen::Index>(o)) = part.mesh.positions().row(v);
    }
    const auto& F = part.mesh.triangles();
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (F(f, 0) < part.owned)
        tris.emplace_back(static_cast<int>(part.original_id[static_cast<std::size_t>(F(f, 0))]),
                          static_cast<int>(part.original_id[static_cast<std::size_t>(F(f, 1))]),
                          static_cast<int>(part.original_id[static_cast<std::size_t>(F(f, 2))]));
  }
  if (const auto gap = std::find(seen.begin(), seen.end(), 0); gap != seen.end())
    throw InputError(fmt::format("{}: no part owns the input's vertex {}", dir.string(), gap - seen.begin()));
  out.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t) out.F.row(static_cast<Eigen::Index>(t)) = tris[t].transpose();
  return out;
}

}  // namespace meshpde
