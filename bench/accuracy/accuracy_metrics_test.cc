// The error metrics of cellflow-bench: interpolation on the deformation grid,
// the observed order and Richardson extrapolation, the Pareto front.
#include "bench/accuracy/accuracy_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace cellflow::bench {
namespace {

TEST(AccuracyMetrics, GridInterpolatesLinearlyFromFirstContact) {
  const std::vector<double> eps = {0.2, 0.4}, force = {2.0, 6.0};
  const std::vector<double> grid = {0.1, 0.2, 0.3, 0.4, 0.5};
  const std::vector<double> f = forces_on_grid(eps, force, grid);
  ASSERT_EQ(f.size(), 5u);
  EXPECT_DOUBLE_EQ(f[0], 1.0);  // between (0, 0) and (0.2, 2)
  EXPECT_DOUBLE_EQ(f[1], 2.0);
  EXPECT_DOUBLE_EQ(f[2], 4.0);
  EXPECT_DOUBLE_EQ(f[3], 6.0);
  EXPECT_TRUE(std::isnan(f[4]));  // the curve stopped at 0.4
}

TEST(AccuracyMetrics, UniformGridIncludesBothEnds) {
  const std::vector<double> g = uniform_grid(0.1, 0.6, 0.1);
  ASSERT_EQ(g.size(), 6u);
  EXPECT_NEAR(g.back(), 0.6, 1e-12);
}

TEST(AccuracyMetrics, LargestRelativeErrorAndNaN) {
  EXPECT_NEAR(max_relative_error(std::vector<double>{1.1, 1.98}, std::vector<double>{1.0, 2.0}), 0.1, 1e-12);
  EXPECT_TRUE(std::isnan(max_relative_error(std::vector<double>{NAN}, std::vector<double>{1.0})));
  EXPECT_TRUE(std::isnan(max_relative_error(std::vector<double>{1.0}, std::vector<double>{1.0, 2.0})));
}

// F(h) = F0 + C h^p on unequally spaced meshes: the order and F0 are recovered.
TEST(AccuracyMetrics, RichardsonRecoversOrderAndLimit) {
  const double p = 2.0, h1 = 0.05, h2 = 0.065, h3 = 0.08;
  const std::vector<double> f0 = {1.0, 3.0, 7.0};
  const std::vector<double> c = {0.5, -2.0, 4.0};
  std::vector<double> f1, f2, f3;
  for (std::size_t i = 0; i < f0.size(); ++i) {
    f1.push_back(f0[i] + c[i] * std::pow(h1, p));
    f2.push_back(f0[i] + c[i] * std::pow(h2, p));
    f3.push_back(f0[i] + c[i] * std::pow(h3, p));
  }
  const Richardson r = richardson_extrapolate(h1, h2, h3, f1, f2, f3);
  ASSERT_TRUE(r.usable);
  EXPECT_NEAR(r.order, p, 1e-6);
  for (std::size_t i = 0; i < f0.size(); ++i) {
    EXPECT_NEAR(r.extrapolated[i], f0[i], 1e-9 * std::abs(f0[i]));
    EXPECT_NEAR(r.pointwise_order[i], p, 1e-6);
  }
}

// Oscillating differences have no order: the finest solution is the reference.
TEST(AccuracyMetrics, RichardsonFallsBackToFinestWhenOscillatory) {
  const std::vector<double> f1 = {1.0}, f2 = {1.1}, f3 = {1.0};
  const Richardson r = richardson_extrapolate(0.05, 0.065, 0.08, f1, f2, f3);
  EXPECT_FALSE(r.usable);
  EXPECT_TRUE(std::isnan(r.order));
  EXPECT_DOUBLE_EQ(r.extrapolated[0], 1.0);
}

// An order far above 4 (differences that collapse) is not trusted either.
TEST(AccuracyMetrics, RichardsonRejectsOrderOutsideRange) {
  const double h1 = 0.05, h2 = 0.1, h3 = 0.2;
  const std::vector<double> f1 = {1.0 + std::pow(h1, 6)}, f2 = {1.0 + std::pow(h2, 6)},
                            f3 = {1.0 + std::pow(h3, 6)};
  const Richardson r = richardson_extrapolate(h1, h2, h3, f1, f2, f3);
  EXPECT_NEAR(r.order, 6.0, 1e-6);
  EXPECT_FALSE(r.usable);
  EXPECT_DOUBLE_EQ(r.extrapolated[0], f1[0]);
}

TEST(AccuracyMetrics, ParetoFrontKeepsOnlyUndominatedPoints) {
  const std::vector<double> time = {1.0, 2.0, 3.0, 2.5, 4.0, 5.0};
  const std::vector<double> error = {0.1, 0.05, 0.06, 0.01, 0.0, NAN};
  const std::vector<bool> front = pareto_front(time, error);
  EXPECT_TRUE(front[0]);
  EXPECT_TRUE(front[1]);
  EXPECT_FALSE(front[2]);  // slower and less accurate than 2.5 s / 0.01
  EXPECT_TRUE(front[3]);
  EXPECT_FALSE(front[4]);  // zero error: the reference itself, not plotted
  EXPECT_FALSE(front[5]);
}

}  // namespace
}  // namespace cellflow::bench
