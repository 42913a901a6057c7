// Viscosity contrast of the shear-flow scene (ShearFlowParams::viscosity_ratio,
// paper section 7): with lambda = 1 nothing is marked; with lambda = 0.05 the
// nodes inside the cell relax with tau_in and the cell behaves as Roscoe's
// theory says a less viscous interior does (shared/validation/
// roscoe_elastic_sphere_shear.csv): it inclines closer to 45 degrees and, at
// Ca = 0.1, deforms more, its steady D closer to the lambda = 0 column; at
// Ca = 0.05 its inclination within 3 degrees of that column. Bad ratios are
// refused naming shear_flow.viscosity_ratio.
//
// Default suite: a coarse lattice (3 nodes per radius, 300 vertices) over 3
// strain units, where the inclination ordering already shows (D is not yet
// resolved there: +22 % above Roscoe for both ratios). SHEAR_FLOW_LONG (label
// long): the default resolution to the steady state.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "physics/scenes/shear_flow/shear_flow.h"

// ctest names the tests of both executables by suite and name: the long
// variant gets its own suite.
#ifdef SHEAR_FLOW_LONG
#define VISCOSITY_SUITE ShearFlowViscosityLong
#else
#define VISCOSITY_SUITE ShearFlowViscosity
#endif

namespace cellflow::scenes {
namespace {

// Roscoe's columns at the capillary numbers used here (the csv's rows).
struct RoscoeRow {
  double ca, d_lambda0, theta_lambda0, d_lambda1, theta_lambda1;
};
constexpr RoscoeRow kRoscoe005{0.05, 0.0624, 42.86, 0.0621, 41.45};
constexpr RoscoeRow kRoscoe01{0.1, 0.1239, 40.73, 0.1216, 38.07};

ShearFlowParams params(double ca, double lambda) {
  ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.capillary_number = ca;
  p.viscosity_ratio = lambda;
  p.numerics.threads = 1;
#ifndef SHEAR_FLOW_LONG
  p.cell.target_vertex_count = 300;
  p.numerics.cells_per_radius = 3.0;
  p.numerics.max_strain = 3.0;
  p.numerics.steady_tolerance = 0.0;
#endif
  return p;
}

ShearFlowResult run_ok(double ca, double lambda) {
  const ShearFlowResult r = run_shear_flow(params(ca, lambda));
  EXPECT_TRUE(r.status.ok()) << r.status.to_string();
  std::printf(
      "[ measured ] Ca %.3g lambda %.3g: D %.5f inclination %.3f deg (%s), %lld steps, lattice %.1f s, "
      "marking "
      "%lld updates (%lld exact) %.3f s, wall %.1f s, %lld nodes inside\n",
      ca, lambda, r.steady_taylor_deformation, r.steady_inclination_deg,
      std::string(stop_name(r.stop)).c_str(), static_cast<long long>(r.time_steps), r.lattice_s,
      static_cast<long long>(r.marking_updates), static_cast<long long>(r.marking_full), r.marking_s,
      r.wall_time_s, static_cast<long long>(r.marked_nodes));
  return r;
}

TEST(VISCOSITY_SUITE, LowInnerViscosityInclinesAndDeformsAsRoscoe) {
  const ShearFlowResult one = run_ok(0.1, 1.0);
  const ShearFlowResult low = run_ok(0.1, 0.05);
  ASSERT_TRUE(one.status.ok() && low.status.ok());
  // lambda = 1: no marking is computed at all.
  EXPECT_EQ(one.marking_updates, 0);
  EXPECT_EQ(one.marking_full, 0);
  EXPECT_EQ(one.marked_nodes, 0);
  EXPECT_EQ(one.setup.inner_relaxation_time, 1.0);
  // lambda = 0.05: tau_in = 1/2 + lambda (tau - 1/2); the nodes inside are
  // the cell's volume in lattice units (within 10 % at 3 nodes per radius).
  EXPECT_DOUBLE_EQ(low.setup.inner_relaxation_time, 0.525);
  EXPECT_GT(low.marking_updates, 0);
  const double volume_nodes = 4.0 / 3.0 * 3.14159265358979 * std::pow(6e-6 / low.setup.lattice_spacing_m, 3);
  EXPECT_NEAR(static_cast<double>(low.marked_nodes) / volume_nodes, 1.0, 0.1);
  // Roscoe: a less viscous interior inclines further toward 45 degrees (by
  // 2.66 degrees at Ca = 0.1); at least one degree of it must show.
  EXPECT_GT(low.steady_inclination_deg, one.steady_inclination_deg + 1.0);
#ifdef SHEAR_FLOW_LONG
  // ... and deforms more, its D closer to the lambda = 0 column.
  EXPECT_GT(low.steady_taylor_deformation, one.steady_taylor_deformation);
  EXPECT_LT(std::abs(low.steady_taylor_deformation - kRoscoe01.d_lambda0),
            std::abs(one.steady_taylor_deformation - kRoscoe01.d_lambda0));
  EXPECT_LT(std::abs(low.steady_inclination_deg - kRoscoe01.theta_lambda0),
            std::abs(one.steady_inclination_deg - kRoscoe01.theta_lambda0));
  EXPECT_EQ(low.stop, ShearFlowStop::kSteady);
  EXPECT_EQ(one.stop, ShearFlowStop::kSteady);
#endif
}

#ifdef SHEAR_FLOW_LONG
TEST(VISCOSITY_SUITE, InclinationAtCa005WithinThreeDegreesOfRoscoesLambda0) {
  const ShearFlowResult low = run_ok(0.05, 0.05);
  ASSERT_TRUE(low.status.ok());
  EXPECT_EQ(low.stop, ShearFlowStop::kSteady);
  EXPECT_NEAR(low.steady_inclination_deg, kRoscoe005.theta_lambda0, 3.0);
}
#endif

TEST(VISCOSITY_SUITE, BadRatiosAreRefusedNamingTheField) {
  for (double lambda : {0.0, -1.0, 1e3, std::nan(""), 0.005}) {
    ShearFlowParams p = params(0.1, lambda);
    const Status s = validate(p);
    ASSERT_FALSE(s.ok()) << lambda;
    EXPECT_NE(s.message().find("shear_flow.viscosity_ratio"), std::string::npos) << s.message();
  }
  // 0.01 is allowed at tau = 1 (tau_in = 0.505), not at tau = 0.75 (0.5025).
  ShearFlowParams p = params(0.1, 0.01);
  EXPECT_TRUE(validate(p).ok());
  p.numerics.relaxation_time = 0.75;
  const Status s = validate(p);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("shear_flow.viscosity_ratio"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("0.02"), std::string::npos) << s.message();  // the smallest ratio at tau 0.75
  const ShearFlowResult r = run_shear_flow(params(0.1, 0.0));
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace cellflow::scenes
