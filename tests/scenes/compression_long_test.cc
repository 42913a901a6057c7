// Heavy compression checks (LABELS long, `ctest -L long`): mesh convergence
// of the force at 50 % compression between 3000 and 12000 vertices, and the
// approach of F / F_Hertz to 1 under refinement. About 1 minute on 2 cores.
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
