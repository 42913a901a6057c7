#include "physics/core/violations.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>

namespace cellflow {
namespace {

TEST(NumberText, ShortestTextReadsBackExactly) {
  EXPECT_EQ(number_text(0.5), "0.5");
  EXPECT_EQ(number_text(3000), "3000");
  EXPECT_EQ(number_text(1e-300), "1e-300");
  EXPECT_EQ(number_text(-0.0), "-0");
  for (double v : {0.1 + 0.2, 8.6e-6, 1.0 / 3.0, 5e-324, 1.7976931348623157e308}) {
    EXPECT_EQ(std::strtod(number_text(v).c_str(), nullptr), v) << number_text(v);  // strtod: denormals too
  }
  EXPECT_EQ(number_text(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(number_text(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(NumberText, SignificantDigitsForDerivedQuantities) {
  EXPECT_EQ(number_text(0.123456789, 4), "0.1235");
  EXPECT_EQ(number_text(1.23456789e-5, 6), "1.23457e-05");
}

TEST(Violations, FieldsAreRelativeAndTheCallerAddsThePath) {
  Violations material;
  material.add_value("poisson_ratio", 0.5, "lie in (-1, 0.5)");
  Violations cell;
  cell.add_value("radius_m", -1.0, "be > 0");
  cell.add_all(material, "material.");
  cell.add_message("mesh_file: whole message kept");
  ASSERT_EQ(cell.list().size(), 3u);
  EXPECT_EQ(cell.list()[1].field, "material.poisson_ratio");
  const Status s = cell.status("compression.cell.");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(
      s.message(),
      "compression.cell.radius_m = -1 must be > 0; compression.cell.material.poisson_ratio = 0.5 must lie in "
      "(-1, 0.5); mesh_file: whole message kept");
  EXPECT_TRUE(Violations().status("x.").ok());
}

TEST(Violations, WholeMessagesNameTheirFieldsThroughPlaceholders) {
  Violations numerics;
  numerics.add_message("set only one of {}a and {}b");
  Violations scene;
  scene.add_all(numerics, "numerics.");
  EXPECT_EQ(scene.status("shear_flow.").message(),
            "set only one of shear_flow.numerics.a and shear_flow.numerics.b");
}

}  // namespace
}  // namespace cellflow
