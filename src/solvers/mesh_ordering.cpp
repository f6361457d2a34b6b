// mesh_nested_dissection_order (solvers/ordering.h): nested dissection of a vertex set
// whose separators are found on a coarse graph of patches and placed on the vertices.
// The only translation unit that includes METIS; built with it when METIS and CHOLMOD
// (for AMD) are found, else the planes of nested_dissection stand in.
#include <fmt/format.h>

#include <algorithm>
#include <mutex>
#include <vector>

#include "dissection_recursion.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/solvers/ordering.h"

#ifdef MESHPDE_HAVE_METIS
#include <amd.h>
#include <metis.h>
#endif

namespace meshpde {

#ifdef MESHPDE_HAVE_METIS

bool mesh_ordering_available() {
  return true;
}

namespace {

// From this many vertices in the two top-level halves they are ordered on two threads.
constexpr std::size_t kParallelHalves = 20000;

// METIS keeps its random state in process-wide variables: calls are serialized, and
// each starts from the same seed, so that the order depends on the input alone (not
// on which thread asked first).
std::mutex metis_mutex;
constexpr idx_t kMetisSeed = 7;

// Which patches the operator couples: two patches are neighbours when a vertex of one
// is within separator_hops edges of a vertex of the other, through any mesh vertex
// (held ones too: K D K couples two free vertices through a held neighbour).
struct PatchGraph {
  std::vector<int> offsets, neighbors;
};

PatchGraph patch_graph_of(const Mesh& mesh, const std::vector<int>& vertices, const std::vector<int>& patch,
                          int patches, int hops) {
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  // Vertices grouped by patch (a counting sort), then each patch's neighbours once.
  std::vector<int> first(static_cast<std::size_t>(patches) + 1, 0), members(vertices.size());
  for (int v : vertices) ++first[static_cast<std::size_t>(patch[static_cast<std::size_t>(v)]) + 1];
  for (int a = 0; a < patches; ++a) first[static_cast<std::size_t>(a) + 1] += first[static_cast<std::size_t>(a)];
  {
    std::vector<int> fill(first.begin(), first.end() - 1);
    for (int v : vertices)
      members[static_cast<std::size_t>(fill[static_cast<std::size_t>(patch[static_cast<std::size_t>(v)])]++)] = v;
  }
  PatchGraph g;
  g.offsets.assign(1, 0);
  std::vector<int> mark(static_cast<std::size_t>(patches), -1);
  for (int a = 0; a < patches; ++a) {
    auto join = [&](int w) {
      const int b = patch[static_cast<std::size_t>(w)];
      if (b >= 0 && b != a && mark[static_cast<std::size_t>(b)] != a) {
        mark[static_cast<std::size_t>(b)] = a;
        g.neighbors.push_back(b);
      }
    };
    for (int q = first[static_cast<std::size_t>(a)]; q < first[static_cast<std::size_t>(a) + 1]; ++q) {
      const int v = members[static_cast<std::size_t>(q)];
      for (int k = off[v]; k < off[v + 1]; ++k) {
        join(nbr[k]);
        if (hops == 2)
          for (int r = off[nbr[k]]; r < off[nbr[k] + 1]; ++r) join(nbr[r]);
      }
    }
    g.offsets.push_back(static_cast<int>(g.neighbors.size()));
  }
  return g;
}

struct PatchDissection {
  const Mesh& mesh;
  const MeshOrderingParams& params;
  const std::vector<int>& patch;  // patch of each mesh vertex; negative outside the ordered set
  const PatchGraph& patch_graph;
  std::vector<int> out;
  // Scratch, per mesh vertex: 0 outside the part at hand; 1, 2 the side; 3 in the part,
  // side not yet known. Per patch: its index in the part's quotient graph, or -1.
  std::vector<unsigned char> side;
  std::vector<int> local;
  std::vector<int> where;                // per mesh vertex: index in a leaf, or -1
  std::vector<unsigned char> near_flag;  // per mesh vertex: near the band of a split

