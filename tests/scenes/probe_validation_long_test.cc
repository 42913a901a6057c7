// The default setting (3000 vertices, 40 load points, default numerics: the
// pole-graded indentation mesh, penalty on the vertices) against the
// CalculiX probe references: the acceptance (colloidal probe within
// 3 % from 0.25 um to 20 um, small probe within 5 % from 0.1 um to 2 um,
// monotone). Measured figures in validation/fe/README.md. Label long.
#include <gtest/gtest.h>

#include "tests/scenes/probe_validation.h"

namespace cellflow::scenes {
namespace {

TEST(ProbeValidationLong, SmallProbeDefault) {
  const ProbeComparison c = compare_with_reference(small_probe(3000, 40));
  print_comparison("small probe, default", c);
  ASSERT_TRUE(c.status.ok()) << c.status.to_string();
  EXPECT_TRUE(c.monotone);
  EXPECT_LT(c.largest_error, 0.05);
  EXPECT_LT(c.largest_step_ratio, kDefaultStepRatio);
}

TEST(ProbeValidationLong, ColloidalProbeDefault) {
  const ProbeComparison c = compare_with_reference(colloidal_probe(3000, 40));
  print_comparison("colloidal probe, default", c);
  ASSERT_TRUE(c.status.ok()) << c.status.to_string();
  EXPECT_TRUE(c.monotone);
  EXPECT_LT(c.largest_error, 0.03);
  EXPECT_LT(c.largest_step_ratio, kDefaultStepRatio);
}

}  // namespace
}  // namespace cellflow::scenes
