// Vessel correction on the real aorta set (../shared/data): accurate solves on a
// marching-cubes surface, the same correction at two resolutions, far carina
// drags without self-intersections, and image-guided correction of a dent against
// the segmentation's level set.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/editor/editor_session.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/steady_direct.h"
#include "test_data.h"
#include "test_support.h"

using namespace meshpde;

namespace {

bool load_vtp(const std::string& name, Mesh& mesh) {
  if (!test::have_data(name)) return false;
  const MeshData d = read_mesh(test::data_dir() / name);
  mesh = Mesh(d.V, d.F);
  return true;
}

// The carina of the iliac bifurcation in aorta-closed-6k (and aorta-103k, whose
// first 6,468 vertices are the same points): the surface vertex between the two
// vmtk centerlines where they are one vessel diameter apart.
constexpr int kCarina = 3178;
// A wall vertex on the abdominal trunk, in a clean part of the image.
constexpr int kTrunk = 500;

// The bi-Laplacian drag of the issue: 8.9 mm, 20 mm region, solved by two solvers.
struct TwoSolves {
  Field cholmod, eigen;
  double residual_cholmod = 0, residual_eigen = 0;
  SteadyDirectSolver::Conditioning conditioning;  // of the CHOLMOD solve, default accuracy 1e-5
};

TwoSolves drag_both_ways(const Mesh& mesh, const MeshOperators& mo, int handle) {
  const auto region = geodesic_ball(mesh, handle, 20.0);
  std::vector<int> free;
  for (int v : region)
    if (v != handle && mo.ops.mass[v] > 0) free.push_back(v);
  Field held = Field::Zero(mesh.num_vertices(), 3);
  held.row(handle) << 0, 0, 8.9;
  TwoSolves t;
  const PdeCoefficients c{.g0 = 0, .g1 = 0, .g2 = 1};
  const SteadyDirectSolver a(mo.mesh, mo.ops, c, free, SparseCholesky::Backend::Cholmod);
  t.cholmod = a.solve(held);
  t.residual_cholmod = a.last_relative_residual();
  t.conditioning = a.conditioning();
  const SteadyDirectSolver b(mo.mesh, mo.ops, c, free, SparseCholesky::Backend::Eigen);
  t.eigen = b.solve(held);
  t.residual_eigen = b.last_relative_residual();
  return t;
}

}  // namespace

