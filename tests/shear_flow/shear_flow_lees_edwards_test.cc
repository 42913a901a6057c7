// The shear-flow scene with Lees-Edwards boundaries (numerics.boundaries =
// kLeesEdwards, physics/lb/lees_edwards.h; the lattice part is tested in
// tests/lb/lees_edwards_test.cc): a coarse cell in a box 6 R high deforms
// like the one in the walled 15 R box and stays centred; a cell whose
// kernel stencil reaches the plane stops with an error naming box_y_radii.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {
namespace {

constexpr double kRadius = 6e-6;  // m

// The coarse cell of the other flow tests (E = 10 Pa in water), 3 cells per
// radius and 300 vertices: about a second per strain unit.
ShearFlowParams coarse_params(double capillary_number, ShearFlowBoundaries boundaries, double box_y_radii) {
  ShearFlowParams p;
  p.cell.radius_m = kRadius;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = 300;
  p.capillary_number = capillary_number;
  p.numerics.cells_per_radius = 3.0;
  p.numerics.box_y_radii = box_y_radii;
  p.numerics.boundaries = boundaries;
  p.numerics.max_strain = 2.0;
  p.numerics.steady_tolerance = 0.0;  // the full 2 strain units
  p.numerics.steady_window_strain = 0.5;
  p.numerics.threads = 1;
  return p;
}

double max_centroid_drift(const ShearFlowResult& r) {
  double drift = 0.0;
  for (const ShearFlowSample& s : r.samples) {
    drift = std::max(
        drift, std::hypot(s.centroid_m[0] - 0.5 * r.setup.box_m[0], s.centroid_m[1] - 0.5 * r.setup.box_m[1],
                          s.centroid_m[2] - 0.5 * r.setup.box_m[2]));
  }
  return drift;
}

// Measured at strain 2: D 0.0834 (Lees-Edwards, 6 R) against 0.0826 (walls,
// 15 R), ratio 1.009; the inclinations differ by 1.2 degrees at this coarse,
// not yet steady state (not checked; at the default resolution the steady
// values differ by 0.1 degree and D by 2.5 %, docs/accuracy/shear_flow.md).
TEST(ShearFlowLeesEdwards, SmallBoxDeformsLikeTheWalledBox) {
  const double ca = 0.05;
  const ShearFlowResult walls = run_shear_flow(coarse_params(ca, ShearFlowBoundaries::kWalls, 15.0));
  const ShearFlowResult le = run_shear_flow(coarse_params(ca, ShearFlowBoundaries::kLeesEdwards, 6.0));
  ASSERT_TRUE(walls.status.ok()) << walls.status.to_string();
  ASSERT_TRUE(le.status.ok()) << le.status.to_string();
  EXPECT_EQ(le.setup.ny * 5, walls.setup.ny * 2);  // 6 R against 15 R
  const double ratio = le.steady_taylor_deformation / walls.steady_taylor_deformation;
  std::printf(
      "walls 15 R: D %.5f incl %.2f (%.1f s); Lees-Edwards 6 R: D %.5f incl %.2f (%.1f s), drift %.2e R\n",
      walls.steady_taylor_deformation, walls.steady_inclination_deg, walls.wall_time_s,
      le.steady_taylor_deformation, le.steady_inclination_deg, le.wall_time_s,
      max_centroid_drift(le) / kRadius);
  EXPECT_NEAR(ratio, 1.0, 0.02);
  EXPECT_LT(max_centroid_drift(le), 0.01 * kRadius);
}

// The smallest box the validation allows with Lees-Edwards planes, 2 + 4 / 3
// R high at 3 cells per radius (the undeformed cell and its kernel reach,
// 2 dx beyond the vertices, just fit): as the cell deforms its stencil
// reaches y = 0 or H and the run stops.
TEST(ShearFlowLeesEdwards, CellReachingThePlaneStopsWithAClearError) {
  ShearFlowParams p = coarse_params(0.2, ShearFlowBoundaries::kLeesEdwards, 2.0 + 4.0 / 3.0);
  ASSERT_TRUE(validate(p).ok()) << validate(p).to_string();
  p.numerics.box_y_radii = 2.0 + 4.0 / 3.0 - 0.01;
  EXPECT_NE(validate(p).message().find("shear_flow.numerics.box_y_radii"), std::string::npos);
  p.numerics.box_y_radii = 2.0 + 4.0 / 3.0;
  const ShearFlowResult r = run_shear_flow(p);
  ASSERT_EQ(r.stop, ShearFlowStop::kFailed) << r.status.to_string();
  EXPECT_EQ(r.status.code(), StatusCode::kNumericalFailure);
  EXPECT_NE(r.status.message().find("Lees-Edwards plane"), std::string::npos) << r.status.message();
  EXPECT_NE(r.status.message().find("shear_flow.numerics.box_y_radii"), std::string::npos);
  ASSERT_FALSE(r.samples.empty());
  std::printf("stopped at strain %.2f (%.1f s): %s\n", r.samples.back().strain_units, r.wall_time_s,
              r.status.message().c_str());
}

TEST(ShearFlowLeesEdwards, BoundaryNames) {
  EXPECT_EQ(boundaries_name(ShearFlowBoundaries::kWalls), "walls");
  EXPECT_EQ(boundaries_name(ShearFlowBoundaries::kLeesEdwards), "lees_edwards");
  EXPECT_EQ(*parse_boundaries("lees_edwards", "f"), ShearFlowBoundaries::kLeesEdwards);
  EXPECT_EQ(*parse_boundaries("walls", "f"), ShearFlowBoundaries::kWalls);
  const StatusOr<ShearFlowBoundaries> bad = parse_boundaries("periodic", "shear_flow.numerics.boundaries");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("shear_flow.numerics.boundaries"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::scenes