  PatchDissection(const Mesh& m, const MeshOrderingParams& p, const std::vector<int>& patch_of, const PatchGraph& graph)
      : mesh(m),
        params(p),
        patch(patch_of),
        patch_graph(graph),
        side(static_cast<std::size_t>(m.num_vertices()), 0),
        local(graph.offsets.size() - 1, -1),
        where(static_cast<std::size_t>(m.num_vertices()), -1),
        near_flag(static_cast<std::size_t>(m.num_vertices()), 0) {}

  // AMD on the couplings among the part's vertices (two vertices are coupled when they
  // are at most separator_hops edges apart, through any vertex).
  void leaf(const std::vector<int>& part) {
    const int n = static_cast<int>(part.size());
    if (n <= 2) {
      out.insert(out.end(), part.begin(), part.end());
      return;
    }
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    for (int k = 0; k < n; ++k) where[static_cast<std::size_t>(part[static_cast<std::size_t>(k)])] = k;
    std::vector<int> Ap{0}, Ai, seen(static_cast<std::size_t>(n), -1);
    for (int k = 0; k < n; ++k) {
      const int v = part[static_cast<std::size_t>(k)];
      auto add = [&](int w) {
        const int j = where[static_cast<std::size_t>(w)];
        if (j >= 0 && j != k && seen[static_cast<std::size_t>(j)] != k) {
          seen[static_cast<std::size_t>(j)] = k;
          Ai.push_back(j);
        }
      };
      for (int a = off[v]; a < off[v + 1]; ++a) {
        add(nbr[a]);
        if (params.separator_hops == 2)
          for (int b = off[nbr[a]]; b < off[nbr[a] + 1]; ++b) add(nbr[b]);
      }
      Ap.push_back(static_cast<int>(Ai.size()));
    }
    for (int v : part) where[static_cast<std::size_t>(v)] = -1;
    std::vector<int> P(static_cast<std::size_t>(n));
    double control[AMD_CONTROL], info[AMD_INFO];
    amd_defaults(control);
    if (amd_order(n, Ap.data(), Ai.data(), P.data(), control, info) < AMD_OK) {
      out.insert(out.end(), part.begin(), part.end());  // out of memory: the order given
      return;
    }
    for (int p : P) out.push_back(part[static_cast<std::size_t>(p)]);
  }

