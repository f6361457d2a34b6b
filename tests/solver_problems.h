// Test problems shared by the solver test files (test_direct, test_global_bilaplacian,
// test_multigrid, test_ordering, test_regions, test_steady).
#pragma once

#include <random>
#include <vector>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "test_support.h"

namespace meshpde::test {

// Two separate icospheres of the given level, the second 5 units along x: vertices
// 0 .. n-1 and n .. 2n-1. With vertex 0 held, the second floats.
inline Mesh two_spheres(int level) {
  const GeneratedMesh a = icosphere(level);
  const auto n = a.V.rows();
  Positions V(2 * n, 3);
  V << a.V, (a.V.rowwise() + Eigen::RowVector3d(5, 0, 0));
  Triangles F(2 * a.F.rows(), 3);
  F << a.F, (a.F.array() + static_cast<int>(n)).matrix();
  return Mesh(V, F);
}

// The global solvers' test problem on an icosphere: the top vertex moved, the far cap
// below z = -0.95 held at zero, everything else free.
struct GlobalProblem {
  Mesh mesh;
  FemOperators ops;
  Field u;
  std::vector<int> free;
};

inline GlobalProblem global_problem(int level) {
  GlobalProblem g{make(icosphere(level)), {}, {}, {}};
  g.ops = build_operators(g.mesh);
  int handle = 0;
  g.mesh.positions().col(2).maxCoeff(&handle);
  g.u = Field::Zero(g.mesh.num_vertices(), 3);
  g.u.row(handle) << 0.01, 0.02, 0.1;
  for (int v = 0; v < g.mesh.num_vertices(); ++v)
    if (v != handle && g.mesh.positions()(v, 2) > -0.95) g.free.push_back(v);
  return g;
}

// The same problem on an icosphere stretched 8x along x: long thin triangles, on which
// the multigrid's coarse spaces are weak.
inline GlobalProblem stretched_global_problem(int level) {
  const GlobalProblem g = global_problem(level);
  Positions X = g.mesh.positions();
  X.col(0) *= 8;
  GlobalProblem s{Mesh(X, g.mesh.triangles()), {}, g.u, g.free};
  s.ops = build_operators(s.mesh);
  return s;
}

// The multigrid tests stop coarsening at 2,000 unknowns instead of the default (12,000
// with CHOLMOD, where a mesh of up to 12k vertices is one factor and needs no coarse
// level): their meshes of 2.5k-41k vertices still get three to five levels.
inline constexpr int kTestCoarsest = 2000;

// The parameters these tests solve global_problem with (g1 0.1, g2 1, relative residual
// 1e-10), with the given preconditioner.
inline GlobalBilaplacianParams global_params(GlobalBilaplacianParams::Preconditioner preconditioner) {
  GlobalBilaplacianParams p{.g1 = 0.1, .g2 = 1, .tolerance = 1e-10};
  p.preconditioner = preconditioner;
  p.multigrid.coarsest_unknowns = kTestCoarsest;
  return p;
}

// A drag region of about 3k vertices on the 41k icosphere, in the order the geodesic
// ball finds them.
inline std::vector<int> ordering_region(const Mesh& mesh) {
  int top = 0;
  mesh.positions().col(2).maxCoeff(&top);
  return geodesic_ball(mesh, top, 0.6);
}

// An icosphere with every vertex moved radially by up to 10 % (seeded): irregular
// triangles, and no two edge paths of exactly the same length.
inline Mesh bumpy_sphere(int level) {
  GeneratedMesh g = icosphere(level);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> scale(0.9, 1.1);
  for (Eigen::Index i = 0; i < g.V.rows(); ++i) g.V.row(i) *= scale(rng);
  return make(g);
}

}  // namespace meshpde::test
