// Heavier calibration checks (ctest -L long): the synthetic recovery of the
// brief on 600 vertices with the library on its own mesh (reference radius
// 10 um: the data's 8.6 um mesh is another TetGen realisation, so mesh
// scatter enters as model error), and the interpolation error on 1000 vertices.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "tests/calibration/calibration_test_util.h"

namespace cellflow::calibration {
namespace {

using testing::kRadius;

TEST(CalibrationLong, RecoversEWAndContactWithTheLibraryOnItsOwnMesh) {
  const auto start = std::chrono::steady_clock::now();
  struct Truth {
    double e, w, offset;
    unsigned seed;
  };
  const Truth truths[] = {{150.0, 0.5, 0.03 * kRadius, 31u}, {120.0, 0.25, -0.03 * kRadius, 32u}};
  std::vector<MeasuredCurve> curves;
  for (const Truth& t : truths) {
    const scenes::QuasiStaticResult run = testing::run_plates(t.e, t.w, 600, 40, 0.75);
    ASSERT_TRUE(run.status.ok()) << run.status.to_string();
    curves.push_back(testing::measured_from(run, kRadius, t.offset, 0.03, t.seed));
  }
  CurveLibrary library;  // reference radius 10 um
  FitOptions options;
  options.numerics = testing::coarse_numerics(600, 30);
  options.joint = false;
  StatusOr<FitResult> fit = fit_curves(curves, options, library);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  EXPECT_LE(fit->simulations_run, 15);
  for (const std::string& note : fit->notes) std::printf("note: %s\n", note.c_str());
  for (std::size_t c = 0; c < 2; ++c) {
    const ParameterFit& f = fit->per_curve[c];
    std::printf(
        "truth E %.0f w %.3f offset %.3f R: E %.2f [%.2f, %.2f] w %.4f [%.4f, %.4f] offset %.4f R, "
        "Hertz E %.1f\n",
        truths[c].e, truths[c].w, truths[c].offset / kRadius, f.youngs_modulus_pa.value,
        f.youngs_modulus_pa.lower, f.youngs_modulus_pa.upper, f.mooney_rivlin_w.value,
        f.mooney_rivlin_w.lower, f.mooney_rivlin_w.upper, f.curves[0].contact_offset_m.value / kRadius,
        f.hertz_youngs_modulus_pa.value_or(-1));
    EXPECT_NEAR(f.youngs_modulus_pa.value / truths[c].e, 1.0, 0.03);
    EXPECT_NEAR(f.mooney_rivlin_w.value, truths[c].w, 0.07);
    EXPECT_NEAR(f.curves[0].contact_offset_m.value, truths[c].offset, 0.02 * kRadius);
  }
  std::printf("%d simulations, run time %.1f s\n", fit->simulations_run,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

TEST(CalibrationLong, InterpolationErrorOnAThousandVertices) {
  CurveLibrary library(testing::same_mesh_options());
  CurveKey key;
  key.numerics = testing::coarse_numerics(1000, 30);
  // On 1000 vertices the curves at w = 0 and 0.125 stop converging at 0.65:
  // ask for 0.6 so that every grid curve is a node.
  StatusOr<CurveInterpolant> model = library.grid_interpolant(key, 0.6);
  ASSERT_TRUE(model.ok()) << model.status().to_string();
  std::printf("interpolant: w in [%.3f, %.3f], deformation up to %.3f\n", model->w_min(), model->w_max(),
              model->max_deformation());
  EXPECT_EQ(model->w_min(), 0.0);
  const double modulus = 100.0;
  // Not below w = 0.25: there the grid curves themselves approach the
  // non-convergence at large deformation that issue "Contact scenes accurate
  // over the whole curve" is about (measured on 1000 vertices to 0.625: 2.5 %
  // at w = 0.03125 with the grid halved below 0.125, 4.4 % at 0.0625 before;
  // the direct run at w = 0.09375 did not converge). The target is not met
  // there and this test does not pretend it is.
  for (const double w : {0.375 + 0.0625, 0.6, 0.9375}) {
    const scenes::QuasiStaticResult direct = testing::run_plates(modulus, w, 1000, 30, 0.75);
    ASSERT_TRUE(direct.status.ok()) << direct.status.to_string();
    double worst = 0.0;
    for (const scenes::CurvePoint& p : direct.curve) {
      if (p.deformation < 0.05 - 1e-12 || p.deformation > model->max_deformation() + 1e-12) continue;
      const double f = p.force_n / (modulus * kRadius * kRadius);
      worst = std::max(worst, std::abs(model->force_scaled(w, p.deformation) / f - 1.0));
    }
    std::printf("1000 vertices, w = %.4f: max relative error (cubic in w) over 0.05-%.3f: %.3f %%\n", w,
                model->max_deformation(), 100 * worst);
    // The target: 0.5 % of the force over the fitted range.
    EXPECT_LT(worst, 0.005);
  }
}

}  // namespace
}  // namespace cellflow::calibration
