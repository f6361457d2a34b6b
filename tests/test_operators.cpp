// K against an independent construction, identities, scale invariance, degenerate
// geometry, weights and the bi-Laplacian.
#include <gtest/gtest.h>

#include <Eigen/SparseCore>
#include <random>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/cotan_laplacian.h"
#include "meshpde/operators/fem_operators.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;
using test::make;

namespace {

/// max |K + L| / max |L| with L from an independent cotangent formula.
double k_vs_cotan(const Mesh& m, CotanFormula formula = CotanFormula::Angles) {
  const FemOperators ops = build_cotan_operators(m);
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
  const Eigen::SparseMatrix<double> L = cotan_laplacian(m, formula);
  const Eigen::SparseMatrix<double> diff = K + L;
  double dmax = 0, lmax = 0;
  for (int k = 0; k < diff.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(diff, k); it; ++it) dmax = std::max(dmax, std::abs(it.value()));
  for (int k = 0; k < L.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, k); it; ++it) lmax = std::max(lmax, std::abs(it.value()));
  return dmax / lmax;
}

void check_identities(const Mesh& m, const std::string& name, double intrinsic_tol = 1e-12) {
  SCOPED_TRACE(name);
  EXPECT_LE(k_vs_cotan(m), 1e-12);
  EXPECT_LE(k_vs_cotan(m, CotanFormula::EdgeLengths), intrinsic_tol);
  const FemOperators ops = build_cotan_operators(m);
  // K 1 = 0 (relative to the diagonal's scale).
  const Field ones = Field::Ones(m.num_vertices(), 1);
  EXPECT_LE(apply_stiffness(m, ops, ones).cwiseAbs().maxCoeff(), 1e-12 * ops.Kii.cwiseAbs().maxCoeff());
  // Symmetric: the value of slot (i, j) equals that of (j, i).
  for (int i = 0; i < m.num_vertices(); ++i)
    for (int s = m.offsets()[i]; s < m.offsets()[i + 1]; ++s)
      ASSERT_EQ(ops.Kij[s], ops.Kij[m.find_slot(m.neighbors()[s], i)]);
  // D M = I where the area is positive; the mass sums to the surface area.
  for (int i = 0; i < m.num_vertices(); ++i)
    if (ops.mass[i] > 0) {
      ASSERT_NEAR(ops.D(i) * ops.mass[i], 1.0, 1e-15);
    }
  EXPECT_NEAR(ops.mass.sum(), analyze(m).area, 1e-12 * analyze(m).area);
  EXPECT_TRUE(ops.Kii.allFinite() && ops.Kij.allFinite() && ops.mass.allFinite());
}

}  // namespace

