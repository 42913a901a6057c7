// Suspension validation (issue 15, label long; hours on two cores at the
// default resolution): the relative viscosity at volume fraction 0.11 and
// small Ca against the rigid-sphere value 1 + 2.5 phi + 6.2 phi^2, shear
// thinning as Ca rises, and the mean D at phi 0.22, Ca 0.2 above the single
// cell's D at that Ca.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/suspension/suspension.h"
#include "physics/scenes/suspension/suspension_statistics.h"

namespace cellflow::scenes {
namespace {

cell::CellParams validation_cell() {
  cell::CellParams c;
  c.radius_m = 6e-6;
  c.material.youngs_modulus_pa = 10.0;
  c.material.poisson_ratio = 0.48;
  c.target_vertex_count = kSuspensionDefaultVertexCount;
  return c;
}

SuspensionResult run_box(double phi, double ca, double box_y_radii = 8.0) {
  SuspensionParams p;
  SuspendedCellKind kind;
  kind.cell = validation_cell();
  kind.volume_fraction = phi;
  p.kinds.push_back(kind);
  p.capillary_number = ca;
  p.numerics.flow.box_y_radii = box_y_radii;
  p.numerics.flow.snapshot_every_strain = 0.0;
  p.numerics.flow.threads = 0;
  StatusOr<PlannedSuspension> planned = plan_suspension_run(p);
  EXPECT_TRUE(planned.ok()) << planned.status().to_string();
  if (!planned.ok()) return {};
  SuspensionResult r = run_suspension(*planned);
  EXPECT_TRUE(r.status.ok()) << r.status.to_string();
  std::printf("phi %.2f (N %d, placed %.4f) Ca %.3f H %.0f R: <D> %.4f +- %.4f, eta_r %.4f +- %.4f, %.0f s\n",
              phi, r.setup.cell_count, r.setup.volume_fraction, ca, box_y_radii, r.average_taylor_deformation,
              r.average_taylor_deformation_error, r.average_relative_viscosity,
              r.average_relative_viscosity_error, r.wall_time_s);
  return r;
}

TEST(SuspensionValidation, RelativeViscosityNearRigidSpheresAndShearThinning) {
  const SuspensionResult stiff = run_box(0.11, 0.02);
  const double rigid = rigid_sphere_relative_viscosity(stiff.setup.volume_fraction);
  EXPECT_NEAR(stiff.average_relative_viscosity, rigid, 0.10 * rigid);
  const SuspensionResult soft = run_box(0.11, 0.2);
  EXPECT_LT(soft.average_relative_viscosity + soft.average_relative_viscosity_error,
            stiff.average_relative_viscosity - stiff.average_relative_viscosity_error);
}

TEST(SuspensionValidation, MeanDeformationAboveTheSingleCell) {
  const SuspensionResult dense = run_box(0.22, 0.2);
  ShearFlowParams single;
  single.cell = validation_cell();
  single.capillary_number = 0.2;
  single.numerics.threads = 0;
  const ShearFlowResult one = run_shear_flow(single);
  ASSERT_TRUE(one.status.ok()) << one.status.to_string();
  std::printf("single cell Ca 0.2: D %.4f\n", one.steady_taylor_deformation);
  EXPECT_GT(dense.average_taylor_deformation - 2.0 * dense.average_taylor_deformation_error,
            one.steady_taylor_deformation);
}

}  // namespace
}  // namespace cellflow::scenes
