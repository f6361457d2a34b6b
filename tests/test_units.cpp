// mesh/units.h: a model in centimetres is told from one in millimetres by its sizes
// and its vessels, and the real models of the data folder pass as millimetres.
#include <gtest/gtest.h>

#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/units.h"
#include "test_data.h"

namespace meshpde {
namespace {

TEST(Units, AModelInCentimetresIsRecognisedByItsSizesAndItsVessels) {
  // A vessel 30 cm long of 1.2 cm radius meshed at 0.05 cm, as SimVascular writes one:
  // plausible sizes in millimetres, but vessels and edges no scanner resolves.
  const GeneratedMesh t = meshpde::tube(1.2, 30, 600, 150, true);
  const Mesh m(t.V, t.F);
  EXPECT_NEAR(median_vessel_radius(m), 1.2, 0.01);
  const UnitsCheck mm = check_units(m, LengthUnit::Millimetre);
  EXPECT_TRUE(mm.implausible);
  ASSERT_TRUE(mm.suggested.has_value());
  EXPECT_EQ(*mm.suggested, LengthUnit::Centimetre);
  EXPECT_NE(units_warning(m, LengthUnit::Millimetre, "tube.vtp").find("finer than any scanner resolves"),
            std::string::npos);
  EXPECT_FALSE(check_units(m, LengthUnit::Centimetre).implausible);
  // The same vessel coarsely meshed in millimetres is plausible, and the real models too.
  const GeneratedMesh coarse = meshpde::tube(12, 300, 60, 48, true);
  EXPECT_FALSE(check_units(Mesh(coarse.V, coarse.F), LengthUnit::Millimetre).implausible);
  for (const char* file : {"aorta-closed-6k.vtp", "aorta-103k.vtp", "carotid-ica-4k.vtp", "aorta-open-6k.stl",
                           "coronary-phantom-7k.stl"}) {
    if (!test::have_data(file)) continue;
    const MeshData r = read_mesh(test::data_dir() / file);
    EXPECT_FALSE(check_units(Mesh(r.V, r.F), LengthUnit::Millimetre).implausible) << file;
  }
}

}  // namespace
}  // namespace meshpde
