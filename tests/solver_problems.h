// Test problems shared by the solver test files (test_direct, test_global_bilaplacian,
// test_multigrid, test_ordering, test_regions, test_steady).
#pragma once

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "meshpde/core/parallel.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/steady_direct.h"
#include "suite/real_mesh_problem.h"
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
  g.ops = build_cotan_operators(g.mesh);
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
  s.ops = build_cotan_operators(s.mesh);
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

// The steady bi-Laplacian K^T D K u = 0 on `free`, the other vertices held at u, solved
// in long double (a 64-bit significand: 2^11 times double's precision) from the same K
// and masses: the product formed, the free block factored by Eigen's simplicial LDL^T
// and refined three times. An answer independent of the solvers under test, whose own
// rounding (about cond * 5e-20) stays below 1e-8 up to a condition number near 1e11.
inline Field extended_precision_solve(const Mesh& m, const FemOperators& ops, const std::vector<int>& free,
                                      const Field& u) {
  using Real = long double;
  using Sparse = Eigen::SparseMatrix<Real>;
  using Dense = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic>;
  const int n = m.num_vertices(), nf = static_cast<int>(free.size()), cols = static_cast<int>(u.cols());
  const Sparse K = stiffness_matrix(m, ops).cast<Real>();
  Eigen::Matrix<Real, Eigen::Dynamic, 1> D(n);
  for (int v = 0; v < n; ++v) D[v] = ops.mass[v] > 0 ? Real(1) / Real(ops.mass[v]) : Real(0);
  const Sparse A = Sparse(K.transpose() * D.asDiagonal()) * K;
  std::vector<int> local(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < nf; ++k) local[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])] = k;
  std::vector<Eigen::Triplet<Real>> entries;
  Dense b = Dense::Zero(nf, cols);
  for (int j = 0; j < A.outerSize(); ++j)
    for (Sparse::InnerIterator it(A, j); it; ++it) {
      const int i = local[static_cast<std::size_t>(it.row())], jl = local[static_cast<std::size_t>(j)];
      if (i < 0) continue;
      if (jl >= 0)
        entries.emplace_back(i, jl, it.value());
      else
        for (int c = 0; c < cols; ++c) b(i, c) -= it.value() * Real(u(j, c));
    }
  Sparse A_FF(nf, nf);
  A_FF.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SimplicialLDLT<Sparse> factor(A_FF);
  Dense x = factor.solve(b);
  for (int step = 0; step < 3; ++step) x += factor.solve(Dense(b - A_FF * x));
  Field out = u;
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < cols; ++c) out(free[static_cast<std::size_t>(k)], c) = static_cast<double>(x(k, c));
  return out;
}

// The global solver on a real mesh: the global solver's answer (Auto, and the Laplacian
// factor forced; relative residual 1e-12) equals the direct solve's to 1e-8 relative,
// on one thread and on two, and on meshes of up to 15k vertices both equal the
// extended-precision answer above to 1e-8. The operators are the ones the commands
// build (`--laplacian auto`: intrinsic Delaunay on badly shaped meshes), the problem is
// the bench's (bench/suite/real_mesh_problem.h: the top vertex moved, the lowest 2 % of
// each connected part held, unreferenced vertices held), and the multigrid stops
// coarsening at kTestCoarsest so that meshes of a few thousand vertices still iterate.
inline void expect_global_matches_direct(const std::string& name, const MeshData& d) {
  SCOPED_TRACE(name);
  const Mesh input(d.V, d.F);
  const MeshOperators mo = build_mesh_operators(input, LaplacianKind::Auto);
  const Mesh& m = mo.mesh;
  const int n = m.num_vertices();
  const auto [handle, u, free] = bench::top_drag(m, mean_edge_length(input));
  const SteadyDirectSolver direct(m, mo.ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  const Field x = direct.solve(u);
  const double scale = x.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0);
  const bool small = n <= 15000;
  const Field reference = small ? extended_precision_solve(m, mo.ops, free, u) : Field();
  if (small) {
    EXPECT_LE((x - reference).cwiseAbs().maxCoeff(), 1e-8 * scale)
        << "the direct solve is " << (x - reference).cwiseAbs().maxCoeff() / scale
        << " relative off the extended-precision one (condition estimate " << direct.conditioning().condition_1 << ")";
  }
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;
  for (const Preconditioner which : {Preconditioner::Auto, Preconditioner::LaplacianFactor}) {
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(std::string(which == Preconditioner::Auto ? "auto" : "laplacian factor") + ", " +
                   std::to_string(threads) + " thread(s)");
      GlobalBilaplacianParams p{.g1 = 0, .g2 = 1, .tolerance = 1e-12, .max_iterations = 3000};
      p.preconditioner = which;
      p.multigrid.coarsest_unknowns = kTestCoarsest;
      const int limit = max_threads();
      set_max_threads(threads);
      const GlobalBilaplacianResult r = solve_global_bilaplacian(m, mo.ops, free, u, p);
      set_max_threads(limit);
      ASSERT_TRUE(r.converged) << r.iterations << " iterations, residual " << r.relative_residual;
      EXPECT_LE((r.values - x).cwiseAbs().maxCoeff(), 1e-8 * scale)
          << (r.values - x).cwiseAbs().maxCoeff() / scale << " relative off the direct solve, " << r.iterations
          << " iterations";
      if (small) {
        EXPECT_LE((r.values - reference).cwiseAbs().maxCoeff(), 1e-8 * scale)
            << (r.values - reference).cwiseAbs().maxCoeff() / scale << " relative off the extended-precision solve";
      }
    }
  }
}

}  // namespace meshpde::test
