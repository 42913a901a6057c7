// Shear-flow scene against Roscoe's theory of an elastic sphere in simple
// shear (shared/validation/README.md, roscoe_elastic_sphere_shear.csv). The
// scene's cell has the fluid's viscosity inside (viscosity ratio lambda = 1,
// as in the paper: the IBM does not subtract the interior fluid), so the
// references are the small-Ca limit D = (5/4) Ca, theta = pi/4 - (5/4) Ca
// (lambda = 1), tank treading at gammadot / 2 for a rigid sphere.
//
// Resolution. Without the hydrodynamic radius correction
// (numerics.hydrodynamic_radius_offset = 0) D converges to (5/4) Ca from
// above, about 3 x 0.4 dx / R too large (+41 % at 4 cells per radius and
// 1000 vertices, +20 % at the default 6 and 3000): the point cloud acts on
// the fluid like a larger sphere. The default offset (0.4 dx for peskin4)
// scales the markers to remove that (docs/accuracy/shear_flow.md).
// The default suite runs the coarse variant (4 cells per radius, 1000
// vertices, 4 strain units) with the band measured for it; the build with
// SHEAR_FLOW_LONG (label long) runs the default numerics (6 cells per radius,
// 3000 vertices) to the steady state at Ca = 0.02, 0.05 and 0.1 against the
// target, D within 5 % of (5/4) Ca and the inclination within 1 degree of
// pi/4 - (5/4) Ca.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {
namespace {

constexpr double kRadius = 6e-6;  // m

#ifdef SHEAR_FLOW_LONG
constexpr double kCellsPerRadius = ShearFlowNumerics{}.cells_per_radius;  // the default, 6
constexpr int kVertices = kFlowDefaultVertexCount;                        // the default, 3000
constexpr double kMaxDeviationD = 0.05;  // the target: within 5 % of (5/4) Ca
constexpr double kMinRatioD = 1.0 - kMaxDeviationD;
constexpr double kMaxRatioD = 1.0 + kMaxDeviationD;
constexpr double kMaxInclinationErrorDeg = 1.0;
constexpr double kMaxStrain = 20.0;    // Ca 0.05, 0.1 steady at strain 9; Ca 0.02 runs on (band 0.8 %)
constexpr double kWindowStrain = 2.0;  // the default steady window
#else
constexpr double kCellsPerRadius = 4.0;
constexpr int kVertices = 1000;
// Coarse variant, 4 strain units: measured D / (5/4 Ca) = 1.117 (Ca = 0.02)
// and 1.076 (Ca = 0.05; without the radius correction 1.46 and 1.41), the
// inclination 0.12 and 1.02 degrees below pi/4 - (5/4) Ca.
constexpr double kMinRatioD = 1.0;
constexpr double kMaxRatioD = 1.2;
constexpr double kMaxInclinationErrorDeg = 2.0;
constexpr double kMaxStrain = 4.0;
constexpr double kWindowStrain = 1.0;
#endif

// E = 10 Pa (mu = 3.38 Pa) in water; Ca fixes the shear rate.
ShearFlowParams flow_params(double capillary_number) {
  ShearFlowParams p;
  p.cell.radius_m = kRadius;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = kVertices;
  p.capillary_number = capillary_number;
  p.numerics.cells_per_radius = kCellsPerRadius;
  p.numerics.steady_window_strain = kWindowStrain;
  // One thread: the tests run beside others, where OpenMP barriers of a
  // second thread that has no core to itself cost more than they gain.
  p.numerics.threads = 1;
  return p;
}

// Steady D against (5/4) Ca and the inclination against pi/4 - (5/4) Ca.
void check_small_capillary_number(double ca) {
  ShearFlowParams p = flow_params(ca);
  p.numerics.max_strain = kMaxStrain;
  const ShearFlowResult r = run_shear_flow(p);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_TRUE(r.stop == ShearFlowStop::kSteady || r.stop == ShearFlowStop::kMaxStrain);
  const double d_ref = small_ca_taylor_deformation(ca);
  const double theta_ref = small_ca_inclination_deg_lambda1(ca);
  const double ratio = r.steady_taylor_deformation / d_ref;
  EXPECT_GE(ratio, kMinRatioD) << "D = " << r.steady_taylor_deformation << ", (5/4) Ca = " << d_ref;
  EXPECT_LE(ratio, kMaxRatioD) << "D = " << r.steady_taylor_deformation << ", (5/4) Ca = " << d_ref;
  EXPECT_NEAR(r.steady_inclination_deg, theta_ref, kMaxInclinationErrorDeg);
  // The window mean is steady: the means of the last two 1-strain windows differ by less than 2 %.
  EXPECT_LT(r.steady_relative_change, 0.02);
  std::printf(
      "Ca %.3g (%g cells/R, %d vertices): D %.5f = %.3f x (5/4) Ca, inclination %.2f deg (ref %.2f), "
      "tank treading %.4f gammadot, stop %s at strain %.2f, %.1f s\n",
      ca, kCellsPerRadius, kVertices, r.steady_taylor_deformation, ratio, r.steady_inclination_deg, theta_ref,
      r.tank_treading_frequency_per_s / r.setup.shear_rate_per_s, std::string(stop_name(r.stop)).c_str(),
      r.samples.back().strain_units, r.wall_time_s);
}

std::string ca_name(const ::testing::TestParamInfo<double>& param_info) {
  if (param_info.param == 0.02) return "Ca0p02";
  return param_info.param == 0.05 ? std::string("Ca0p05") : std::string("Ca0p1");
}

// The long build registers its suite under another name, so that ctest
// (which knows tests by name) keeps the two variants and their labels apart.
#ifdef SHEAR_FLOW_LONG
class SmallCapillaryNumberLong : public ::testing::TestWithParam<double> {};
TEST_P(SmallCapillaryNumberLong, SteadyDeformationAndInclination) {
  check_small_capillary_number(GetParam());
}
INSTANTIATE_TEST_SUITE_P(Roscoe, SmallCapillaryNumberLong, ::testing::Values(0.02, 0.05, 0.1), ca_name);
#else
class SmallCapillaryNumber : public ::testing::TestWithParam<double> {};
TEST_P(SmallCapillaryNumber, SteadyDeformationAndInclination) {
  check_small_capillary_number(GetParam());
}
INSTANTIATE_TEST_SUITE_P(Roscoe, SmallCapillaryNumber, ::testing::Values(0.02, 0.05), ca_name);
#endif

#ifndef SHEAR_FLOW_LONG
// A stiff cell (Ca = 0.001) at the centre of the Couette flow: it must stay
// centred (drift below 1 % of R) and turn like a rigid sphere, at gammadot / 2
// within 5 %. Re_p = 0.02 keeps the explicit update stable (stiffness ratio
// 1.6 against the peskin4 limit 2.5; at Re_p = 0.1 it is 8.2 and blows up).
TEST(ShearFlowValidation, StiffCellStaysCentredAndRotatesAtHalfTheShearRate) {
  ShearFlowParams p = flow_params(0.001);
  p.numerics.cells_per_radius = 4.0;
  p.cell.target_vertex_count = 1000;
  p.numerics.target_reynolds_number = 0.02;
  p.numerics.max_strain = 1.5;
  p.numerics.steady_tolerance = 0.0;  // run the full 1.5 strain units
  const ShearFlowResult r = run_shear_flow(p);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.stop, ShearFlowStop::kMaxStrain);
  const double centre[3] = {0.5 * r.setup.box_m[0], 0.5 * r.setup.box_m[1], 0.5 * r.setup.box_m[2]};
  double drift = 0.0;
  for (const ShearFlowSample& s : r.samples) {
    const double d =
        std::hypot(s.centroid_m[0] - centre[0], s.centroid_m[1] - centre[1], s.centroid_m[2] - centre[2]);
    drift = std::max(drift, d);
  }
  EXPECT_LT(drift, 0.01 * kRadius);
  const double rotation = r.tank_treading_frequency_per_s / r.setup.shear_rate_per_s;
  EXPECT_NEAR(rotation, 0.5, 0.05 * 0.5);
  // A stiff cell hardly deforms: D = (5/4) Ca = 0.00125 up to the coarse-lattice factor.
  EXPECT_LT(r.steady_taylor_deformation, 0.0025);
  std::printf("stiff cell: drift %.2e R, rotation %.4f gammadot, D %.5f, stiffness ratio %.3g, %.1f s\n",
              drift / kRadius, rotation, r.steady_taylor_deformation, r.stiffness_ratio, r.wall_time_s);
}

