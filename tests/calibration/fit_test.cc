// fit_curves on synthetic curves made by the scene: recovery of (E, w, contact
// point) from noisy curves, simulations per fit, the direction of w, and bad input.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "tests/calibration/calibration_test_util.h"

namespace cellflow::calibration {
namespace {

using testing::kRadius;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void print_fit(const char* label, const ParameterFit& f) {
  std::printf(
      "%s: E = %.2f Pa [%.2f, %.2f], w = %.4f [%.4f, %.4f]%s, Hertz E (eps <= 0.1) = %.2f Pa, "
      "rms rel. residual %.4f, N = %d, p = %d\n",
      label, f.youngs_modulus_pa.value, f.youngs_modulus_pa.lower, f.youngs_modulus_pa.upper,
      f.mooney_rivlin_w.value, f.mooney_rivlin_w.lower, f.mooney_rivlin_w.upper,
      f.mooney_rivlin_w.upper_at_bound ? " (upper at bound)" : "", f.hertz_youngs_modulus_pa.value_or(-1),
      f.rms_relative_residual, f.points, f.parameters);
  for (const CurvePart& c : f.curves) {
    std::printf("   %s: contact offset %.4f R [%.4f, %.4f]\n", c.name.c_str(),
                c.contact_offset_m.value / kRadius, c.contact_offset_m.lower / kRadius,
                c.contact_offset_m.upper / kRadius);
  }
}

// Data and library on the same mesh (400 vertices, R = 8.6 um, nu = 0.48):
// this checks the fitting machinery (interpolation in w and deformation,
// closed-form E, contact search, intervals), not the mesh error. The data
// have twice the library's load points, 3 % multiplicative noise (seeded)
// and contact offsets of +3 % and -2.5 % of R.
TEST(FitCurves, RecoversEWAndContactFromNoisySceneCurves) {
  const auto start = std::chrono::steady_clock::now();
  struct Truth {
    double e, w, offset;
    unsigned seed;
  };
  const Truth truths[] = {{150.0, 0.5, 0.03 * kRadius, 11u}, {120.0, 0.25, -0.025 * kRadius, 12u}};
  std::vector<MeasuredCurve> curves;
  for (const Truth& t : truths) {
    const scenes::QuasiStaticResult run = testing::run_plates(t.e, t.w, 400, 30, 0.75);
    ASSERT_TRUE(run.status.ok()) << run.status.to_string();
    curves.push_back(testing::measured_from(run, kRadius, t.offset, 0.03, t.seed));
    curves.back().name = t.e > 130 ? "E150" : "E120";
  }
  const double data_seconds = seconds_since(start);

  CurveLibrary library(testing::same_mesh_options());
  FitOptions options;
  options.numerics = testing::coarse_numerics();
  options.joint = false;
  const auto fit_start = std::chrono::steady_clock::now();
  StatusOr<FitResult> fit = fit_curves(curves, options, library);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  const double fit_seconds = seconds_since(fit_start);
  std::printf("w free, empty library: %d simulations, %.1f s (data: %.1f s)\n", fit->simulations_run,
              fit_seconds, data_seconds);
  EXPECT_LE(fit->simulations_run, 15);
  ASSERT_EQ(fit->per_curve.size(), 2u);
  for (std::size_t c = 0; c < 2; ++c) {
    const ParameterFit& f = fit->per_curve[c];
    print_fit(curves[c].name.c_str(), f);
    EXPECT_NEAR(f.youngs_modulus_pa.value / truths[c].e, 1.0, 0.03);
    EXPECT_NEAR(f.mooney_rivlin_w.value, truths[c].w, 0.07);
    EXPECT_NEAR(f.curves[0].contact_offset_m.value, truths[c].offset, 0.02 * kRadius);
    // the 95 % intervals hold the truth and the estimate
    EXPECT_LE(f.youngs_modulus_pa.lower, f.youngs_modulus_pa.value);
    EXPECT_GE(f.youngs_modulus_pa.upper, f.youngs_modulus_pa.value);
    EXPECT_LE(f.mooney_rivlin_w.lower, f.mooney_rivlin_w.value);
    EXPECT_GE(f.mooney_rivlin_w.upper, f.mooney_rivlin_w.value);
    EXPECT_LT(f.rms_relative_residual, 0.05);  // 3 % noise
    ASSERT_TRUE(f.hertz_youngs_modulus_pa.has_value());
    // Hertz over eps <= 0.1 sees the stiffer-than-Hertz start of the curve (F/F_Hertz 1.1-1.2): a larger E
    EXPECT_GT(*f.hertz_youngs_modulus_pa, 0.9 * f.youngs_modulus_pa.value);
  }

  // a second fit on the warm library runs nothing
  const auto warm_start = std::chrono::steady_clock::now();
  StatusOr<FitResult> again = fit_curves(curves, options, library);
  ASSERT_TRUE(again.ok());
  std::printf("warm library: %d simulations, %.2f s\n", again->simulations_run, seconds_since(warm_start));
  EXPECT_EQ(again->simulations_run, 0);
  EXPECT_EQ(again->per_curve[0].youngs_modulus_pa.value, fit->per_curve[0].youngs_modulus_pa.value);

  // w fixed on an empty library: one simulation
  CurveLibrary fresh(testing::same_mesh_options());
  FitOptions fixed = options;
  fixed.mooney_rivlin_w = 0.5;
  StatusOr<FitResult> one = fit_curves({curves[0]}, fixed, fresh);
  ASSERT_TRUE(one.ok()) << one.status().to_string();
  std::printf("w fixed, empty library: %d simulation(s)\n", one->simulations_run);
  EXPECT_EQ(one->simulations_run, 1);
  print_fit("E150 at w = 0.5 fixed", one->per_curve[0]);
  EXPECT_TRUE(one->per_curve[0].mooney_rivlin_w.fixed);
  EXPECT_NEAR(one->per_curve[0].youngs_modulus_pa.value / 150.0, 1.0, 0.03);
  std::printf("run time %.1f s\n", seconds_since(start));
}

// Two noisy realisations of one cell (E = 150 Pa, w = 0.5): one joint fit
// with shared E and w (free) and a contact point each, and one fit per
// curve. A 5-point w grid keeps it short.
TEST(FitCurves, JointFitSharesEAndWAndKeepsAContactPerCurve) {
  const scenes::QuasiStaticResult run = testing::run_plates(150.0, 0.5, 400, 30, 0.75);
  ASSERT_TRUE(run.status.ok()) << run.status.to_string();
  const std::vector<MeasuredCurve> curves = {
      testing::measured_from(run, kRadius, 0.04 * kRadius, 0.03, 21u),
      testing::measured_from(run, kRadius, -0.02 * kRadius, 0.03, 22u)};
  LibraryOptions lib = testing::same_mesh_options();
  lib.w_grid = {0.0, 0.25, 0.5, 0.75, 1.0};
  CurveLibrary library(lib);
  FitOptions options;
  options.numerics = testing::coarse_numerics();
  const auto start = std::chrono::steady_clock::now();
  StatusOr<FitResult> fit = fit_curves(curves, options, library);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  std::printf("joint + 2 per-curve fits, w free: %d simulations, %.1f s\n", fit->simulations_run,
              seconds_since(start));
  EXPECT_EQ(fit->simulations_run, 5);
  ASSERT_TRUE(fit->joint.has_value());
  ASSERT_EQ(fit->per_curve.size(), 2u);
  const ParameterFit& joint = *fit->joint;
  print_fit("joint", joint);
  print_fit("per curve 0", fit->per_curve[0]);
  print_fit("per curve 1", fit->per_curve[1]);
  EXPECT_EQ(joint.curves.size(), 2u);
  EXPECT_EQ(joint.parameters, 4);  // E, w and two contact offsets
  EXPECT_EQ(joint.points, fit->per_curve[0].points + fit->per_curve[1].points);
  EXPECT_NEAR(joint.youngs_modulus_pa.value / 150.0, 1.0, 0.03);
  EXPECT_NEAR(joint.mooney_rivlin_w.value, 0.5, 0.07);
  EXPECT_NEAR(joint.curves[0].contact_offset_m.value, 0.04 * kRadius, 0.02 * kRadius);
  EXPECT_NEAR(joint.curves[1].contact_offset_m.value, -0.02 * kRadius, 0.02 * kRadius);
  // the joint interval of E is narrower than a single curve's
  const double joint_width = joint.youngs_modulus_pa.upper - joint.youngs_modulus_pa.lower;
  EXPECT_LT(joint_width,
            fit->per_curve[0].youngs_modulus_pa.upper - fit->per_curve[0].youngs_modulus_pa.lower);
  EXPECT_LT(joint_width,
            fit->per_curve[1].youngs_modulus_pa.upper - fit->per_curve[1].youngs_modulus_pa.lower);
  // the model curve comes with the fit
  EXPECT_EQ(joint.curves[0].model_force_n.size(), joint.curves[0].points.size());
}

// Joint fits of two and five curves on a warm library: the warm-started
// profiles (default) against FitOptions::exact_profiles (every profile point
// re-solved from scratch, the previous implementation): the estimates are the
// same solve, the interval bounds agree within 1e-3 of E, 1e-3 in w and
// 1e-3 R. The exact five-curve reference takes ~11 s; it runs when
// CELLFLOW_FIT_EXACT_FIVE is set, else five curves are timed only.
TEST(FitCurves, WarmStartedProfilesMatchExactProfiles) {
  const scenes::QuasiStaticResult run = testing::run_plates(150.0, 0.5, 400, 30, 0.75);
  ASSERT_TRUE(run.status.ok()) << run.status.to_string();
  const double offsets[] = {0.04, -0.02, 0.01, 0.03, -0.01};
  std::vector<MeasuredCurve> curves;
  for (int c = 0; c < 5; ++c) {
    curves.push_back(testing::measured_from(run, kRadius, offsets[c] * kRadius, 0.03, 31u + c));
  }
  LibraryOptions lib = testing::same_mesh_options();
  lib.w_grid = {0.0, 0.25, 0.5, 0.75, 1.0};
  CurveLibrary library(lib);
  FitOptions options;
  options.numerics = testing::coarse_numerics();
  options.per_curve = false;
  ASSERT_TRUE(fit_curves(curves, options, library).ok());  // warms the library
  const auto close = [](const Estimate& a, const Estimate& b, double tolerance) {
    EXPECT_EQ(a.value, b.value);
    EXPECT_NEAR(a.lower, b.lower, tolerance);
    EXPECT_NEAR(a.upper, b.upper, tolerance);
    EXPECT_EQ(a.lower_at_bound, b.lower_at_bound);
    EXPECT_EQ(a.upper_at_bound, b.upper_at_bound);
  };
  const bool exact_five = std::getenv("CELLFLOW_FIT_EXACT_FIVE") != nullptr;
  for (const std::size_t n : {std::size_t{2}, std::size_t{5}}) {
    const std::vector<MeasuredCurve> some(curves.begin(), curves.begin() + n);
    auto start = std::chrono::steady_clock::now();
    StatusOr<FitResult> fast = fit_curves(some, options, library);
    const double fast_seconds = seconds_since(start);
    ASSERT_TRUE(fast.ok()) << fast.status().to_string();
    EXPECT_EQ(fast->simulations_run, 0);
    print_fit(n == 2 ? "joint of 2, warm-started profiles" : "joint of 5, warm-started profiles",
              *fast->joint);
    std::printf("joint of %zu curves, warm-started profiles: %.3f s\n", n, fast_seconds);
    if (n == 5 && !exact_five) continue;
    FitOptions exact_options = options;
    exact_options.exact_profiles = true;
    start = std::chrono::steady_clock::now();
    StatusOr<FitResult> exact = fit_curves(some, exact_options, library);
    const double exact_seconds = seconds_since(start);
    ASSERT_TRUE(exact.ok()) << exact.status().to_string();
    print_fit("exact profiles", *exact->joint);
    std::printf("joint of %zu curves, exact profiles: %.3f s\n", n, exact_seconds);
    const ParameterFit& a = *fast->joint;
    const ParameterFit& b = *exact->joint;
    EXPECT_EQ(a.objective, b.objective);
    std::printf("largest bound difference: E %.2e (relative), w %.2e",
                std::max(std::abs(a.youngs_modulus_pa.lower - b.youngs_modulus_pa.lower),
                         std::abs(a.youngs_modulus_pa.upper - b.youngs_modulus_pa.upper)) /
                    b.youngs_modulus_pa.value,
                std::max(std::abs(a.mooney_rivlin_w.lower - b.mooney_rivlin_w.lower),
                         std::abs(a.mooney_rivlin_w.upper - b.mooney_rivlin_w.upper)));
    double ds = 0.0;
    for (std::size_t c = 0; c < n; ++c) {
      ds = std::max({ds, std::abs(a.curves[c].contact_offset_m.lower - b.curves[c].contact_offset_m.lower),
                     std::abs(a.curves[c].contact_offset_m.upper - b.curves[c].contact_offset_m.upper)});
    }
    std::printf(", s %.2e R\n", ds / kRadius);
    close(a.youngs_modulus_pa, b.youngs_modulus_pa, 1e-3 * b.youngs_modulus_pa.value);
    close(a.mooney_rivlin_w, b.mooney_rivlin_w, 1e-3);
    for (std::size_t c = 0; c < n; ++c) {
      close(a.curves[c].contact_offset_m, b.curves[c].contact_offset_m, 1e-3 * kRadius);
    }
  }
}

// Probe indentation (Rp = R, 600 vertices: the probe much wider than the
// mesh edge), w fixed at 1: one simulation; E and the contact recovered from
// a noiseless shifted curve; scene_force_n reproduces the scene at its load points.
constexpr double kReproductionTolerance = 1e-10;
TEST(FitCurves, ProbeIndentationWithFixedW) {
  const double probe_radius = kRadius;
  scenes::IndentationParams p;
  p.cell.radius_m = kRadius;
  p.cell.material = {.youngs_modulus_pa = 580.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = 600;
  p.probe_radius_m = probe_radius;
  p.max_indentation_m = 0.5 * 2 * kRadius;
  p.load_points = 10;
  p.numerics.threads = 1;
  // Converged far below the 1e-9 asserted below: the library runs the scene
  // at another E (not a power of two away), and on the default probe mesh
  // (graded to the pole, issue 11) the default 1e-6 left 1.3e-9 between them.
  p.numerics.residual_tolerance = kReproductionTolerance;
  const scenes::QuasiStaticResult run = scenes::run_indentation(p);
  ASSERT_TRUE(run.status.ok()) << run.status.to_string();
  MeasuredCurve curve = testing::measured_from(run, kRadius, 0.02 * kRadius, 0.0, 1u);
  curve.geometry = Geometry::kProbe;
  curve.probe_radius_m = probe_radius;
  CurveLibrary library(testing::same_mesh_options());
  FitOptions options;
  options.mooney_rivlin_w = 1.0;
  options.max_deformation = 0.45;
  options.numerics = testing::coarse_numerics(600, 10);
  options.numerics.max_deformation = 0.5;
  options.numerics.residual_tolerance = kReproductionTolerance;
  options.joint = false;
  StatusOr<FitResult> fit = fit_curves({curve}, options, library);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  EXPECT_EQ(fit->simulations_run, 1);
  print_fit("probe", fit->per_curve[0]);
  EXPECT_NEAR(fit->per_curve[0].youngs_modulus_pa.value / 580.0, 1.0, 0.01);
  EXPECT_NEAR(fit->per_curve[0].curves[0].contact_offset_m.value, 0.02 * kRadius, 0.005 * kRadius);

  CurveKey key;
  key.geometry = Geometry::kProbe;
  key.probe_to_cell_radius = 1.0;
  key.numerics = options.numerics;
  for (const scenes::CurvePoint& point : run.curve) {
    StatusOr<double> f = scene_force_n(library, key, 580.0, 1.0, kRadius, point.displacement_m);
    ASSERT_TRUE(f.ok()) << f.status().to_string();
    EXPECT_NEAR(*f / point.force_n, 1.0, 1e-9) << "deformation " << point.deformation;
  }
  EXPECT_EQ(library.simulations_run(), 1);
}

// A neo-Hookean curve (scene at w = 1 on a finer mesh than the library's)
// fits w near 1; the same curve with a force that turns up earlier
// (F (1 + 3 eps^2)) gets a smaller w. A 5-point w grid keeps it short.
TEST(FitCurves, NeoHookeanFitsWNearOneAndAnEarlierUpturnGivesASmallerW) {
  const scenes::QuasiStaticResult run = testing::run_plates(150.0, 1.0, 600, 15, 0.75);
  ASSERT_TRUE(run.status.ok()) << run.status.to_string();
  MeasuredCurve neo = testing::measured_from(run, kRadius, 0.0, 0.0, 1u);
  MeasuredCurve upturn = neo;
  for (std::size_t i = 0; i < upturn.force_n.size(); ++i) {
    const double eps = upturn.indentation_m[i] / (2 * kRadius);
    upturn.force_n[i] *= 1.0 + 3.0 * eps * eps;
  }
  LibraryOptions lib = testing::same_mesh_options();
  lib.w_grid = {0.0, 0.25, 0.5, 0.75, 1.0};
  CurveLibrary library(lib);
  FitOptions options;
  options.numerics = testing::coarse_numerics();
  options.joint = false;
  StatusOr<FitResult> fit = fit_curves({neo, upturn}, options, library);
  ASSERT_TRUE(fit.ok()) << fit.status().to_string();
  EXPECT_EQ(fit->simulations_run, 5);
  print_fit("neo-Hookean", fit->per_curve[0]);
  print_fit("earlier upturn", fit->per_curve[1]);
  EXPECT_GT(fit->per_curve[0].mooney_rivlin_w.value, 0.85);
  EXPECT_LT(fit->per_curve[1].mooney_rivlin_w.value, fit->per_curve[0].mooney_rivlin_w.value - 0.2);
}

// Each bad input is refused before any simulation, naming the problem.
TEST(FitCurves, BadInputIsRefusedNamingTheProblem) {
  MeasuredCurve good;
  good.radius_m = kRadius;
  for (int i = 0; i < 20; ++i) {
    good.indentation_m.push_back(0.05 * i * kRadius);
    good.force_n.push_back(1e-9 * i * i);
  }
  CurveLibrary library(testing::same_mesh_options());
  FitOptions options;
  options.numerics = testing::coarse_numerics();
  const auto refused = [&](const MeasuredCurve& c, const FitOptions& o, const std::string& needle) {
    StatusOr<FitResult> r = fit_curves({good, c}, o, library);
    ASSERT_FALSE(r.ok()) << "accepted; expected an error with " << needle;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().message();
  };
  MeasuredCurve c = good;
  std::swap(c.indentation_m[5], c.indentation_m[6]);
  refused(c, options, "curves[1].indentation_m[6]");  // non-monotonic deformation
  c = good;
  c.force_n[3] = -2e-10;
  refused(c, options, "curves[1].force_n[3] = -2e-10 is negative");
  c = good;
  c.indentation_m.push_back(2.0 * kRadius);
  c.force_n.push_back(1e-6);
  refused(c, options, ">= 1");  // deformation >= 1
  c = good;
  c.geometry = Geometry::kProbe;
  refused(c, options, "curves[1].probe_radius_m = 0 must be > 0 for the probe geometry");
  c = good;
  c.force_n.pop_back();
  refused(c, options, "curves[1].force_n has 19 samples");
  FitOptions range = options;
  range.min_deformation = 0.5;  // data reach 0.475
  range.max_deformation = 0.6;
  refused(good, range, "no sample in the fit range");
  FitOptions reach = options;
  reach.max_deformation = 0.72;  // + window 0.05 > the library's 0.75
  refused(good, reach, "fit.numerics.max_deformation");
  FitOptions w = options;
  w.mooney_rivlin_w = 1.5;
  refused(good, w, "fit.mooney_rivlin_w = 1.5");
  StatusOr<FitResult> none = fit_curves({}, options, library);
  EXPECT_FALSE(none.ok());
  EXPECT_EQ(library.simulations_run(), 0);
}

}  // namespace
}  // namespace cellflow::calibration