TEST(Operators, ElementMatrixMatchesHandComputedRightTriangle) {
  // Right isosceles triangle: cot(45) = 1, cot(90) = 0 -> K_01 = K_02 = -1/2, K_12 = 0.
  Positions V(3, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  Triangles F(1, 3);
  F << 0, 1, 2;
  const Mesh m(V, F);
  const FemOperators ops = build_cotan_operators(m);
  EXPECT_NEAR(ops.Kii[0], 1.0, 1e-15);
  EXPECT_NEAR(ops.Kii[1], 0.5, 1e-15);
  EXPECT_NEAR(ops.Kij[m.find_slot(0, 1)], -0.5, 1e-15);
  EXPECT_NEAR(ops.Kij[m.find_slot(1, 2)], 0.0, 1e-15);
  EXPECT_NEAR(ops.mass[0], 0.5 / 3, 1e-15);
}

TEST(Operators, IdentitiesOnGeneratedMeshes) {
  check_identities(make(icosphere(3)), "icosphere");
  check_identities(make(latlong_sphere(15, 100)), "latlong");
  check_identities(make(geodesic_sphere(BaseSolid::Tetrahedron, 10, 5)), "tetra");
  check_identities(make(tube(1, 4, 9, 16)), "tube");
  check_identities(make(plane_grid(7, 5)), "plane");
  check_identities(make(fins(4, 5)), "fins");
  check_identities(make(y_bifurcation(BifurcationParams{.cell = 1.0})), "bifurcation");
}

TEST(Operators, IdentitiesOnRealMeshes) {
  for (const char* name : {"bunny-3k.off", "cow-3k.off", "camelhead-11k.off", "fertility-4k.off",
                           "decimated-knight.off", "aorta-open-6k.stl", "coronary-phantom-7k.stl", "bunny-36k.obj",
                           "nonmanifold-vierbein.obj", "nonmanifold-vertex-hourglass.obj"}) {
    Mesh m;
    if (!test::load_data(name, m)) continue;  // (every missing file reported)
    // The intrinsic formula is ill-conditioned on marching-cubes slivers (see cotan_laplacian.h).
    check_identities(m, name, 1e-9);
  }
}

TEST(Operators, ScaleInvarianceAt1e8And1em8) {
  GeneratedMesh g = icosphere(3);
  const FemOperators base = build_cotan_operators(make(g));
  for (const double s : {1e8, 1e-8}) {
    GeneratedMesh h = g;
    h.V *= s;
    const Mesh m = make(h);
    check_identities(m, "scaled");
    const FemOperators ops = build_cotan_operators(m);
    // K is dimensionless: unchanged by scaling. M scales with s^2.
    EXPECT_LE((ops.Kij - base.Kij).cwiseAbs().maxCoeff(), 1e-12 * base.Kij.cwiseAbs().maxCoeff());
    EXPECT_LE((ops.mass / (s * s) - base.mass).cwiseAbs().maxCoeff(), 1e-12 * base.mass.maxCoeff());
  }
}

TEST(Operators, LinearPrecisionOnAPerturbedPlane) {
  const GeneratedMesh g = test::jittered_plane(10, 0.02, 7);
  const Mesh m = make(g);
  const FemOperators ops = build_cotan_operators(m);
  Field u(m.num_vertices(), 1);
  for (int i = 0; i < m.num_vertices(); ++i) u(i, 0) = 2 * g.V(i, 0) - 3 * g.V(i, 1) + 1;
  const Field Ku = apply_stiffness(m, ops, u);
  for (int i = 0; i < m.num_vertices(); ++i)
    if (g.V(i, 0) > 1e-9 && g.V(i, 0) < 1 - 1e-9 && g.V(i, 1) > 1e-9 && g.V(i, 1) < 1 - 1e-9) {
      EXPECT_NEAR(Ku(i, 0), 0.0, 1e-12);
    }
}

TEST(Operators, BilaplacianMatchesAssembledLMinvL) {
  const Mesh m = make(icosphere(3));
  const FemOperators ops = build_cotan_operators(m);
  const Eigen::SparseMatrix<double> L = cotan_laplacian(m);
  Eigen::SparseMatrix<double> Minv(m.num_vertices(), m.num_vertices());
  for (int i = 0; i < m.num_vertices(); ++i) Minv.insert(i, i) = 1.0 / ops.mass[i];
  const Eigen::SparseMatrix<double> B = L * Minv * L;  // libigl harmonic(k=2) builds the same
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  Field u(m.num_vertices(), 3);
  for (Eigen::Index k = 0; k < u.size(); ++k) u.data()[k] = n01(rng);
  const Field a = apply_bilaplacian(m, ops, u);
  const Eigen::MatrixXd b = B * Eigen::MatrixXd(u);
  EXPECT_LE((Eigen::MatrixXd(a) - b).cwiseAbs().maxCoeff(), 1e-10 * b.cwiseAbs().maxCoeff());
  // The fused scalar kernel agrees with the assembled matrix too.
  std::vector<double> t(m.num_vertices()), y(m.num_vertices());
  const Eigen::VectorXd u0 = u.col(0);
  apply_bilaplacian_scalar(m, ops, u0.data(), t.data(), y.data());
  const Eigen::VectorXd b0 = B * u0;
  for (int i = 0; i < m.num_vertices(); ++i) {
    EXPECT_NEAR(y[i], b0[i], 1e-10 * b0.cwiseAbs().maxCoeff());
  }
  for (int i = 0; i < m.num_vertices(); ++i)
    EXPECT_NEAR(bilaplacian_diagonal(m, ops, i), B.coeff(i, i), 1e-10 * B.coeff(i, i));
}

TEST(Operators, DegenerateGeometryNeverGivesNaN) {
  // Good triangle, a zero-area (collinear) triangle, a repeated-index triangle,
  // two coincident vertices and an unreferenced vertex.
  Positions V(7, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0, 3, 0, 0, 1, 0, 0, 9, 9, 9;
  Triangles F(4, 3);
  F << 0, 1, 2, 1, 3, 4, 2, 2, 0, 5, 3, 1;
  const Mesh m(V, F);
  const FemOperators ops = build_cotan_operators(m);
  EXPECT_EQ(ops.degenerate_faces, 3);
  EXPECT_TRUE(ops.Kii.allFinite() && ops.Kij.allFinite() && ops.mass.allFinite());
  EXPECT_EQ(ops.mass[3], 0.0);
  EXPECT_EQ(ops.D(3), 0.0);
  EXPECT_EQ(ops.mass[6], 0.0);
  EXPECT_EQ(ops.zero_area_vertices, 4);  // 3, 4, 5 (coincident with 1) and 6
  const Field u = Field::Random(7, 3);
  EXPECT_TRUE(apply_bilaplacian(m, ops, u).allFinite());
}

TEST(Operators, FaceWeightsScaleTheElementStiffness) {
  const Mesh m = make(icosphere(2));
  const FemOperators base = build_cotan_operators(m);
  const FemOperators twice =
      build_cotan_operators(m, OperatorOptions{.face_weights = Eigen::VectorXd::Constant(m.num_faces(), 2.0)});
  EXPECT_LE((twice.Kij - 2 * base.Kij).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_EQ(twice.mass, base.mass);  // weights affect stiffness only
  // A per-vertex stiffness field averaged onto triangles.
  const Eigen::VectorXd field = Eigen::VectorXd::Constant(m.num_vertices(), 3.0);
  const FemOperators three = build_cotan_operators(m, {.face_weights = vertex_to_face_average(m, field)});
  EXPECT_LE((three.Kii - 3 * base.Kii).cwiseAbs().maxCoeff(), 1e-13);
  EXPECT_THROW(build_cotan_operators(m, {.face_weights = Eigen::VectorXd::Constant(3, 1.0)}), InputError);
  EXPECT_THROW(build_cotan_operators(m, {.face_weights = Eigen::VectorXd::Constant(m.num_faces(), -1.0)}), InputError);
}

#include "meshpde/core/parallel.h"

TEST(Operators, ParallelAppliesEqualTheSerialOnesExactly) {
  if (!openmp_available()) GTEST_SKIP() << "built without OpenMP: the applies run on one thread only";
  // Above the 20k-row threshold the applies split rows across threads; every row is
  // computed the same way, so one and two threads must agree bit for bit.
  const GeneratedMesh g = icosphere(6);  // 40,962 vertices
  const Mesh mesh(g.V, g.F);
  const FemOperators ops = build_cotan_operators(mesh);
  const int n = mesh.num_vertices();
  Field U(n, 3);
  for (int i = 0; i < n; ++i) U.row(i) << std::sin(0.01 * i), std::cos(0.02 * i), mesh.positions()(i, 2);
  std::vector<double> u(static_cast<std::size_t>(n)), t(u.size()), y1(u.size()), y2(u.size());
  for (int i = 0; i < n; ++i) u[static_cast<std::size_t>(i)] = U(i, 0);
  const int limit = max_threads();
  set_max_threads(1);
  const Field K1 = apply_stiffness(mesh, ops, U), B1 = apply_bilaplacian(mesh, ops, U);
  apply_bilaplacian_scalar(mesh, ops, u.data(), t.data(), y1.data());
  set_max_threads(2);
  EXPECT_EQ(max_threads(), 2);
  const Field K2 = apply_stiffness(mesh, ops, U), B2 = apply_bilaplacian(mesh, ops, U);
  apply_bilaplacian_scalar(mesh, ops, u.data(), t.data(), y2.data());
  set_max_threads(limit);
  EXPECT_EQ((K1 - K2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((B1 - B2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(y1, y2);
  EXPECT_GT(B1.cwiseAbs().maxCoeff(), 0.0);
  // The scalar K D K apply is the same operator as the field one.
  for (int i = 0; i < n; i += 97)
    EXPECT_NEAR(y1[static_cast<std::size_t>(i)], B1(i, 0), 1e-9 * B1.cwiseAbs().maxCoeff());
  set_max_threads(0);
  EXPECT_GE(max_threads(), 1);
  set_max_threads(limit);
}