  // Splits `part` in two sides and a separator; false when it does not split.
  bool split(const std::vector<int>& part, std::vector<int>& lower, std::vector<int>& upper,
             std::vector<int>& separator) {
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    const bool two_hops = params.separator_hops == 2;
    auto side_of = [&](int v) -> unsigned char& { return side[static_cast<std::size_t>(v)]; };
    auto patch_of = [&](int v) { return local[static_cast<std::size_t>(patch[static_cast<std::size_t>(v)])]; };
    // The quotient graph: one node per patch with vertices in the part.
    std::vector<int> patches;
    for (int v : part) {
      int& l = local[static_cast<std::size_t>(patch[static_cast<std::size_t>(v)])];
      if (l < 0) {
        l = static_cast<int>(patches.size());
        patches.push_back(patch[static_cast<std::size_t>(v)]);
      }
      side_of(v) = 3;
    }
    const auto np = static_cast<idx_t>(patches.size());
    bool split_found = false;
    if (np >= 3) {
      // The coupling graph of the patches (built once for the whole set), restricted
      // to the part's patches, weighted by their vertices in the part.
      std::vector<idx_t> xadj{0}, adjncy, weight(static_cast<std::size_t>(np), 0);
      for (int v : part) ++weight[static_cast<std::size_t>(patch_of(v))];
      for (idx_t a = 0; a < np; ++a) {
        const int global = patches[static_cast<std::size_t>(a)];
        for (int q = patch_graph.offsets[static_cast<std::size_t>(global)];
             q < patch_graph.offsets[static_cast<std::size_t>(global) + 1]; ++q) {
          const int b = local[static_cast<std::size_t>(patch_graph.neighbors[static_cast<std::size_t>(q)])];
          if (b >= 0) adjncy.push_back(b);
        }
        xadj.push_back(static_cast<idx_t>(adjncy.size()));
      }
      // METIS's vertex separator of the quotient graph: two sets of patches (labels 0,
      // 1) and the band of patches between them (2).
      std::vector<idx_t> label(static_cast<std::size_t>(np), 0);
      idx_t nvtx = np, separator_weight = 0;
      idx_t options[METIS_NOPTIONS];
      METIS_SetDefaultOptions(options);
      options[METIS_OPTION_NUMBERING] = 0;
      options[METIS_OPTION_SEED] = kMetisSeed;
      int status = METIS_OK;
      {
        const std::lock_guard<std::mutex> lock(metis_mutex);
        status = METIS_ComputeVertexSeparator(&nvtx, xadj.data(), adjncy.data(), weight.data(), options,
                                              &separator_weight, label.data());
      }
      if (status == METIS_OK) {
        std::vector<int> band;
        for (int v : part) {
          const idx_t l = label[static_cast<std::size_t>(patch_of(v))];
          if (l == 2)
            band.push_back(v);
          else
            side_of(v) = static_cast<unsigned char>(1 + l);
        }
        // The sides meet only in and next to the band (no two patches of different
        // sides are coupled), so the work below visits the band and four rings around
        // it (`near`), not the part: the breadth-first search crosses the band, each
        // smoothing pass moves the meeting line by at most a ring, and the separator
        // reaches two rings from it.
        std::vector<int> near = band, frontier, next;
        for (int v : band) near_flag[static_cast<std::size_t>(v)] = 1;
        for (std::size_t begin = 0, ring = 0; ring < 4; ++ring) {
          const std::size_t end = near.size();
          for (std::size_t q = begin; q < end; ++q)
            for (int k = off[near[q]]; k < off[near[q] + 1]; ++k) {
              const int w = nbr[k];
              if (side_of(w) != 0 && !near_flag[static_cast<std::size_t>(w)]) {
                near_flag[static_cast<std::size_t>(w)] = 1;
                near.push_back(w);
              }
            }
          begin = end;
        }
        // Each band vertex joins the side it is nearer to (in edges, a breadth-first
        // search from both sides at once), so that the cut runs through the middle of
        // the band.
        for (int v : near)
          if (side_of(v) == 1 || side_of(v) == 2)
            for (int k = off[v]; k < off[v + 1]; ++k)
              if (side_of(nbr[k]) == 3) {
                frontier.push_back(v);
                break;
              }
        while (!frontier.empty()) {
          next.clear();
          for (int v : frontier)
            for (int k = off[v]; k < off[v + 1]; ++k)
              if (side_of(nbr[k]) == 3) {
                side_of(nbr[k]) = side_of(v);
                next.push_back(nbr[k]);
              }
          frontier.swap(next);
        }
        for (int v : band)
          if (side_of(v) == 3) side_of(v) = 1;  // reached by neither side
        // The band's middle is jagged at the scale of a patch: a vertex with more
        // neighbours across than on its own side changes sides (two passes; more
        // changed nothing on armadillo-43k, and these took its fill from 1.39x
        // METIS's to 1.21x).
        for (int pass = 0; pass < 2; ++pass) {
          int flips = 0;
          for (int v : near) {
            const unsigned char me = side_of(v);
            int same = 0, other = 0;
            for (int k = off[v]; k < off[v + 1]; ++k) {
              const unsigned char s = side_of(nbr[k]);
              same += s == me;
              other += s == 3 - me;
            }
            if (other > same) {
              side_of(v) = static_cast<unsigned char>(3 - me);
              ++flips;
            }
          }
          if (!flips) break;
        }
        // The separator: the vertices with a neighbour across, from one side for one
        // hop (K: the side whose boundary is shorter), from both sides for two (K D K).
        // For two hops a vertex of side 1 also joins when a vertex outside the part
        // is next to it and to side 2: K D K couples them through that vertex.
        unsigned char from = 1;
        if (!two_hops) {
          std::size_t boundary[3] = {0, 0, 0};
          for (int v : near) {
            const unsigned char me = side_of(v);
            for (int k = off[v]; k < off[v + 1]; ++k)
              if (side_of(nbr[k]) == 3 - me) {
                ++boundary[me];
                break;
              }
          }
          if (boundary[2] < boundary[1]) from = 2;
        }
        for (int v : part) {
          const unsigned char me = side_of(v);
          bool across = false;
          if (near_flag[static_cast<std::size_t>(v)] && (me == from || two_hops))
            for (int k = off[v]; k < off[v + 1] && !across; ++k) {
              const int w = nbr[k];
              const unsigned char s = side_of(w);
              across = (s == 1 || s == 2) && s != me;
              if (s == 0 && me == 1 && two_hops)
                for (int q = off[w]; q < off[w + 1] && !across; ++q) across = side_of(nbr[q]) == 2;
            }
          (across ? separator : me == 1 ? lower : upper).push_back(v);
        }
        for (int v : near) near_flag[static_cast<std::size_t>(v)] = 0;
        split_found = !lower.empty() && !upper.empty();
      }
    }
    for (int p : patches) local[static_cast<std::size_t>(p)] = -1;
    for (int v : part) side_of(v) = 0;
    return split_found;
  }