TEST(AortaCorrection, IntrinsicOperatorsMakeTwoSolversAgree) {
  if (!SparseCholesky::cholmod_available()) GTEST_SKIP() << "built without CHOLMOD: one direct solver only";
  for (const char* name : {"aorta-closed-6k.vtp", "aorta-103k.vtp"}) {
    SCOPED_TRACE(name);
    Mesh mesh;
    if (!load_vtp(name, mesh)) continue;
    const MeshOperators mo = build_mesh_operators(mesh, LaplacianKind::Auto);
    EXPECT_EQ(mo.kind, LaplacianKind::IntrinsicDelaunay) << mo.reason;
    const TwoSolves t = drag_both_ways(mesh, mo, 1000);
    const double diff = (t.cholmod - t.eigen).rowwise().norm().maxCoeff();
    std::printf("%s intrinsic: solvers differ by %.2e mm, residuals %.1e %.1e\n", name, diff, t.residual_cholmod,
                t.residual_eigen);
    EXPECT_LE(diff, 1e-6 * 8.9);
    EXPECT_LE(t.residual_cholmod, 1e-10);
    EXPECT_LE(t.residual_eigen, 1e-10);
    // The solver layer vouches for this solve: its error bound is below 1e-5.
    std::printf("  condition estimate %.1e, error bound %.1e\n", t.conditioning.condition_1,
                t.conditioning.relative_error);
    EXPECT_TRUE(t.conditioning.sufficient) << t.conditioning.message;
    EXPECT_LE(diff / 8.9, t.conditioning.relative_error);  // the bound holds
    // Smooth: nothing moves further than the handle, and the field is no rougher
    // (|d_i - mean of its neighbours|) at vertices of sliver triangles (an angle
    // below 1 degree) than anywhere else away from the handle: no spikes at slivers.
    EXPECT_LE(t.cholmod.rowwise().norm().maxCoeff(), 1.001 * 8.9);
    std::vector<char> sliver(static_cast<std::size_t>(mesh.num_vertices()), 0);
    int slivers = 0;
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = mesh.positions().row(mesh.triangles()(f, k));
        const Eigen::Vector3d a = mesh.positions().row(mesh.triangles()(f, (k + 1) % 3)).transpose() - p;
        const Eigen::Vector3d b = mesh.positions().row(mesh.triangles()(f, (k + 2) % 3)).transpose() - p;
        if (std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) < M_PI / 180) {
          for (int c = 0; c < 3; ++c) sliver[static_cast<std::size_t>(mesh.triangles()(f, c))] = 1;
          ++slivers;
        }
      }
    double rough_all = 0, rough_sliver = 0;
    for (int v : geodesic_ball(mesh, 1000, 20.0)) {
      if ((mesh.positions().row(v) - mesh.positions().row(1000)).norm() < 3) continue;
      Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
      for (int w : mesh.neighbors(v)) mean += t.cholmod.row(w);
      const double r = (t.cholmod.row(v) - mean / mesh.degree(v)).norm();
      rough_all = std::max(rough_all, r);
      if (sliver[static_cast<std::size_t>(v)]) rough_sliver = std::max(rough_sliver, r);
    }
    std::printf("  roughness at sliver vertices %.3f mm, elsewhere up to %.3f mm (%d sliver angles)\n", rough_sliver,
                rough_all, slivers);
    EXPECT_GT(slivers, 0);
    EXPECT_LT(rough_sliver, rough_all);
    if (std::string(name) == "aorta-103k.vtp") {
      // The plain cotangent operator on the same mesh. Its assembled K D K is so
      // ill-conditioned that the two factors' answers differed by 1.9e-3 mm while
      // refinement measured residuals against the assembled matrix; refined against
      // the products (CG, solvers/refinement.h) they agree again, but the residual
      // stays four orders of magnitude above the intrinsic operator's: the products'
      // own rounding, which the condition number turns into the error bound below.
      const MeshOperators plain = build_mesh_operators(mesh, LaplacianKind::Cotan);
      const TwoSolves p = drag_both_ways(mesh, plain, 1000);
      const double plain_diff = (p.cholmod - p.eigen).rowwise().norm().maxCoeff();
      std::printf("%s cotan: solvers differ by %.2e mm, residuals %.1e %.1e\n", name, plain_diff, p.residual_cholmod,
                  p.residual_eigen);
      EXPECT_LE(plain_diff, 1e-6 * 8.9);
      EXPECT_GT(std::min(p.residual_cholmod, p.residual_eigen), 1e3 * std::max(t.residual_cholmod, t.residual_eigen));
      // ... and the solver layer says so by itself, before anyone compares solvers.
      std::printf("  cotan condition estimate %.1e, error bound %.1e\n", p.conditioning.condition_1,
                  p.conditioning.relative_error);
      EXPECT_FALSE(p.conditioning.sufficient);
      EXPECT_NE(p.conditioning.message.find("ill-conditioned"), std::string::npos);
      EXPECT_GE(p.conditioning.relative_error, plain_diff / 8.9);  // the bound covers the disagreement
    }
  }
}

