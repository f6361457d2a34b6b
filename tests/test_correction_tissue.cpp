// Tissue: stiffness, mass, elasticity and viscosity, as scalars and per vertex, static
// and dynamic.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "correction_support.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "meshpde/operators/fem_operators.h"
#include "test_support.h"

using namespace meshpde;
using namespace meshpde::test;

namespace {

// Bands of other tissue across the tube near z = 30: heavier above, softer at the
// handle's height, more viscous below; the thesis's defaults elsewhere.
TissueParams banded_tissue(const Mesh& m) {
  const int nv = m.num_vertices();
  TissueParams t;
  t.mass_field = Eigen::VectorXd::Constant(nv, 0.1);
  t.elasticity_field = Eigen::VectorXd::Constant(nv, 0.9);
  t.viscosity_field = Eigen::VectorXd::Constant(nv, 0.6);
  for (int i = 0; i < nv; ++i) {
    const double z = m.positions()(i, 2);
    if (z > 31 && z < 34) t.mass_field[i] = 0.8;
    if (z > 29 && z < 31.5) t.elasticity_field[i] = 0.3;
    if (z > 25 && z < 29) t.viscosity_field[i] = 1.0;
  }
  return t;
}

}  // namespace

TEST(Vessel, StifferTissueDeformsLess) {
  // A stiff patch between the handle and the border bends less: the displacement
  // varies less across it than with uniform tissue.
  const Mesh m = tube_at(64);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 0}, 12.0);
  const std::vector<int> patch = patch_near(m, {5, 0, 36}, 2.5);
  const double uniform = spread(correct_vessel(m, p), patch);
  p.stiffness = Eigen::VectorXd::Ones(m.num_vertices());
  for (int i : patch) p.stiffness[i] = 20;
  const double stiff = spread(correct_vessel(m, p), patch);
  EXPECT_LT(stiff, 0.5 * uniform);
  p.stiffness[0] = -1;
  EXPECT_THROW(correct_vessel(m, p), InputError);
}

TEST(Vessel, DynamicCorrectionSettlesToTheStaticOne) {
  const Mesh m = tube_at(48);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 1}, 10.0);
  const CorrectionResult still = correct_vessel(m, p);
  p.dynamic = true;
  p.steps = 300;
  const CorrectionResult settled = correct_vessel(m, p);
  const double scale = still.displacement.norm();
  EXPECT_LT((settled.displacement - still.displacement).norm(), 1e-3 * scale);
  p.steps = 1;  // a moment after the drag: the tissue has not caught up
  EXPECT_GT((correct_vessel(m, p).displacement - still.displacement).norm(), 0.2 * scale);
  // After 40 steps (10 / omega) critically damped tissue has settled; barely damped
  // tissue is still ringing.
  p.steps = 40;
  p.tissue.viscosity = 1.0;
  const double critical = (correct_vessel(m, p).displacement - still.displacement).norm();
  p.tissue.viscosity = 0.05;
  const double ringing = (correct_vessel(m, p).displacement - still.displacement).norm();
  EXPECT_LT(critical, 1e-2 * scale);
  EXPECT_GT(ringing, 10 * critical);
}

TEST(Vessel, ConstantTissueFieldsGiveExactlyTheScalarsResult) {
  const Mesh m = tube_at(48);
  const int a = nearest_vertex(m, {5, 0, 30}), nv = m.num_vertices();
  for (const CorrectionMethod method : {CorrectionMethod::Fem, CorrectionMethod::Springs})
    for (const bool dynamic : {false, true}) {
      if (method == CorrectionMethod::Springs && dynamic) continue;
      CorrectionParams p;
      p.handles = {{a, {-1, 0, 0.5}}};
      p.method = method;
      p.dynamic = dynamic;
      p.steps = 12;
      p.g1 = 0.2;
      if (method == CorrectionMethod::Springs)
        p.rings = 4;
      else
        p.radius = 8;
      p.tissue.mass = 0.3;
      p.tissue.elasticity = 0.5;
      p.tissue.viscosity = 0.8;
      CorrectionParams q = p;
      q.tissue.mass_field = Eigen::VectorXd::Constant(nv, 0.3);
      q.tissue.elasticity_field = Eigen::VectorXd::Constant(nv, 0.5);
      q.tissue.viscosity_field = Eigen::VectorXd::Constant(nv, 0.8);
      q.tissue.mass = q.tissue.elasticity = q.tissue.viscosity = 0;  // unused once the fields are given
      SCOPED_TRACE(fmt::format("method {} dynamic {}", static_cast<int>(method), dynamic));
      const CorrectionResult r = correct_vessel(m, p), s = correct_vessel(m, q);
      EXPECT_EQ(r.displacement, s.displacement);
      EXPECT_GT(r.max_displacement, 0);
    }
}

