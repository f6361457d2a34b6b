// mesh/caps.h and the correction's held vertices: flat caps found from face labels and by
// shape on generated capped vessels and a real SimVascular model, never moved by a
// correction near an open end; and mesh/units.h's rule for models in centimetres.
#include <gtest/gtest.h>

#include <set>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/io/medical_io.h"
#include "meshpde/mesh/caps.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/mesh/units.h"
#include "test_data.h"

namespace meshpde {
namespace {

std::set<int> labels_of(const std::vector<Cap>& caps) {
  std::set<int> s;
  for (const auto& c : caps) s.insert(c.label);
  return s;
}

TEST(Caps, TheFlatLabelledPatchesAreCapsAndTheWallIsNot) {
  const GeneratedMesh tube = meshpde::tube(3.0, 20.0, 20, 24, true);
  const Mesh m(tube.V, tube.F);
  EXPECT_EQ(analyze(m).boundary_edges, 0);
  const auto caps = caps_from_labels(m, tube.face_labels);
  ASSERT_EQ(labels_of(caps), (std::set<int>{2, 3}));
  for (const Cap& c : caps) {
    EXPECT_NEAR(std::abs(c.normal.z()), 1.0, 1e-12);
    EXPECT_LT(c.flatness, 1e-12);
    EXPECT_EQ(c.vertices.size(), 25u);  // the centre and the rim
  }
  EXPECT_EQ(cap_vertices(caps).size(), 50u);

  BifurcationParams q;
  q.caps = true;
  q.cell = 0.7;
  const GeneratedMesh bif = y_bifurcation(q);
  const Mesh b(bif.V, bif.F);
  EXPECT_EQ(analyze(b).boundary_edges, 0);
  const auto bcaps = caps_from_labels(b, bif.face_labels);
  ASSERT_EQ(labels_of(bcaps), (std::set<int>{2, 3, 4}));
  for (const Cap& c : bcaps) EXPECT_LT(c.flatness, 1e-6);
  EXPECT_THROW(caps_from_labels(b, Eigen::VectorXi::Ones(3)), InputError);
  // One label only: no caps; a rule of Off: none either.
  EXPECT_TRUE(caps_from_labels(b, Eigen::VectorXi::Ones(b.num_faces())).empty());
  EXPECT_TRUE(find_caps(b, bif.face_labels, CapRule::Off).empty());
  EXPECT_EQ(parse_cap_rule("auto"), CapRule::Auto);
  EXPECT_THROW(parse_cap_rule("yes"), InputError);
}

TEST(Caps, ARealSimVascularModelsCapsAreFoundByLabelAndByShape) {
  if (!test::have_data("simvascular-pipe-capped-5k.vtp")) return;
  const MeshData d = read_mesh(test::data_dir() / "simvascular-pipe-capped-5k.vtp");
  const Mesh m(d.V, d.F);
  std::string name;
  const Eigen::VectorXi labels = face_labels(d, &name);
  EXPECT_EQ(name, "ModelFaceID");
  const auto by_label = caps_from_labels(m, labels);
  ASSERT_EQ(labels_of(by_label), (std::set<int>{1, 3}));  // 2 is the wall
  const auto by_shape = find_flat_caps(m);
  ASSERT_EQ(by_shape.size(), 2u);
  EXPECT_EQ(cap_vertices(by_shape), cap_vertices(by_label));
  for (const Cap& c : by_shape) EXPECT_GT(c.rim_turn_deg, 80);
  // No false caps on the real meshes without any (marching-cubes facets, subdivisions).
  for (const char* file : {"aorta-closed-6k.vtp", "aorta-103k.vtp", "carotid-ica-4k.vtp"}) {
    if (!test::have_data(file)) continue;
    const MeshData r = read_mesh(test::data_dir() / file);
    EXPECT_TRUE(find_flat_caps(Mesh(r.V, r.F)).empty()) << file;
  }
}

// The largest displacement of a cap vertex, and the largest out of its cap's plane.
std::pair<double, double> cap_motion(const Mesh& m, const std::vector<Cap>& caps, const Field& d) {
  double most = 0, off_plane = 0;
  for (const Cap& c : caps)
    for (const int v : c.vertices) {
      most = std::max(most, d.row(v).norm());
      const Eigen::Vector3d p = m.positions().row(v).transpose() + d.row(v).transpose();
      off_plane = std::max(off_plane, std::abs(c.normal.dot(p - c.centre)));
    }
  return {most, off_plane};
}

TEST(Caps, ACorrectionNearAnOpenEndLeavesTheCapWhereItIs) {
  BifurcationParams q;
  q.caps = true;
  q.cell = 0.7;
  const GeneratedMesh bif = y_bifurcation(q);
  const Mesh m(bif.V, bif.F);
  const auto caps = caps_from_labels(m, bif.face_labels);
  // A wall vertex 2 mm above the trunk's cap (at z = -20), pushed outwards by 1.5 mm over 6 mm.
  int handle = 0;
  (m.positions().rowwise() - Eigen::RowVector3d(q.trunk_radius, 0, -q.trunk_length + 2))
      .rowwise()
      .squaredNorm()
      .minCoeff(&handle);
  CorrectionParams p;
  p.handles = parse_handles(m, {handle}, {"normal:1.5"});
  p.radius = 6;
  CorrectionParams held = p;
  held.held = cap_vertices(caps);
  const CorrectionResult free_caps = correct_vessel(m, p);
  const CorrectionResult kept = correct_vessel(m, held);
  EXPECT_GT(cap_motion(m, caps, free_caps.displacement).first, 0.05) << "without caps held the trunk's cap moves";
  const auto [most, off_plane] = cap_motion(m, caps, kept.displacement);
  EXPECT_EQ(most, 0.0);
  EXPECT_LT(off_plane, 1e-9);
  EXPECT_GT(kept.max_displacement, 1.4);
  // The springs baseline holds them too, and a handle on a cap is refused in words.
  held.method = CorrectionMethod::Springs;
  held.radius = 0;
  held.rings = 8;
  EXPECT_EQ(cap_motion(m, caps, correct_vessel(m, held).displacement).first, 0.0);
  held.handles[0].vertex = caps[0].vertices[0];
  try {
    correct_vessel(m, held);
    FAIL() << "a cap vertex was used as a handle";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lies on a cap"), std::string::npos) << e.what();
  }
}

TEST(Caps, TheRealPipesCapsStayFlatUnderAPushAtItsEnd) {
  if (!test::have_data("simvascular-pipe-capped-5k.vtp")) return;
  const MeshData d = read_mesh(test::data_dir() / "simvascular-pipe-capped-5k.vtp");
  const Mesh m(d.V, d.F);
  const auto caps = find_caps(m, face_labels(d), CapRule::Labels);
  int handle = 0;  // on the wall, 0.3 cm from the cap at z = 0
  (m.positions().rowwise() - Eigen::RowVector3d(2, 0, 0.3)).rowwise().squaredNorm().minCoeff(&handle);
  CorrectionParams p;
  p.units = LengthUnit::Centimetre;
  p.handles = parse_handles(m, {handle}, {"normal:3"});  // mm, on a model in cm
  p.radius = 12;
  p.held = cap_vertices(caps);
  const CorrectionResult r = correct_vessel(m, p);
  EXPECT_GT(r.moved_vertices, 10);
  EXPECT_NEAR(r.max_displacement, 3.0, 1e-9);  // mm: the handle's move
  const auto [most, off_plane] = cap_motion(m, caps, r.displacement);
  EXPECT_EQ(most, 0.0);
  EXPECT_LE(off_plane, 0.007);  // the cap at z = 30 is 0.006 cm from flat in the file
}

}  // namespace
}  // namespace meshpde