TEST(AortaCorrection, TheRegionsCopyGivesTheWholeMeshAnswer) {
  // correct_vessel solves on the region plus a margin of rings; the same free set
  // solved with operators built on the whole mesh must give the same field: to
  // rounding with the cotangent operator, and to 2e-5 of the drag with the intrinsic
  // one, whose mollification constant is set by the worst triangle of the mesh it
  // is built on (the region's copy or the whole mesh). On aorta-closed-6k the solves
  // are well conditioned (two solvers agree to 1e-10 mm), so rounding stays small.
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh)) return;
  for (const LaplacianKind kind : {LaplacianKind::Cotan, LaplacianKind::IntrinsicDelaunay}) {
    SCOPED_TRACE(to_string(kind));
    CorrectionParams p;
    p.handles = {{kTrunk, Eigen::Vector3d(0, 0, 5)}};
    p.radius = 15;
    p.boundary = RegionBoundary::Clamp;  // the held handle and region the construction below repeats
    p.laplacian = kind;
    const CorrectionResult r = correct_vessel(mesh, p);
    const MeshOperators whole = build_mesh_operators(mesh, kind);
    std::vector<int> free;
    for (int v : r.region)
      if (v != kTrunk) free.push_back(v);
    Field held = Field::Zero(mesh.num_vertices(), 3);
    held.row(kTrunk) << 0, 0, 5;
    const SteadyDirectSolver s(whole.mesh, whole.ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
    const double diff = (s.solve(held) - r.displacement).rowwise().norm().maxCoeff();
    std::printf("%s: region copy vs whole mesh %.2e mm\n", to_string(kind), diff);
    EXPECT_LE(diff, kind == LaplacianKind::Cotan ? 1e-9 : 2e-5 * 5);
  }
}

TEST(AortaCorrection, TheEditorsPreviewEqualsTheReleasedCorrection) {
  // A real segmentation with slivers (intrinsic Delaunay operators, chosen by Auto on
  // the region's copy in both): the editor's preview when the mouse stops equals the
  // correction applied on release, to 1e-9 of the drag.
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh)) return;
  MeshData data;
  data.V = mesh.positions();
  data.F = mesh.triangles();
  EditorSession s(data);
  const Eigen::Vector3d offset(0, 0, 2.0);
  s.drag_begin(kTrunk, 9.0);
  s.drag_move(0.5 * offset);
  s.drag_move(offset);
  const Positions preview = s.display_positions();
  CorrectionParams p;
  p.handles = {{kTrunk, offset}};
  p.radius = 9.0;
  const CorrectionResult r = s.correct(p);
  EXPECT_EQ(r.laplacian, LaplacianKind::IntrinsicDelaunay);
  EXPECT_EQ(r.intersection_action, "none");
  const double diff = (preview - r.V).cwiseAbs().maxCoeff();
  std::printf("editor preview vs released correction: %.2e mm of a %.1f mm drag\n", diff, offset.norm());
  EXPECT_LE(diff, 1e-9 * offset.norm());
}

TEST(AortaCorrection, SameCorrectionOnTheCoarseAndTheSubdividedAorta) {
  Mesh coarse, fine;
  if (!load_vtp("aorta-closed-6k.vtp", coarse) || !load_vtp("aorta-103k.vtp", fine)) return;
  ASSERT_EQ((fine.positions().topRows(coarse.num_vertices()) - coarse.positions()).cwiseAbs().maxCoeff(), 0.0);
  const Eigen::Vector3d d(0, 0, 5);
  CorrectionParams p;
  p.handles = {{kTrunk, d}};
  p.radius = 15;
  const CorrectionResult a = correct_vessel(coarse, p), b = correct_vessel(fine, p);
  const double h = hausdorff_distance(a.V, coarse.triangles(), b.V, fine.triangles());
  CorrectionParams s = p;
  s.method = CorrectionMethod::Springs;
  s.radius = 0;
  s.rings = 10;
  const CorrectionResult sa = correct_vessel(coarse, s), sb = correct_vessel(fine, s);
  const double hs = hausdorff_distance(sa.V, coarse.triangles(), sb.V, fine.triangles());
  std::printf("aorta 6k vs 103k: Hausdorff fem %.4f mm, thesis springs %.4f mm (limit %.4f)\n", h, hs, 0.02 * d.norm());
  EXPECT_LE(h, 0.02 * d.norm());
  EXPECT_GT(hs, 0.02 * d.norm());
}

