// Golden end-to-end case (deal.II style): one coarse compression curve whose
// forces at three points were recorded when the scene was written. A change
// of the mesher, the element, the contact law or the solver that moves a
// number fails here; if the change is intended, regenerate:
//   build/tests/scenes/scenes_golden_compression_test --gtest_also_run_disabled_tests
//   --gtest_filter=*PrintGolden*
// and paste the printed values into kGoldenForces with the reason in the commit.
// The solve is converged to 1e-11 and the held rigid modes are a linear
// constraint, so the numbers do not depend on the Newton path: 6 or 12 load
// points, tolerance 1e-11 or 1e-12 agree to 1e-11 relative. 1e-6 relative is
// then a tight but safe band.
#include <gtest/gtest.h>

#include <cstdio>

#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

CompressionParams golden_case() {
  CompressionParams p;
  p.cell.radius_m = 8.6e-6;
  p.cell.material = {.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5};
  p.cell.target_vertex_count = 300;
  p.max_deformation = 0.6;
  p.load_points = 6;
  p.numerics.residual_tolerance = 1e-11;
  p.numerics.threads = 1;
  // The golden numbers pin the penalty law (the default): the augmented
  // Lagrangian's forces depend on its gap tolerance (1e-4 R); tests/scenes
  // compression_test checks its gaps, validation/fe/compare_cellflow.py its
  // forces against the FE references.
  p.numerics.contact_enforcement = ContactEnforcement::kPenalty;
  return p;
}

constexpr int kGoldenPoints[3] = {1, 3, 5};  // deformation 0.2, 0.4, 0.6
// Nodal-averaged volumetric term (elastic::VolumetricTerm::kNodalAverage, the
// quasi-static default): 18 %, 12 % and 6 % below the per-tet element.
// Regenerated when the mesher put a vertex at each pole (+2.9 %, -0.19 %,
// -0.73 % against the previous mesh orientation). Regenerated when the
// plates' penalty range began to shrink past deformation 0.15 (+0.11 %,
// +0.30 %, +0.71 %: the stand-off of the range, see plate_penalty_at).
constexpr double kGoldenForces[3] = {2.3063599425600384e-09, 9.9997485502114905e-09, 3.9425205747787976e-08};

TEST(GoldenCompression, ForcesAtThreePoints) {
  const QuasiStaticResult r = run_compression(golden_case());
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.curve.size(), 6u);
  for (int k = 0; k < 3; ++k) {
    const double force = r.curve[kGoldenPoints[k]].force_n;
    EXPECT_NEAR(force, kGoldenForces[k], 1e-6 * kGoldenForces[k]) << "point " << kGoldenPoints[k];
  }
}

TEST(GoldenCompression, DISABLED_PrintGolden) {
  const QuasiStaticResult r = run_compression(golden_case());
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  std::printf("constexpr double kGoldenForces[3] = {%.17g, %.17g, %.17g};\n", r.curve[1].force_n,
              r.curve[3].force_n, r.curve[5].force_n);
}

}  // namespace
}  // namespace cellflow::scenes
