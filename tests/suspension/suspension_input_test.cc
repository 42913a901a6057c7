// Suspension scene input: N from the volume fraction, refusals naming the
// field (lambda out of range or != 1, more cells than fit, overlapping or
// outside explicit places, bad numerics), and the flow fields renamed into
// the suspension's.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "physics/scenes/suspension/suspension.h"

namespace cellflow::scenes {
namespace {

SuspensionParams base_params() {
  SuspensionParams p;
  SuspendedCellKind kind;
  kind.cell.radius_m = 6e-6;
  kind.cell.material.youngs_modulus_pa = 10.0;
  kind.cell.material.poisson_ratio = 0.48;
  kind.cell.target_vertex_count = 300;
  kind.volume_fraction = 0.11;
  p.kinds.push_back(kind);
  p.capillary_number = 0.1;
  p.numerics.flow.cells_per_radius = 4.0;
  p.numerics.flow.threads = 1;
  return p;
}

void expect_refused(const SuspensionParams& p, const std::string& field) {
  const StatusOr<PlannedSuspension> planned = plan_suspension_run(p);
  ASSERT_FALSE(planned.ok()) << "expected a refusal naming " << field;
  EXPECT_EQ(planned.status().code(), StatusCode::kInvalidArgument) << planned.status().to_string();
  EXPECT_NE(planned.status().message().find(field), std::string::npos) << planned.status().to_string();
}

TEST(SuspensionPlan, CountFollowsTheVolumeFraction) {
  SuspensionParams p = base_params();
  // 5 x 8 x 4 R box: N = round(phi 160 / (4/3 pi)) = 4 at 0.11, 8 at 0.22 (paper section 7.2).
  StatusOr<PlannedSuspension> planned = plan_suspension_run(p);
  ASSERT_TRUE(planned.ok()) << planned.status().to_string();
  EXPECT_EQ(planned->setup().cell_count, 4);
  EXPECT_EQ(planned->placements().size(), 4u);
  EXPECT_EQ(planned->cell_kinds(), std::vector<int>(4, 0));
  EXPECT_NEAR(planned->setup().volume_fraction, 4 * 4.18879 / 160, 2e-3);
  EXPECT_GT(planned->setup().memory_bytes, planned->setup().flow.lattice_bytes);
  p.kinds[0].volume_fraction = 0.22;
  planned = plan_suspension_run(p);
  ASSERT_TRUE(planned.ok()) << planned.status().to_string();
  EXPECT_EQ(planned->setup().cell_count, 8);
  // Defaults of the suspension numerics.
  EXPECT_EQ(suspension_numerics_defaults().flow.box_y_radii, 8.0);
  EXPECT_EQ(suspension_numerics_defaults().flow.max_strain, 20.0);
  EXPECT_EQ(SuspendedCellKind{}.cell.target_vertex_count, kSuspensionDefaultVertexCount);
}

TEST(SuspensionPlan, BadViscosityRatioNamesTheField) {
  SuspensionParams p = base_params();
  for (double lambda : {0.0, -1.0, 1000.0, std::nan("")}) {
    p.kinds[0].viscosity_ratio = lambda;
    expect_refused(p, "suspension.kinds[0].viscosity_ratio");
  }
  p.kinds[0].viscosity_ratio = 0.05;  // in range: planned, with the marking's memory
  const StatusOr<PlannedSuspension> contrast = plan_suspension_run(p);
  ASSERT_TRUE(contrast.ok()) << contrast.status().to_string();
  p.kinds[0].viscosity_ratio = 1.0;
  const StatusOr<PlannedSuspension> plain = plan_suspension_run(p);
  ASSERT_TRUE(plain.ok());
  const ShearFlowSetup& f = plain->setup().flow;
  EXPECT_EQ(contrast->setup().memory_bytes - plain->setup().memory_bytes,
            static_cast<std::size_t>(f.nx) * f.ny * f.nz * 5);
  // tau_in = 1/2 + lambda (tau - 1/2) below the stable 0.505.
  p.kinds[0].viscosity_ratio = 0.02;
  p.numerics.flow.relaxation_time = 0.6;
  expect_refused(p, "suspension.kinds[0].viscosity_ratio");
}

TEST(SuspensionPlan, MoreCellsThanFitNamesTheField) {
  SuspensionParams p = base_params();
  p.kinds[0].volume_fraction = 0.45;
  expect_refused(p, "suspension.kinds[0].volume_fraction");
  p.kinds[0].volume_fraction = 0.0;
  p.kinds[0].count = 30;
  expect_refused(p, "suspension.kinds[0].count");
  p.kinds[0].volume_fraction = 0.6;  // two of count / fraction set, and out of range
  expect_refused(p, "suspension.kinds[0].count");
}

TEST(SuspensionPlan, ExplicitPlacesOverlappingOrOutside) {
  SuspensionParams p = base_params();
  const double r = 6e-6;
  p.kinds[0].volume_fraction = 0.0;
  p.kinds[0].placements = {{{1.5 * r, 4 * r, 2 * r}, {}}, {{2.5 * r, 4.2 * r, 2 * r}, {}}};
  expect_refused(p, "suspension.kinds[0].placements[1]");
  p.kinds[0].placements = {{{1.5 * r, 4 * r, 2 * r}, {}}, {{3.5 * r, 9 * r, 2 * r}, {}}};
  expect_refused(p, "suspension.kinds[0].placements[1]");
  p.kinds[0].placements = {{{1.5 * r, 4 * r, 2 * r}, {}}, {{3.8 * r, 4 * r, 2 * r}, {}}};
  EXPECT_TRUE(plan_suspension_run(p).ok());
}

TEST(SuspensionPlan, NumericsAndFlowFieldsAreNamed) {
  SuspensionParams p = base_params();
  p.numerics.contact_range_dx = 0.0;
  expect_refused(p, "suspension.numerics.contact_range_dx");
  p = base_params();
  p.numerics.contact_strength = 1e4;
  expect_refused(p, "suspension.numerics.contact_strength");
  p = base_params();
  p.numerics.min_gap_dx = -1;
  expect_refused(p, "suspension.numerics.min_gap_dx");
  p = base_params();
  p.numerics.average_after_strain = 30.0;  // beyond max_strain 20
  expect_refused(p, "suspension.numerics.average_after_strain");
  p = base_params();
  p.numerics.flow.cells_per_radius = 1.0;
  expect_refused(p, "suspension.numerics.flow.cells_per_radius");
  p = base_params();
  p.kinds[0].cell.radius_m = -1.0;
  expect_refused(p, "suspension.kinds[0].cell.radius_m");
  p = base_params();
  p.kinds.clear();
  expect_refused(p, "suspension.kinds");
  p = base_params();
  p.capillary_number = 0.0;
  expect_refused(p, "suspension.capillary_number");
  p = base_params();
  p.numerics.flow.max_mach = 1e-3;  // the plan's Mach check, renamed
  expect_refused(p, "suspension.numerics.flow.");
}

}  // namespace
}  // namespace cellflow::scenes