TEST(AortaCorrection, FarCarinaDragsCreateNoIntersections) {
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh)) return;
  for (const Eigen::Vector3d& d : {Eigen::Vector3d(0, 10, 0), Eigen::Vector3d(10, 0, 0), Eigen::Vector3d(0, -10, 0)}) {
    SCOPED_TRACE(d.transpose());
    CorrectionParams p;
    p.handles = {{kCarina, d}};
    p.radius = 12;
    const CorrectionResult r = correct_vessel(mesh, p);
    std::printf("carina drag (%g, %g, %g): %s, applied %.3f, %.0f ms\n", d.x(), d.y(), d.z(),
                r.intersection_action.c_str(), r.applied_fraction, r.time_ms);
    EXPECT_EQ(r.new_self_intersections, 0);
    EXPECT_GT(r.applied_fraction, 0.9);
    Mesh after = mesh;
    after.set_positions(r.V);
    EXPECT_TRUE(SelfIntersectionChecker(after).all_pairs().empty());
    CorrectionParams s = p;
    s.method = CorrectionMethod::Springs;
    s.radius = 0;
    s.rings = 10;
    const CorrectionResult t = correct_vessel(mesh, s);
    std::printf("  thesis springs: %d new self-intersections\n", t.new_self_intersections);
    EXPECT_GT(t.new_self_intersections, 0);
  }
}

TEST(AortaCorrection, ImageGuidanceRestoresADentedWall) {
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh) || !test::have_data("aorta-mra.mha") ||
      !test::have_data("aorta-levelset.mha"))
    return;
  const Volume phi = read_volume(test::data_dir() / "aorta-levelset.mha");
  const Volume mra = read_volume(test::data_dir() / "aorta-mra.mha");
  // The outward normal from the level set (phi < 0 inside), in the mesh's RAS frame.
  const Eigen::Vector3d p0 = mesh.positions().row(kTrunk).transpose();
  const Eigen::Vector3d outward = to_lps(*phi.gradient_lps(to_lps(p0, Space::RAS)), Space::RAS).normalized();
  // Dent the wall 2.5 mm inwards over a 6 mm patch.
  CorrectionParams dent;
  dent.handles = {{kTrunk, -2.5 * outward}};
  dent.radius = 6;
  const CorrectionResult dr = correct_vessel(mesh, dent);
  ASSERT_EQ(dr.new_self_intersections, 0);
  Mesh dented = mesh;
  dented.set_positions(dr.V);
  // The user drags the dent's centre back out over a 9 mm region, without and with the image.
  CorrectionParams fix;
  fix.handles = {{kTrunk, 2.5 * outward}};
  fix.radius = 9;
  const CorrectionResult plain = correct_vessel(dented, fix);
  fix.image.edges = std::make_shared<const Volume>(gradient_magnitude(mra, 1.0));
  fix.image.space = Space::RAS;
  const CorrectionResult guided = correct_vessel(dented, fix);
  fix.image.cube_size = 3;
  const CorrectionResult cube = correct_vessel(dented, fix);
  std::vector<int> moved;
  for (int v : guided.region)
    if (guided.displacement.row(v).norm() > 1e-3) moved.push_back(v);
  ASSERT_GT(moved.size(), 50u);
  auto mean_abs_phi = [&](const Positions& V) {
    double s = 0;
    for (int v : moved) s += std::abs(*phi.sample(V.row(v).transpose(), Space::RAS));
    return s / static_cast<double>(moved.size());
  };
  const double before = mean_abs_phi(dr.V), without = mean_abs_phi(plain.V), with = mean_abs_phi(guided.V),
               with_cube = mean_abs_phi(cube.V);
  std::printf("mean |phi| over %zu moved vertices: dented %.3f, unguided %.3f, guided %.3f, thesis cube %.3f mm\n",
              moved.size(), before, without, with, with_cube);
  EXPECT_LE(with, 0.5 * before);
  EXPECT_GT(without, 2 * with);  // the unguided correction does measurably worse
  EXPECT_GT(guided.image_mean_edge_after, guided.image_mean_edge_before);
  EXPECT_EQ(guided.new_self_intersections, 0);
}

