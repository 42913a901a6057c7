// Preprocessing on synthetic curves with a known contact point, baseline
// offset and tilt, and Gaussian noise: both contact-point methods recover it.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "io/afm/preprocess.h"

namespace cellflow::afm {
namespace {

struct Synthetic {
  std::vector<double> x_m, f_n;
};

// Tip travels 0..10 um; contact at 6 um; Hertz-like f = A d^1.5 reaching 5 nN
// at 4 um; baseline 0.3 nN + 0.02 nN/um tilt; noise sigma 0.02 nN.
constexpr double kContact = 6e-6, kOffset = 0.3e-9, kTilt = 0.02e-9 / 1e-6, kSigma = 0.02e-9;
constexpr double kAmplitude = 5e-9 / 8e-9;  // 5 nN / (4 um)^1.5

Synthetic make_curve(unsigned seed, double exponent = 1.5) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, kSigma);
  Synthetic s;
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    const double x = 10e-6 * i / (n - 1);
    const double d = x - kContact;
    const double a = kAmplitude * std::pow(4e-6, 1.5) / std::pow(4e-6, exponent);
    s.x_m.push_back(x);
    s.f_n.push_back(kOffset + kTilt * x + (d > 0 ? a * std::pow(d, exponent) : 0.0) + noise(rng));
  }
  return s;
}

TEST(AfmPreprocess, TipPositionIsHeightMinusDeflection) {
  const std::vector<double> h{1.0, 2.0, 3.0}, d{0.1, 0.2, 0.3};
  const auto t = tip_position_m(h, d);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_DOUBLE_EQ(t[2], 2.7);
}

TEST(AfmPreprocess, BaselineOffsetAndTiltRecovered) {
  const Synthetic s = make_curve(1);
  auto b = fit_baseline(s.x_m, s.f_n, 0, 1000, true);  // x < 5 um: free
  ASSERT_TRUE(b.ok());
  EXPECT_NEAR(b->offset_n, kOffset, 0.005e-9);
  EXPECT_NEAR(b->slope_n_per_m, kTilt, 0.1 * kTilt);
  EXPECT_NEAR(b->noise_sigma_n, kSigma, 0.1 * kSigma);
  const auto corrected = subtract_baseline(s.x_m, s.f_n, *b);
  EXPECT_NEAR(corrected[0], s.f_n[0] - kOffset, 0.005e-9);
}

// Tolerances: deviation method within 0.5 um (its threshold bias at 5 sigma is
// (5 sigma / A)^(2/3) = 0.29 um here, plus noise); power-law fit within
// 0.05 um (0.5 % of the travel).
TEST(AfmPreprocess, BothContactMethodsRecoverTheContact) {
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) {
    const Synthetic s = make_curve(seed);
    auto dev = contact_by_baseline_deviation(s.x_m, s.f_n, {});
    ASSERT_TRUE(dev.ok()) << dev.status().message();
    EXPECT_GE(dev->tip_position_m, kContact - 0.05e-6) << seed;  // biased late, never early
    EXPECT_NEAR(dev->tip_position_m, kContact, 0.5e-6) << seed;
    EXPECT_NEAR(dev->baseline.offset_n, kOffset, 0.01e-9) << seed;
    EXPECT_NEAR(dev->baseline.slope_n_per_m, kTilt, 0.1 * kTilt) << seed;

    auto fit = contact_by_power_law_fit(s.x_m, s.f_n, {});
    ASSERT_TRUE(fit.ok()) << fit.status().message();
    EXPECT_NEAR(fit->contact.tip_position_m, kContact, 0.05e-6) << seed;
    EXPECT_NEAR(fit->amplitude_n_per_m_pow, kAmplitude, 0.05 * kAmplitude) << seed;
    EXPECT_NEAR(fit->contact.baseline.offset_n, kOffset, 0.01e-9) << seed;
    EXPECT_NEAR(fit->contact.baseline.slope_n_per_m, kTilt, 0.1 * kTilt) << seed;
    EXPECT_NEAR(fit->rms_residual_n, kSigma, 0.1 * kSigma) << seed;
  }
}

TEST(AfmPreprocess, PowerLawFitWithConeExponent) {
  const Synthetic s = make_curve(7, 2.0);
  PowerLawFitOptions o;
  o.exponent = 2.0;
  auto fit = contact_by_power_law_fit(s.x_m, s.f_n, o);
  ASSERT_TRUE(fit.ok());
  EXPECT_NEAR(fit->contact.tip_position_m, kContact, 0.05e-6);
}

TEST(AfmPreprocess, NoContactIsAnError) {
  Synthetic s = make_curve(1);
  for (std::size_t i = 0; i < s.x_m.size(); ++i) s.f_n[i] = kOffset + 1e-14 * std::sin(1.0 * i);
  EXPECT_FALSE(contact_by_baseline_deviation(s.x_m, s.f_n, {}).ok());
}

TEST(AfmPreprocess, IndentationAndFitRanges) {
  const Synthetic s = make_curve(1);
  const auto d = indentation_m(s.x_m, kContact);
  EXPECT_DOUBLE_EQ(d.front(), -kContact);
  EXPECT_NEAR(d.back(), 4e-6, 1e-15);
  const auto rel = select_fit_range(s.x_m, kContact, FitRange::relative(0.0, 1e-6));
  ASSERT_FALSE(rel.empty());
  EXPECT_GE(s.x_m[rel.front()], kContact);
  EXPECT_LE(s.x_m[rel.back()], kContact + 1e-6);
  EXPECT_NEAR(static_cast<double>(rel.size()), 200.0, 2.0);  // 1 um of 10 um at 2000 points
  const auto abs = select_fit_range(s.x_m, kContact, FitRange::absolute(1e-6, 2e-6));
  ASSERT_FALSE(abs.empty());
  EXPECT_GE(s.x_m[abs.front()], 1e-6);
  EXPECT_LE(s.x_m[abs.back()], 2e-6);
}

}  // namespace
}  // namespace cellflow::afm
