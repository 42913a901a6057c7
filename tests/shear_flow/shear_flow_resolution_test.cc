// The lattice that resolves the cell's thickness (numerics.resolve_thickness):
// the predictor from Roscoe's lambda = 1 deformation, the plan that applies
// it (the small-Ca default unchanged), and on a coarse run the check that
// fires below kMinThicknessOverKernel and restarts finer.
#include "physics/scenes/shear_flow/shear_flow_resolution.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {
namespace {

TEST(ShearFlowResolution, RoscoeDeformationFollowsTheTable) {
  // rows of roscoe_elastic_sphere_shear.csv (D_lambda1)
  EXPECT_DOUBLE_EQ(roscoe_taylor_deformation_lambda1(0.05), 0.0621);
  EXPECT_DOUBLE_EQ(roscoe_taylor_deformation_lambda1(1.0), 0.6135);
  EXPECT_DOUBLE_EQ(roscoe_taylor_deformation_lambda1(2.0), 0.7656);
  // linear between rows: Ca 1.6 between (1.5, 0.7068) and (2, 0.7656)
  EXPECT_NEAR(roscoe_taylor_deformation_lambda1(1.6), 0.7068 + 0.2 * (0.7656 - 0.7068), 1e-12);
  // small-Ca limit D = 5/4 Ca below the table
  EXPECT_DOUBLE_EQ(roscoe_taylor_deformation_lambda1(0.004), 0.005);
  // beyond the table: rising, below 1
  double previous = roscoe_taylor_deformation_lambda1(2.0);
  for (const double ca : {2.5, 4.0, 10.0, 100.0}) {
    const double d = roscoe_taylor_deformation_lambda1(ca);
    EXPECT_GT(d, previous) << ca;
    EXPECT_LT(d, 1.0) << ca;
    previous = d;
  }
}

TEST(ShearFlowResolution, PredictedThicknessAndLattice) {
  // 2 a1 / R = 2 sqrt((1 - D) / (1 + D)): a sphere at Ca -> 0, the paper's
  // Ca = 2 cell (strain 1.8: a3 ~ 2.8 R, a1 ~ R / 2.8) about 0.73 R.
  EXPECT_NEAR(predicted_thickness_over_radius(1e-6), 2.0, 1e-5);
  EXPECT_NEAR(predicted_thickness_over_radius(2.0), 2.0 * std::sqrt(0.2344 / 1.7656), 1e-12);
  EXPECT_NEAR(predicted_thickness_over_radius(2.0), 0.729, 1e-3);
  // peskin4 (4 nodes): cpr = 1.1 x 0.75 x 4 / (2 a1 / R), up to a multiple of 0.5
  EXPECT_EQ(resolving_cells_per_radius(0.05, ibm::Kernel::kPeskin4), 2.0);  // the default 6 stays
  EXPECT_EQ(resolving_cells_per_radius(0.4, ibm::Kernel::kPeskin4), 2.5);
  EXPECT_EQ(resolving_cells_per_radius(1.0, ibm::Kernel::kPeskin4), 3.5);
  EXPECT_EQ(resolving_cells_per_radius(2.0, ibm::Kernel::kPeskin4), 5.0);  // the default 6 stays
  EXPECT_EQ(resolving_cells_per_radius(8.0, ibm::Kernel::kPeskin4), 8.5);  // extrapolated D 0.92
  // a narrower kernel needs a coarser lattice
  EXPECT_EQ(resolving_cells_per_radius(2.0, ibm::Kernel::kPeskin3), 3.5);
  // at the chosen lattice the prediction clears the margin
  for (const double ca : {0.8, 1.0, 1.6, 2.0}) {
    const double cpr = resolving_cells_per_radius(ca, ibm::Kernel::kPeskin4);
    EXPECT_GE(predicted_thickness_over_radius(ca) * cpr / 4.0, kThicknessMargin * kMinThicknessOverKernel)
        << ca;
  }
  // a measured thickness scales the lattice to the margin, at least 1.25 x
  EXPECT_EQ(refined_cells_per_radius(6.0, 0.3), 16.5);  // 6 x 0.825 / 0.3
  EXPECT_EQ(refined_cells_per_radius(6.0, 0.7), 7.5);   // 7.07 < 1.25 x 6
}

ShearFlowParams large_ca_params() {
  ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = 400;
  p.capillary_number = 2.0;
  p.numerics.threads = 1;  // beside other tests on a shared machine
  return p;
}

TEST(ShearFlowResolution, PlanRaisesTheLatticeAtLargeCaOnly) {
  ShearFlowParams p = large_ca_params();
  // Re_p 0.024 at Ca = 2, raised to 3 x 0.1 / (a3 / R)^2 = 0.04: 4 cells per
  // radius within the Mach limit (E = 10 Pa, Re_p 0.24, is not)
  p.cell.material.youngs_modulus_pa = 1.0;
  p.capillary_number = 0.05;
  StatusOr<ShearFlowSetup> small = plan_shear_flow(p);
  ASSERT_TRUE(small.ok()) << small.status().to_string();
  EXPECT_EQ(small->cells_per_radius, 6.0);  // the default, unchanged
  EXPECT_EQ(small->nx, 60);
  EXPECT_TRUE(small->resolution_note.empty());

  // the default lattice resolves the Ca = 2 cell (0.729 x 6 / 4 = 1.09 kernel widths predicted)
  p.capillary_number = 2.0;
  StatusOr<ShearFlowSetup> large = plan_shear_flow(p);
  ASSERT_TRUE(large.ok()) << large.status().to_string();
  EXPECT_EQ(large->cells_per_radius, 6.0);
  EXPECT_GE(large->predicted_thickness_over_kernel, kThicknessMargin * kMinThicknessOverKernel);
  // a coarser one is raised
  p.numerics.cells_per_radius = 4.0;
  large = plan_shear_flow(p);
  ASSERT_TRUE(large.ok()) << large.status().to_string();
  EXPECT_EQ(large->cells_per_radius, 5.0);
  EXPECT_EQ(large->nx, 50);  // 10 radii
  EXPECT_GE(large->predicted_thickness_over_kernel, kThicknessMargin * kMinThicknessOverKernel);
  StatusOr<PlannedShearFlow> planned = plan_shear_flow_run(p);
  ASSERT_TRUE(planned.ok());
  EXPECT_EQ(planned->params().numerics.cells_per_radius, 5.0);

  // a coarse lattice at small Ca (the sphere itself under-resolved) stays
  p.capillary_number = 0.2;  // predicted 2 a1 = 1.59 R: not flattened
  p.numerics.cells_per_radius = 3.0;
  EXPECT_EQ(plan_shear_flow(p)->cells_per_radius, 3.0);
  p.capillary_number = 1.0;  // 0.98 R: raised to 3.5
  EXPECT_EQ(plan_shear_flow(p)->cells_per_radius, 3.5);
  p.capillary_number = 2.0;

  // a finer lattice set by the user stays; resolve_thickness off keeps the coarse one
  p.numerics.cells_per_radius = 12.0;
  EXPECT_EQ(plan_shear_flow(p)->cells_per_radius, 12.0);
  p.numerics.cells_per_radius = 4.0;
  p.numerics.resolve_thickness = false;
  StatusOr<ShearFlowSetup> off = plan_shear_flow(p);
  ASSERT_TRUE(off.ok());
  EXPECT_EQ(off->cells_per_radius, 4.0);
  // 0.729 x 4 / 4 = 0.73
  EXPECT_LT(off->predicted_thickness_over_kernel, kThicknessMargin * kMinThicknessOverKernel);

  // the resolving lattice over the memory limit: the coarse one, with the reason
  p.numerics.resolve_thickness = true;
  p.numerics.memory_limit_bytes = 7e6;  // 40 x 60 x 20 (4.8 MB) fits, 50 x 75 x 25 (9.4 MB) does not
  StatusOr<ShearFlowSetup> refused = plan_shear_flow(p);
  ASSERT_TRUE(refused.ok()) << refused.status().to_string();
  EXPECT_EQ(refused->cells_per_radius, 4.0);
  EXPECT_NE(refused->resolution_note.find("cells_per_radius = 5"), std::string::npos)
      << refused->resolution_note;
}

TEST(ShearFlowResolution, StokesTargetAlsoBoundsTheLongCell) {
  // The paper's flow: gammadot = 4 / s, mu = eta gammadot / Ca, Re_p 1.4e-4.
  ShearFlowParams p = large_ca_params();
  for (const double ca : {0.05, 0.5, 2.0}) {
    p.capillary_number = ca;
    p.cell.material.youngs_modulus_pa = 2.0 * 1.48 * p.fluid_viscosity_pa_s * 4.0 / ca;
    StatusOr<ShearFlowSetup> s = plan_shear_flow(p);
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    EXPECT_NEAR(s->reynolds_number_physical, 1.44e-4, 1e-6) << ca;
    // Re_p = min(target, 3 target / (a3 / R)^2), (a3 / R)^2 = (1 + D) / (1 - D)
    const double d = roscoe_taylor_deformation_lambda1(ca);
    const double expected = std::min(0.1, 3.0 * 0.1 * (1.0 - d) / (1.0 + d));
    EXPECT_NEAR(s->reynolds_number_simulated, expected, 1e-12) << ca;
  }
  EXPECT_NEAR(plan_shear_flow(p)->reynolds_number_simulated, 0.0398, 1e-4);  // Ca = 2
  p.capillary_number = 0.05;
  p.cell.material.youngs_modulus_pa = 2.0 * 1.48 * p.fluid_viscosity_pa_s * 4.0 / 0.05;
  EXPECT_DOUBLE_EQ(plan_shear_flow(p)->reynolds_number_simulated, 0.1);  // the small-Ca default as before
  // a physical Re_p above the bound is kept (E = 10 Pa at Ca = 2: 0.243)
  p = large_ca_params();
  EXPECT_NEAR(plan_shear_flow(p)->reynolds_number_simulated, 0.243, 1e-3);
}

// A coarse Ca = 2 run whose predicted lattice the memory limit refuses: at 3
// cells per radius the undeformed sphere is 1.5 kernel widths thick and the
// flattening cell falls below 0.75 of them at strain ~2, which fires the
// check; the run restarts finer (within the limit) until its restarts are
// used, then warns.
ShearFlowParams coarse_large_ca_params() {
  ShearFlowParams p = large_ca_params();
  p.numerics.cells_per_radius = 3.0;
  p.numerics.box_x_radii = 8.0;
  p.numerics.box_y_radii = 8.0;
  p.numerics.box_z_radii = 4.0;
  p.numerics.memory_limit_bytes = 2.5e6;  // 5 cells per radius needs 40 x 40 x 20 nodes: refused
  p.numerics.max_strain = 4.0;
  p.numerics.steady_tolerance = 0.0;
  return p;
}

TEST(ShearFlowResolution, ThinCellRestartsOnAFinerLattice) {
  const ShearFlowParams p = coarse_large_ca_params();
  std::vector<ShearFlowRestart> seen;
  std::vector<ShearFlowSample> samples;
  ShearFlowCallbacks cb;
  cb.on_restart = [&](const ShearFlowRestart& r) {
    seen.push_back(r);
    samples.clear();  // the finer run reports from its first sample again
  };
  cb.on_sample = [&](const ShearFlowSample& s) { samples.push_back(s); };
  const ShearFlowResult r = run_shear_flow(p, cb);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.restarts.size(), static_cast<std::size_t>(kMaxResolutionRestarts));
  ASSERT_EQ(seen.size(), r.restarts.size());
  double cpr = 3.0;
  for (const ShearFlowRestart& restart : r.restarts) {
    EXPECT_EQ(restart.old_cells_per_radius, cpr);
    EXPECT_LT(restart.thickness_over_kernel, kMinThicknessOverKernel);
    EXPECT_GE(restart.new_cells_per_radius, 1.25 * cpr);
    EXPECT_EQ(restart.setup.cells_per_radius, restart.new_cells_per_radius);
    EXPECT_GT(restart.abandoned_wall_time_s, 0.0);
    cpr = restart.new_cells_per_radius;
  }
  // the result is the finest lattice's, from step 0 to the end
  EXPECT_EQ(r.setup.cells_per_radius, cpr);
  ASSERT_FALSE(samples.empty());
  EXPECT_EQ(samples.front().time_step, 0);
  EXPECT_EQ(samples.size(), r.samples.size());
  EXPECT_NEAR(r.samples.back().strain_units, 4.0, 0.05);
  EXPECT_GT(r.wall_time_s, r.restarts.back().abandoned_wall_time_s);
  // restarts used up, the cell still thinner than the limit: a warning says so
  bool warned = false, noted = false;
  for (const std::string& w : r.warnings) {
    warned = warned || w.find("under-resolved") != std::string::npos;
    noted = noted || w.find("was refused") != std::string::npos;
  }
  EXPECT_LT(r.min_thickness_over_kernel, kMinThicknessOverKernel);
  EXPECT_EQ(warned, r.thickness_over_kernel < kMinThicknessOverKernel);
  EXPECT_TRUE(noted);  // the refused predicted lattice
}

TEST(ShearFlowResolution, RecordingCallerWithoutRestartKeepsItsLattice) {
  ShearFlowParams p = coarse_large_ca_params();
  int samples = 0;
  ShearFlowCallbacks cb;
  cb.on_sample = [&](const ShearFlowSample&) { ++samples; };  // records, takes no restart
  const ShearFlowResult r = run_shear_flow(p, cb);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  EXPECT_TRUE(r.restarts.empty());
  EXPECT_EQ(r.setup.cells_per_radius, 3.0);
  EXPECT_EQ(samples, static_cast<int>(r.samples.size()));
  EXPECT_LT(r.thickness_over_kernel, kMinThicknessOverKernel);
  ASSERT_FALSE(r.warnings.empty());
}

}  // namespace
}  // namespace cellflow::scenes