TEST(AortaCorrection, TheThesisSpringsWithTheirDynamicModeAndImageStep) {
  // The thesis's baseline made complete (its sections 13.3 and 13.4): the dynamic
  // version integrates eq. 12.1 with its inertia, and the image step moves each vertex
  // towards the strongest voxel of its direction cube inside that integration.
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh) || !test::have_data("aorta-mra.mha")) return;
  const Volume mra = read_volume(test::data_dir() / "aorta-mra.mha");
  const auto edges = std::make_shared<const Volume>(gradient_magnitude(mra, 1.0));
  const Eigen::Vector3d normal = vertex_normals(mesh).row(kTrunk).transpose();
  CorrectionParams dent;
  dent.handles = {{kTrunk, 2.0 * normal}};
  dent.radius = 6;
  Mesh dented = mesh;
  dented.set_positions(correct_vessel(mesh, dent).V);
  auto run = [&](bool dynamic, bool image, double viscosity) {
    CorrectionParams s;
    s.method = CorrectionMethod::Springs;
    s.handles = {{kTrunk, -2.0 * normal}};
    s.rings = 8;
    s.dynamic = dynamic;
    s.tissue.viscosity = viscosity;
    if (image) {
      s.image.edges = edges;
      s.image.space = Space::RAS;
      s.image.cube_size = 3;
    }
    return correct_vessel(dented, s);
  };
  const CorrectionResult fixed = run(false, false, 1.0), fixed_image = run(false, true, 1.0);
  const CorrectionResult damped = run(true, false, 1.0), ringing = run(true, false, 0.0);
  const CorrectionResult damped_image = run(true, true, 1.0);
  for (const CorrectionResult* r : {&fixed, &fixed_image, &damped, &ringing, &damped_image}) {
    EXPECT_LT((r->displacement.row(kTrunk).transpose() + 2.0 * normal).norm(), 1e-12);
    EXPECT_TRUE(r->V.allFinite());
  }
  // The image step pulls the moved wall towards the MRA's edges, static or dynamic.
  EXPECT_GT(fixed_image.pulled_vertices, 20);
  EXPECT_GT(fixed_image.image_mean_edge_after, fixed_image.image_mean_edge_before);
  EXPECT_GT(damped_image.image_mean_edge_after, damped_image.image_mean_edge_before);
  double far = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    far = std::max(far, (fixed_image.displacement.row(v) - fixed.displacement.row(v)).norm());
  EXPECT_GT(far, 0.05);  // the image moved something
  // Critically damped, the dynamic version settles where the overdamped one stops (both
  // to the same force threshold: 0.05 mm apart here); undamped, it is caught ringing,
  // tens of millimetres off, as the thesis found its viscosity-0 results.
  const double settled = (damped.displacement - fixed.displacement).rowwise().norm().maxCoeff();
  const double rung = (ringing.displacement - fixed.displacement).rowwise().norm().maxCoeff();
  std::printf(
      "springs: dynamic (viscosity 1) vs fixed %.3f mm, undamped vs fixed %.3f mm; image step: mean edge "
      "%.2f -> %.2f (fixed), %.2f -> %.2f (dynamic)\n",
      settled, rung, fixed_image.image_mean_edge_before, fixed_image.image_mean_edge_after,
      damped_image.image_mean_edge_before, damped_image.image_mean_edge_after);
  EXPECT_LT(settled, 0.25);
  EXPECT_LT(10 * settled, rung);
}

