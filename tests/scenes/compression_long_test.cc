// Heavy compression checks (LABELS long, `ctest -L long`): where the nu = 0.45
// curve ends, mesh convergence of the force at 50 % compression between 3000
// and 12000 vertices, and the approach of F / F_Hertz to 1 under refinement. About 1 minute on 2 cores.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

constexpr double kRadius = 8.6e-6;

CompressionParams cell(int vertices, double w, double max_deformation, int load_points) {
  CompressionParams p;
  p.cell.radius_m = kRadius;
  p.cell.material = {.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = w};
  p.cell.target_vertex_count = vertices;
  p.max_deformation = max_deformation;
  p.load_points = load_points;
  return p;
}

const CurvePoint& at(const QuasiStaticResult& r, double deformation) {
  for (const CurvePoint& p : r.curve) {
    if (std::abs(p.deformation - deformation) < 1e-9) return p;
  }
  ADD_FAILURE() << "no point at deformation " << deformation;
  return r.curve.front();
}

double ratio(const CurvePoint& p) {
  return p.force_n / p.hertz_force_n;
}

// The requirement: less than 2 % change. Measured 0.34 % with the
// nodal-averaged volumetric term and a mesh vertex at each pole (1.66 %
// before the poles were put on vertices; 2.85 % with the per-tet term).
// The stability matrix's compression/grid/w1-nu0.45 (3000 vertices, 30
// points to 0.9, E = 1 kPa): CalculiX's axisymmetric CAX8 reference of the
// same energy (validation/fe/curves/plates_w1_nu0.45_L2_cax8.csv) gives
// F(0.87) = 1.82e-6 N with V/V0 0.73, and at 0.9 min element J 0.176: the
// contact centre's pressure nears kappa = 3.3 E and its volume collapses
// (eq. 5). cellflow follows it to 0.897, where its equilibrium path loses
// stability (Newton fails at any step) with J = 0.18 < 0.2 already at the
// sub-step 0.8925. The run must end there naming the J guard, in far less
// time than the 10 halvings x 200 Newton iterations it spent before (123 s).
TEST(CompressionLong, Nu045CurveEndsAtTheVolumeCollapseNearDeformation09) {
  CompressionParams p = cell(3000, 1.0, 0.9, 30);
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.45, .mooney_rivlin_w = 1.0};
  p.numerics.threads = 1;
  const QuasiStaticResult r = run_compression(p);
  ASSERT_EQ(r.status.code(), StatusCode::kNumericalFailure) << r.status.to_string();
  EXPECT_NE(r.status.message().find("is compressed to J = "), std::string::npos) << r.status.message();
  ASSERT_EQ(r.curve.size(), 29u);
  const CurvePoint& last = at(r, 0.87);
  int newton = 0;
  for (const CurvePoint& c : r.curve) newton += c.newton_iterations;
  std::printf("nu 0.45: F(0.87) = %.4g N (CalculiX CAX8 L2 1.8245e-06 N), Newton %d\n", last.force_n, newton);
  EXPECT_LT(std::abs(last.force_n / 1.8245e-6 - 1.0), 0.03);
}

TEST(CompressionLong, MeshConvergenceAtHalfCompression) {
  const QuasiStaticResult fine = run_compression(cell(3000, 0.5, 0.5, 10));
  const QuasiStaticResult finer = run_compression(cell(12000, 0.5, 0.5, 10));
  ASSERT_TRUE(fine.status.ok()) << fine.status.to_string();
  ASSERT_TRUE(finer.status.ok()) << finer.status.to_string();
  const double change = std::abs(at(fine, 0.5).force_n / at(finer, 0.5).force_n - 1.0);
  std::printf("force at 0.5: 3000 -> 12000 vertices changes by %.4f\n", change);
  EXPECT_LT(change, 0.02);
}

// Measured (pole vertices): 3000 vertices 1.073 / 1.114 / 1.153, 12000
// vertices 1.061 / 1.084 / 1.149 at eps = 0.02 / 0.05 / 0.1.
TEST(CompressionLong, SmallDeformationLimitUnderRefinement) {
  const QuasiStaticResult coarse = run_compression(cell(3000, 1.0, 0.1, 10));
  const QuasiStaticResult fine = run_compression(cell(12000, 1.0, 0.1, 10));
  ASSERT_TRUE(coarse.status.ok()) << coarse.status.to_string();
  ASSERT_TRUE(fine.status.ok()) << fine.status.to_string();
  for (double eps : {0.02, 0.05, 0.1}) {
    const double rc = ratio(at(coarse, eps)), rf = ratio(at(fine, eps));
    std::printf("F/F_Hertz at %.2f: 3000 vertices %.4f, 12000 vertices %.4f\n", eps, rc, rf);
    // refinement moves the ratio towards 1 from above
    EXPECT_GT(rf, 1.0);
    EXPECT_LT(rf, rc);
  }
}

}  // namespace
}  // namespace cellflow::scenes