  PatchDissection sibling() const { return PatchDissection(mesh, params, patch, patch_graph); }
};

}  // namespace

NestedDissection mesh_nested_dissection(const Mesh& mesh, const std::vector<int>& vertices,
                                        const MeshOrderingParams& params) {
  detail::check_dissection_input(mesh, vertices, params.separator_hops, params.leaf_size, "mesh ordering");
  if (params.patch_size < 1)
    throw InputError(fmt::format("mesh ordering: patch_size is {}; it must be at least 1", params.patch_size));
  std::vector<int> patch(static_cast<std::size_t>(mesh.num_vertices()), -2);  // -2 outside the set, -1 in no patch yet
  for (int v : vertices) patch[static_cast<std::size_t>(v)] = -1;
  // Patches: breadth-first from each vertex not yet taken (in the order given) until
  // patch_size vertices, through the set's own vertices.
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  int patches = 0;
  std::vector<int> queue;
  for (int s : vertices) {
    if (patch[static_cast<std::size_t>(s)] != -1) continue;
    queue.assign(1, s);
    patch[static_cast<std::size_t>(s)] = patches;
    for (std::size_t h = 0; h < queue.size() && static_cast<int>(queue.size()) < params.patch_size; ++h)
      for (int k = off[queue[h]]; k < off[queue[h] + 1] && static_cast<int>(queue.size()) < params.patch_size; ++k)
        if (patch[static_cast<std::size_t>(nbr[k])] == -1) {
          patch[static_cast<std::size_t>(nbr[k])] = patches;
          queue.push_back(nbr[k]);
        }
    ++patches;
  }
  const PatchGraph graph = patch_graph_of(mesh, vertices, patch, patches, params.separator_hops);
  PatchDissection d(mesh, params, patch, graph);
  return detail::dissect_all(d, vertices, params.leaf_size, kParallelHalves);
}

#else  // without METIS

bool mesh_ordering_available() {
  return false;
}

NestedDissection mesh_nested_dissection(const Mesh& mesh, const std::vector<int>& vertices,
                                        const MeshOrderingParams& params) {
  if (params.patch_size < 1)
    throw InputError(fmt::format("mesh ordering: patch_size is {}; it must be at least 1", params.patch_size));
  return nested_dissection(mesh, vertices, {params.separator_hops, std::max(params.leaf_size, 1)});
}

#endif

std::vector<int> mesh_nested_dissection_order(const Mesh& mesh, const std::vector<int>& vertices,
                                              const MeshOrderingParams& params) {
  return mesh_nested_dissection(mesh, vertices, params).order;
}

}  // namespace meshpde