// The editor's "image pull (mm)" after an image-guided correction is what the image did:
// |the guided field - the same drag's field without the image|, both computed here
// independently with correct_vessel; "moved (mm)" is the guided move itself.
TEST(AortaCorrection, TheEditorsImagePullIsTheGuidedMinusTheUnguidedCorrection) {
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh) || !test::have_data("aorta-mra.mha")) return;
  const Volume mra = read_volume(test::data_dir() / "aorta-mra.mha");
  const auto edges = std::make_shared<const Volume>(gradient_magnitude(mra, 1.0));
  MeshData data;
  data.V = mesh.positions();
  data.F = mesh.triangles();
  EditorSession s(data, edges, Space::RAS);
  const Eigen::Vector3d normal = vertex_normals(mesh).row(kTrunk).transpose();
  CorrectionParams p;
  p.handles = {{kTrunk, 2.0 * normal}};
  p.radius = 9;
  p.laplacian = s.laplacian();
  const CorrectionResult r = s.correct(p);
  ASSERT_EQ(s.field_name(), "moved (mm)");
  ASSERT_EQ(s.image_pull().size(), mesh.num_vertices());
  CorrectionParams plain = p, guided = p;
  guided.image.edges = edges;
  guided.image.space = Space::RAS;
  const CorrectionResult g = correct_vessel(mesh, guided), u = correct_vessel(mesh, plain);
  ASSERT_EQ(r.applied_fraction, 1.0);
  const Eigen::VectorXd expected = (g.displacement - u.displacement).rowwise().norm();
  EXPECT_LT((s.image_pull() - expected).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT(expected.maxCoeff(), 0.05) << "the image moved the wall measurably";
  EXPECT_LT((s.field() - g.displacement.rowwise().norm()).cwiseAbs().maxCoeff(), 1e-9);
  s.show_correction_field("image pull (mm)");
  EXPECT_EQ(s.field_name(), "image pull (mm)");
  EXPECT_EQ(s.field(), s.image_pull());
  EXPECT_THROW(s.show_correction_field("paint"), InputError);
  s.show_correction_field("moved (mm)");
  EXPECT_EQ(s.field_name(), "moved (mm)");
  // The next action ends both; a correction without the image has no pull to show.
  s.undo();
  EXPECT_EQ(s.field_name(), "");
  EXPECT_THROW(s.show_correction_field("moved (mm)"), InputError);
  p.image.weight = 0;
  s.correct(p);
  EXPECT_EQ(s.image_pull().size(), 0);
  EXPECT_THROW(s.show_correction_field("image pull (mm)"), InputError);
}

