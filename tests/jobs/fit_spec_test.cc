// The fit spec's checks (jobs/fit/fit_spec.h): each refusal names its field
// path and, for one sample, the curve and sample; the fit range and the tip
// position's contact estimate are converted as documented.
#include "jobs/fit/fit_spec.h"

#include <gtest/gtest.h>

#include <cmath>

namespace cellflow::jobs {
namespace {

v1::FitSpec good_spec() {
  v1::FitSpec fit;
  fit.set_geometry(v1::FIT_GEOMETRY_PLATES);
  fit.set_radius_m(5e-6);
  fit.set_w_free(true);
  auto* c = fit.add_curves();
  c->set_name("a");
  for (int i = -10; i < 50; ++i) {
    const double x = i * 0.1e-6;
    c->add_indentation_m(x);
    c->add_force_n(x > 0 ? 1e-9 * std::pow(x / 1e-6, 1.5) : 0.0);
  }
  return fit;
}

void expect_refused(const v1::FitSpec& fit, const std::string& field, int curve = -1, int sample = -1) {
  FitSpecError where;
  const StatusOr<FitPlan> plan = to_fit_plan(fit, &where);
  ASSERT_FALSE(plan.ok()) << field;
  EXPECT_EQ(plan.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(plan.status().message().rfind(field, 0), 0u) << plan.status().message();
  EXPECT_EQ(where.curve, curve) << plan.status().message();
  EXPECT_EQ(where.sample, sample) << plan.status().message();
}

TEST(FitSpec, GoodSpecKeepsTheSamplesInTheDefaultRange) {
  const StatusOr<FitPlan> plan = to_fit_plan(good_spec());
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  ASSERT_EQ(plan->curves.size(), 1u);
  EXPECT_FALSE(plan->mooney_rivlin_w.has_value());
  EXPECT_EQ(plan->min_deformation, -0.05);
  EXPECT_EQ(plan->max_deformation, 0.7);
  // deformation >= -0.05: x >= -0.5 um, i.e. samples 5.. of 60
  EXPECT_EQ(plan->curves[0].sample.front(), 5);
  EXPECT_EQ(plan->curves[0].indentation_m.size(), 55u);
  EXPECT_EQ(plan->total_samples, 60);
}

TEST(FitSpec, RefusalsNameTheField) {
  v1::FitSpec fit = good_spec();
  fit.clear_geometry();
  expect_refused(fit, "fit.geometry");
  fit = good_spec();
  fit.set_geometry(v1::FIT_GEOMETRY_PROBE);
  expect_refused(fit, "fit.probe_radius_m");
  fit = good_spec();
  fit.set_geometry(v1::FIT_GEOMETRY_TIP);
  expect_refused(fit, "fit.tip_radius_m");
  fit = good_spec();
  fit.clear_w();
  expect_refused(fit, "fit.w");
  fit = good_spec();
  fit.set_mooney_rivlin_w(1.5);
  expect_refused(fit, "fit.mooney_rivlin_w");
  fit = good_spec();
  fit.set_model(v1::FIT_MODEL_HERTZ);
  expect_refused(fit, "fit.w_free");
  fit = good_spec();
  fit.clear_radius_m();
  expect_refused(fit, "fit.radius_m");
  fit = good_spec();
  fit.set_poisson_ratio(0.5);
  expect_refused(fit, "fit.poisson_ratio");
  fit = good_spec();
  fit.mutable_numerics()->set_target_vertex_count(100);
  expect_refused(fit, "fit.numerics.target_vertex_count");
  fit = good_spec();
  fit.mutable_numerics()->set_max_deformation(0.5);
  expect_refused(fit, "fit.numerics.max_deformation");  // does not reach 0.7 + 0.05
  fit = good_spec();
  fit.clear_curves();
  expect_refused(fit, "fit.curves");
}

TEST(FitSpec, SampleRefusalsNameCurveAndSample) {
  v1::FitSpec fit = good_spec();
  fit.mutable_curves(0)->add_force_n(1e-9);
  expect_refused(fit, "fit.curves[0].force_n", 0);
  fit = good_spec();
  fit.mutable_curves(0)->set_force_n(20, std::nan(""));
  expect_refused(fit, "fit.curves[0].force_n[20]", 0, 20);
  fit = good_spec();
  fit.mutable_curves(0)->set_indentation_m(30, 0.0);
  expect_refused(fit, "fit.curves[0].indentation_m[30]", 0, 30);  // not increasing
  fit = good_spec();
  fit.mutable_curves(0)->set_force_n(25, -1e-12);
  expect_refused(fit, "fit.curves[0].force_n[25]", 0, 25);  // negative, no noise given
  fit.mutable_curves(0)->set_force_noise_n(1e-12);
  EXPECT_TRUE(to_fit_plan(fit).ok());  // within 3 force_noise_n
  fit = good_spec();
  fit.mutable_curves(0)->set_indentation_m(59, 10e-6);
  expect_refused(fit, "fit.curves[0].indentation_m[59]", 0, 59);  // x / 2R >= 1
  fit = good_spec();
  fit.mutable_range()->set_min(0.8);
  fit.mutable_range()->set_max(0.85);
  expect_refused(fit, "fit.curves[0].indentation_m", 0);  // no sample in the range
  fit = good_spec();
  for (int i = 0; i < 10; ++i) *fit.add_curves() = fit.curves(0);
  fit.mutable_curves(3)->clear_force_n();
  expect_refused(fit, "fit.curves[3].force_n", 3);
}

TEST(FitSpec, MetreRangeAndTipPositions) {
  v1::FitSpec fit = good_spec();
  fit.mutable_range()->set_mode(v1::FitRange::RELATIVE_M);
  fit.mutable_range()->set_min(0.0);
  fit.mutable_range()->set_max(2e-6);
  StatusOr<FitPlan> plan = to_fit_plan(fit);
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_NEAR(plan->min_deformation, 0.0, 1e-12);
  EXPECT_NEAR(plan->max_deformation, 0.2, 1e-9);  // 2 um / 10 um
  EXPECT_EQ(plan->curves[0].indentation_m.size(), 21u);

  // Tip positions: the contact estimate is the last sample before 5 % of the maximum force.
  fit = good_spec();
  auto* c = fit.mutable_curves(0);
  std::vector<double> x(c->indentation_m().begin(), c->indentation_m().end());
  c->clear_indentation_m();
  for (double v : x) c->add_tip_position_m(v + 3e-6);
  plan = to_fit_plan(fit);
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  const double max_force = c->force_n(59);
  int first = 0;
  while (c->force_n(first) <= 0.05 * max_force) ++first;
  EXPECT_DOUBLE_EQ(plan->curves[0].contact_estimate_m, x[first - 1] + 3e-6);
}

TEST(FitSpec, TooManySamplesAreRefused) {
  v1::FitSpec fit = good_spec();
  auto* c = fit.add_curves();
  for (std::int64_t i = 0; i <= kMaxFitPoints; ++i) {
    c->add_indentation_m(static_cast<double>(i) * 1e-12);
    c->add_force_n(0.0);
  }
  expect_refused(fit, "fit.curves");
}

}  // namespace
}  // namespace cellflow::jobs