// The first-order error the hydrodynamic radius correction removes: without
// it (offset 0) D falls from 4 to 6 cells per radius by at least a quarter of
// its excess (measured: +0.41 -> +0.26 at 1000 vertices); with the default
// offset the excess at 4 cells per radius is at most half the uncorrected
// one there (3 x 0.4 dx / R predicts 0.41 -> 0.11).
TEST(ShearFlowValidation, RefiningTheLatticeApproachesRoscoe) {
  const double ca = 0.05;
  double deviation[3] = {0.0, 0.0, 0.0};
  const double resolutions[3] = {4.0, 6.0, 4.0};
  const double offsets[3] = {0.0, 0.0, -1.0};
  for (int i = 0; i < 3; ++i) {
    ShearFlowParams p = flow_params(ca);
    p.numerics.cells_per_radius = resolutions[i];
    p.numerics.hydrodynamic_radius_offset = offsets[i];
    p.numerics.max_strain = 2.5;
    p.numerics.steady_tolerance = 0.0;
    const ShearFlowResult r = run_shear_flow(p);
    ASSERT_TRUE(r.status.ok()) << r.status.to_string();
    deviation[i] = r.steady_taylor_deformation / small_ca_taylor_deformation(ca) - 1.0;
    std::printf("Ca %.3g, %g cells/R, offset %g: D / (5/4 Ca) - 1 = %+.3f (%.1f s)\n", ca, resolutions[i],
                radius_offset(p.numerics), deviation[i], r.wall_time_s);
  }
  EXPECT_GT(deviation[1], 0.0);
  EXPECT_LT(deviation[1], 0.75 * deviation[0]);
  EXPECT_LT(std::abs(deviation[2]), 0.5 * deviation[0]);
}
#endif

}  // namespace
}  // namespace cellflow::scenes
