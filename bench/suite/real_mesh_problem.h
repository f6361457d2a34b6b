// The real-mesh problem of the global bi-Laplacian benchmarks (`meshpde bench`,
// global_bilap_*_<mesh>) and of the tests that check the global solver against the
// direct one on every mesh of the data folder (tests/solver_problems.h): one home, so
// that the figures and the tests are about the same problem.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <vector>

#include "meshpde/mesh/field.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/topology.h"

namespace meshpde::bench {

// The real-mesh problem of the global solves: the handle at the top moved by 0.01
// `edge` x (1, 2, 10), the lowest 2 % (by height) of each connected part held, and
// vertices that no triangle uses held too (bunny-36k has 1,113; a part with nothing
// held would float), every other vertex free. On a mesh of one part, as the three
// meshes of the first rows are, that is the lowest 2 % of the whole mesh.
struct TopDrag {
  int handle = 0;
  Field u;
  std::vector<int> free;
};
inline TopDrag top_drag(const Mesh& m, double edge) {
  TopDrag t;
  const int n = m.num_vertices();
  m.positions().col(2).maxCoeff(&t.handle);
  t.u = Field::Zero(n, 3);
  t.u.row(t.handle) = 0.01 * edge * Eigen::RowVector3d(1, 2, 10);
  int parts = 0;
  const std::vector<int> part = vertex_components(m, &parts);
  std::vector<double> z0(static_cast<std::size_t>(parts), 1e300), z1(static_cast<std::size_t>(parts), -1e300);
  std::vector<int> size(static_cast<std::size_t>(parts), 0);
  for (int v = 0; v < n; ++v) {
    const auto c = static_cast<std::size_t>(part[static_cast<std::size_t>(v)]);
    z0[c] = std::min(z0[c], m.positions()(v, 2));
    z1[c] = std::max(z1[c], m.positions()(v, 2));
    ++size[c];
  }
  for (int v = 0; v < n; ++v) {
    const auto c = static_cast<std::size_t>(part[static_cast<std::size_t>(v)]);
    if (v != t.handle && size[c] > 1 && m.positions()(v, 2) > z0[c] + 0.02 * (z1[c] - z0[c])) t.free.push_back(v);
  }
  return t;
}

}  // namespace meshpde::bench