// The aorta meshes are in RAS, the MRA in LPS (MANIFEST). A guided correction with the
// mesh read in the wrong frame lies wholly outside the image: refused, naming the frame
// in which the region lies inside it, instead of tying every region vertex to where it
// is (which stiffened the wall with no edge to pull it to); a mesh far from the image in
// both frames is refused too. The right frame is guided as before.
TEST(AortaCorrection, AGuidedCorrectionOutsideTheImageIsRefusedNamingTheOtherFrame) {
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh) || !test::have_data("aorta-mra.mha")) return;
  const Volume mra = read_volume(test::data_dir() / "aorta-mra.mha");
  CorrectionParams p;
  p.handles = {{kTrunk, 2.0 * vertex_normals(mesh).row(kTrunk).transpose()}};
  p.radius = 9;
  p.image.edges = std::make_shared<const Volume>(gradient_magnitude(mra, 1.0));
  p.image.space = Space::LPS;
  const std::string wrong = test::error_of([&] { correct_vessel(mesh, p); });
  EXPECT_NE(wrong.find("none of the region's"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("read as LPS"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("is the mesh in RAS?"), std::string::npos) << wrong;
  Mesh far = mesh;
  far.set_positions(mesh.positions().rowwise() + Eigen::RowVector3d(0, 0, 500));
  const std::string nowhere = test::error_of([&] { correct_vessel(far, p); });
  EXPECT_NE(nowhere.find("same scan"), std::string::npos) << nowhere;
  p.image.weight = 0;  // the image attached but not pulling: nothing to refuse
  EXPECT_NO_THROW(correct_vessel(mesh, p));
  p.image.weight = ImageGuidance{}.weight;
  p.image.space = Space::RAS;
  const CorrectionResult r = correct_vessel(mesh, p);
  EXPECT_GT(r.pulled_vertices, 50);
  EXPECT_GT(r.image_mean_edge_before, 0);
}

// A region across the edge of the image (a correction near the border of the scan's
// field of view): the vertices outside the image have nothing to be pulled to, so they
// get no spring and follow the drag unguided. Checked through the plate's own balance:
// at a free vertex without a spring the correction's field has (K D K d)_i = 0, at a
// pulled one the spring's force is what is left. The edge map is the MRA's, cut through
// the handle; vertices of the cut-off half would have been tied where they were.
TEST(AortaCorrection, VerticesOutsideTheImageFollowTheDragUnguided) {
  Mesh mesh;
  if (!load_vtp("aorta-closed-6k.vtp", mesh) || !test::have_data("aorta-mra.mha")) return;
  const Volume mra = read_volume(test::data_dir() / "aorta-mra.mha");
  const Volume E = gradient_magnitude(mra, 1.0);
  // Keep the voxels on one side of the handle along the axis on which the region spans
  // the most voxels.
  const Eigen::Vector3d at = E.lps_to_index(to_lps(mesh.positions().row(kTrunk).transpose(), Space::RAS));
  Eigen::Vector3d lo = at, hi = at;
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if ((mesh.positions().row(v) - mesh.positions().row(kTrunk)).norm() < 9) {
      const Eigen::Vector3d q = E.lps_to_index(to_lps(mesh.positions().row(v).transpose(), Space::RAS));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int keep = static_cast<int>(std::floor(at[axis])) + 1;
  ASSERT_GT(keep, 1);
  ASSERT_LT(keep, E.dims[static_cast<std::size_t>(axis)]);
  Volume cut = E;
  cut.dims[static_cast<std::size_t>(axis)] = keep;
  cut.values.clear();
  for (int k = 0; k < cut.dims[2]; ++k)
    for (int j = 0; j < cut.dims[1]; ++j)
      for (int i = 0; i < cut.dims[0]; ++i) cut.values.push_back(E.at(i, j, k));

  CorrectionParams p;
  p.handles = {{kTrunk, 2.0 * vertex_normals(mesh).row(kTrunk).transpose()}};
  p.radius = 9;
  p.boundary = RegionBoundary::Clamp;  // no foundation: the balance below is the plate's alone
  p.laplacian = LaplacianKind::Cotan;
  p.prevent_intersections = false;  // one solve on the mesh itself
  p.image.edges = std::make_shared<const Volume>(std::move(cut));
  p.image.space = Space::RAS;
  const CorrectionResult r = correct_vessel(mesh, p);
  const FemOperators ops = build_cotan_operators(mesh);
  double outside_force = 0, pulled_force = 0;
  int outside = 0, inside = 0;
  for (const int v : r.region) {
    if (v == kTrunk) continue;
    Eigen::Vector3d force;
    for (int c = 0; c < 3; ++c) force[c] = bilaplacian_row(mesh, ops, v, [&](int w) { return r.displacement(w, c); });
    if (p.image.edges->sample(mesh.positions().row(v).transpose(), Space::RAS)) {
      ++inside;
      pulled_force = std::max(pulled_force, force.norm());
    } else {
      ++outside;
      outside_force = std::max(outside_force, force.norm());
    }
  }
  EXPECT_GT(outside, 30);
  EXPECT_GT(inside, 30);
  EXPECT_EQ(r.image_outside_vertices, outside);
  EXPECT_EQ(r.pulled_vertices, inside);
  EXPECT_GT(pulled_force, 0);
  EXPECT_LE(outside_force, 1e-8 * pulled_force) << outside_force << " against " << pulled_force;
  // For the record: how far the cut-off side lies from the unguided field (it is
  // coupled to the pulled side; tied where it was, it lay 0.92 mm off for the 2 mm drag).
  CorrectionParams plain = p;
  plain.image = ImageGuidance{};
  const CorrectionResult u = correct_vessel(mesh, plain);
  double worst = 0;
  for (const int v : r.region)
    if (!p.image.edges->sample(mesh.positions().row(v).transpose(), Space::RAS))
      worst = std::max(worst, (r.displacement.row(v) - u.displacement.row(v)).norm());
  std::printf(
      "outside the image: %d free vertices, largest force %.2e (pulled %.2e), largest difference from "
      "the unguided field %.3f mm\n",
      outside, outside_force, pulled_force, worst);
  const std::string json = correction_report_json(mesh.positions(), mesh.triangles(), p, r);
  EXPECT_NE(json.find("\"outside_vertices\":" + std::to_string(outside)), std::string::npos) << json;
}
