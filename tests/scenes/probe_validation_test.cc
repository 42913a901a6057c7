// Probe indentation against the CalculiX references of validation/fe
// (curves/*.csv, README there): the colloidal probe (R 40 um, Rp 26.5 um,
// E 580 Pa) and the small probe (Rp 2.5 um on R 8 um, E 1000 Pa), each to
// its largest relative force error over the range, monotonicity and
// the largest step between consecutive load points against the reference's
// step over the same interval. The coarse setting runs in the default suite,
// the default setting (3000 vertices, 40 points) with the label long
// (probe_validation_long_test). The figures asserted are the measured ones
// with their tolerance (validation/fe/README.md has the table).
#include "tests/scenes/probe_validation.h"

#include <gtest/gtest.h>

namespace cellflow::scenes {
namespace {

// Coarse: 1000 vertices, 10 load points, the default numerics (the pole
// grading of the default indentation mesh included).
TEST(ProbeValidation, SmallProbeCoarse) {
  const ProbeComparison c = compare_with_reference(small_probe(1000, 10));
  print_comparison("small probe, 1000 vertices, 10 points", c);
  ASSERT_TRUE(c.status.ok()) << c.status.to_string();
  EXPECT_TRUE(c.monotone);
  EXPECT_LT(c.largest_error, kSmallProbeCoarseError);
  EXPECT_LT(c.largest_step_ratio, kCoarseStepRatio);
}

TEST(ProbeValidation, ColloidalProbeCoarse) {
  const ProbeComparison c = compare_with_reference(colloidal_probe(1000, 10));
  print_comparison("colloidal probe, 1000 vertices, 10 points", c);
  ASSERT_TRUE(c.status.ok()) << c.status.to_string();
  EXPECT_TRUE(c.monotone);
  EXPECT_LT(c.largest_error, kColloidalProbeCoarseError);
  EXPECT_LT(c.largest_step_ratio, kCoarseStepRatio);
}

}  // namespace
}  // namespace cellflow::scenes
