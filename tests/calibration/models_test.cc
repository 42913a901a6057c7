// Hertz models, the closed-form E, the 1-D minimiser and the contact-point
// search: exact properties, no simulation.
#include "physics/calibration/models.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace cellflow::calibration {
namespace {

constexpr double kRadius = 8.6e-6;

// shared/validation/README.md: nu = 0.5, F/(E R^2) = 0.0199, 0.0562, 0.159, 0.292 at eps = 0.05 ... 0.3
TEST(HertzModels, PlatesMatchTheValidationTable) {
  const double eps[] = {0.05, 0.1, 0.2, 0.3};
  const double table[] = {0.0199, 0.0562, 0.159, 0.292};
  for (int k = 0; k < 4; ++k) {
    const double f = hertz_plates_force_n(1.0, 0.5, kRadius, eps[k] * 2 * kRadius) / (kRadius * kRadius);
    EXPECT_NEAR(f / table[k], 1.0, 3e-3) << "eps " << eps[k];  // the table has 3 digits
  }
}

// plates = two sphere-on-flat contacts of delta/2 each; paraboloid = sphere-on-flat formula
TEST(HertzModels, PlatesAreTwoSphereOnFlatContactsAndTheParaboloidIsOne) {
  for (const double delta : {0.1e-6, 1e-6, 3e-6}) {
    const double plates = hertz_plates_force_n(150.0, 0.48, kRadius, delta);
    EXPECT_NEAR(hertz_sphere_on_flat_force_n(150.0, 0.48, kRadius, delta / 2) / plates, 1.0, 1e-12);
    EXPECT_NEAR(hertz_paraboloid_force_n(150.0, 0.48, kRadius, delta / 2) / plates, 1.0, 1e-12);
  }
  EXPECT_EQ(hertz_paraboloid_force_n(150.0, 0.48, 1e-6, -1e-7), 0.0);
  EXPECT_EQ(hertz_plates_force_n(150.0, 0.48, kRadius, -1e-7), 0.0);
}

// A probe of radius -> infinity is a plate: probe-on-cell-on-plate -> plates
TEST(HertzModels, WideProbeIsAPlateAndProbeForceIsLinearInE) {
  const double delta = 2e-6;
  EXPECT_NEAR(hertz_probe_force_n(150.0, 0.48, kRadius, 1e6 * kRadius, delta) /
                  hertz_plates_force_n(150.0, 0.48, kRadius, delta),
              1.0, 1e-5);
  EXPECT_NEAR(hertz_probe_force_n(300.0, 0.48, kRadius, 5e-6, delta) /
                  hertz_probe_force_n(150.0, 0.48, kRadius, 5e-6, delta),
              2.0, 1e-12);
  // a narrower probe gives less force at the same total indentation
  EXPECT_LT(hertz_probe_force_n(150.0, 0.48, kRadius, 2e-6, delta),
            hertz_probe_force_n(150.0, 0.48, kRadius, 20e-6, delta));
}

TEST(ClosedFormModulus, RecoversTheExactEFromANoiselessModelCurve) {
  std::vector<double> shape, force, weights;
  for (int i = 1; i <= 30; ++i) {
    const double d = 0.1e-6 * i;
    shape.push_back(hertz_probe_force_n(1.0, 0.48, kRadius, 5e-6, d));
    force.push_back(237.5 * shape.back());
    weights.push_back(1.0 / (force.back() * force.back()));  // relative residuals
  }
  StatusOr<double> e = closed_form_modulus(shape, force, weights);
  ASSERT_TRUE(e.ok()) << e.status().to_string();
  EXPECT_NEAR(*e / 237.5, 1.0, 1e-13);
  EXPECT_NEAR(closed_form_objective(shape, force, weights), 0.0, 1e-12 * 30);  // S = C - A^2/B, C = 30
  // any weights give the exact E for exact data
  for (std::size_t i = 0; i < weights.size(); ++i) weights[i] = 1.0 + i % 3;
  EXPECT_NEAR(*closed_form_modulus(shape, force, weights) / 237.5, 1.0, 1e-13);
}

TEST(ClosedFormModulus, RefusesMismatchedSizesAndNoContact) {
  const std::vector<double> a = {1, 2}, b = {1, 2, 3}, zeros = {0, 0};
  StatusOr<double> sizes = closed_form_modulus(a, b, a);
  ASSERT_FALSE(sizes.ok());
  EXPECT_NE(sizes.status().message().find("differ in size"), std::string::npos) << sizes.status().message();
  StatusOr<double> none = closed_form_modulus(zeros, a, a);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.status().message().find("no point in contact"), std::string::npos);
}

TEST(Minimise1d, FindsTheMinimumOfAParabolaAndOfAStepWithASideMinimum) {
  const Minimum m = minimise_1d([](double x) { return (x - 0.3137) * (x - 0.3137); }, -1.0, 2.0, 1e-10);
  EXPECT_NEAR(m.x, 0.3137, 1e-8);
  // a shallow side minimum at -0.8 and the true one at 0.6: the grid scan picks the right basin
  const Minimum n =
      minimise_1d([](double x) { return std::min(0.5 + (x + 0.8) * (x + 0.8), 10 * (x - 0.6) * (x - 0.6)); },
                  -1.0, 1.0, 1e-10);
  EXPECT_NEAR(n.x, 0.6, 1e-7);
  EXPECT_EQ(minimise_1d([](double x) { return x; }, 0.5, 0.5, 1e-9).x, 0.5);
}

TEST(ContactPoint, RecoveredFromAShiftedCurve) {
  // A paraboloid tip curve, contact at x0 = 0.3137 um, with free (zero-force) samples before it
  const double x0 = 0.3137e-6, e_true = 812.0, tip = 2e-6;
  std::vector<double> x, f, w;
  for (int i = 0; i <= 300; ++i) {
    x.push_back(-1e-6 + 1e-8 * i);
    f.push_back(hertz_paraboloid_force_n(e_true, 0.5, tip, x.back() - x0));
    w.push_back(1.0);
  }
  const auto shape = [&](double d) { return hertz_paraboloid_force_n(1.0, 0.5, tip, d); };
  StatusOr<ContactFit> fit = fit_contact_point(x, f, w, shape, -0.5e-6, 1e-6);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  EXPECT_NEAR(fit->contact_m, x0, 1e-12);  // 1e-6 of the window
  EXPECT_NEAR(fit->youngs_modulus_pa / e_true, 1.0, 1e-6);
  EXPECT_GT(fit->points_in_contact, 150);

  StatusOr<ContactFit> inverted = fit_contact_point(x, f, w, shape, 1e-6, -1e-6);
  ASSERT_FALSE(inverted.ok());
  EXPECT_NE(inverted.status().message().find("window"), std::string::npos);
  StatusOr<ContactFit> beyond = fit_contact_point(x, f, w, shape, 3e-6, 4e-6);  // every sample before contact
  ASSERT_FALSE(beyond.ok());
  EXPECT_NE(beyond.status().message().find("no point in contact"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::calibration