TEST(Vessel, AnElasticityFieldWeighsTheStaticSolveAsTheStiffnessFieldDoes) {
  // The model: elasticity e_i relative to its largest value multiplies the stiffness,
  // static or dynamic. So a patch twenty times more elastic than the tissue around it
  // bends less (as in StifferTissueDeformsLess): the displacement varies less across it.
  const Mesh m = tube_at(64);
  CorrectionParams p = drag_to(m, {5, 0, 30}, {-2, 0, 0}, 12.0);
  p.g1 = 0.2;
  const TissueParams t = banded_tissue(m);
  CorrectionParams banded = p, weighted = p;
  banded.tissue.elasticity_field = t.elasticity_field;
  weighted.stiffness = t.elasticity_field / t.elasticity_field.maxCoeff();
  EXPECT_LT((correct_vessel(m, banded).displacement - correct_vessel(m, weighted).displacement).cwiseAbs().maxCoeff(),
            1e-12);

  const std::vector<int> patch = patch_near(m, {5, 0, 36}, 2.5);
  CorrectionParams elastic = p;
  elastic.tissue.elasticity_field = Eigen::VectorXd::Constant(m.num_vertices(), 0.045);
  for (int i : patch) elastic.tissue.elasticity_field[i] = 0.9;
  EXPECT_LT(spread(correct_vessel(m, elastic), patch), 0.5 * spread(correct_vessel(m, p), patch));
}

TEST(Vessel, PerVertexTissueEntersTheDynamicsAsTheModelSays) {
  // Three successive states d_{N-2}, d_{N-1}, d_N of a dynamic correction through the
  // bands (runs of N-2, N-1 and N steps) satisfy, at every free vertex i, the model's
  // backward-Euler step, built here from the weighted stiffness of the whole tube:
  //   alpha_i M_i (d_N - 2 d_{N-1} + d_{N-2}) / dt^2 + b_i M_i (d_N - d_{N-1}) / dt
  //     + e_max (g2 K_w D K_w + g1 K_w) d_N = 0,
  // alpha_i = mass_i, k_i = e_i s, b_i = 2 viscosity_i sqrt(alpha_i k_i), w_i = e_i / e_max,
  // s = g2 (pi/L)^4 + g1 (pi/L)^2 (L the radius), dt = 1 / (4 sqrt(e_max s / min alpha)).
  const Mesh m = tube_at(48);
  const int a = nearest_vertex(m, {5, 0, 30}), nv = m.num_vertices();
  CorrectionParams p;
  p.handles = {{a, {-1, 0, 0.5}}};
  p.radius = 8;
  p.boundary = RegionBoundary::Clamp;  // the held handle and free set the construction below repeats
  p.g1 = 0.2;
  p.dynamic = true;
  p.tissue = banded_tissue(m);
  const int N = 9;
  std::vector<CorrectionResult> r;
  for (int steps : {N - 2, N - 1, N}) {
    p.steps = steps;
    r.push_back(correct_vessel(m, p));
  }
  const TissueParams& t = p.tissue;
  const double e_max = t.elasticity_field.maxCoeff();
  OperatorOptions o;
  o.face_weights = vertex_to_face_average(m, t.elasticity_field / e_max);
  const FemOperators ops = build_cotan_operators(m, o);
  const Eigen::SparseMatrix<double> K = stiffness_matrix(m, ops);
  const Eigen::VectorXd D = ops.mass.cwiseInverse();
  const double s = p.g2 * std::pow(M_PI / p.radius, 4) + p.g1 * std::pow(M_PI / p.radius, 2);
  std::vector<int> free;
  for (int v : r[2].region)
    if (v != a) free.push_back(v);
  double alpha_min = 1;
  for (int v : free) alpha_min = std::min(alpha_min, t.mass_field[v]);
  const double dt = 0.25 / std::sqrt(e_max * s / alpha_min);
  const Field& d0 = r[0].displacement;
  const Field& d1 = r[1].displacement;
  const Field& d2 = r[2].displacement;
  const Field elastic = e_max * (p.g2 * (K * (D.asDiagonal() * (K * d2))) + p.g1 * (K * d2));
  double worst = 0, scale = 0;
  for (int i : free) {
    const double alpha = t.mass_field[i];
    const double b = 2 * t.viscosity_field[i] * std::sqrt(alpha * t.elasticity_field[i] * s);
    const Eigen::RowVector3d inertia = alpha * ops.mass[i] * (d2.row(i) - 2 * d1.row(i) + d0.row(i)) / (dt * dt);
    const Eigen::RowVector3d damping = b * ops.mass[i] * (d2.row(i) - d1.row(i)) / dt;
    worst = std::max(worst, (inertia + damping + elastic.row(i)).norm());
    scale = std::max({scale, inertia.norm(), damping.norm(), elastic.row(i).norm()});
  }
  EXPECT_GT(scale, 0);
  EXPECT_LT(worst, 1e-8 * scale) << "worst residual " << worst << " of terms up to " << scale;
  // And the heavier band has not caught up yet: it lags the light tissue's run.
  CorrectionParams light = p;
  light.tissue.mass_field = Eigen::VectorXd::Constant(nv, 0.1);
  const CorrectionResult lr = correct_vessel(m, light);
  const CorrectionParams settled = [&] {
    CorrectionParams q = p;
    q.dynamic = false;
    return q;
  }();
  const Field target = correct_vessel(m, settled).displacement;
  double lag = 0, lag_light = 0;
  for (int i = 0; i < nv; ++i) {
    const double z = m.positions()(i, 2);
    if (!(z > 31 && z < 34)) continue;
    lag += (d2.row(i) - target.row(i)).norm();
    lag_light += (lr.displacement.row(i) - target.row(i)).norm();
  }
  EXPECT_GT(lag, lag_light);
}
