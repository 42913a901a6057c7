// Block averaging: the plain standard error for independent samples, the
// correlated error of an AR(1) series, and edge cases.
#include "physics/scenes/suspension/suspension_statistics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace cellflow::scenes {
namespace {

// Standard normal numbers by Box-Muller from mt19937_64's raw output.
std::vector<double> normals(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto uniform = [&] { return (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53; };
  std::vector<double> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = std::sqrt(-2.0 * std::log(uniform())) * std::cos(2.0 * 3.14159265358979323846 * uniform());
  }
  return out;
}

TEST(BlockAverage, IndependentSamplesGiveThePlainError) {
  const std::size_t n = 4096;
  double mean_ratio = 0.0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const std::vector<double> x = normals(n, seed);
    const BlockAverage b = block_average(x);
    mean_ratio += b.standard_error / (1.0 / std::sqrt(static_cast<double>(n))) / 20.0;
  }
  // The maximum over levels is biased up a little for independent data.
  EXPECT_GT(mean_ratio, 0.95);
  EXPECT_LT(mean_ratio, 1.35);
}

TEST(BlockAverage, CorrelatedSeriesGivesTheCorrelatedError) {
  // AR(1): x_i = rho x_{i-1} + e_i, var x = 1 / (1 - rho^2); the error of the
  // mean is sqrt(var x / n (1 + rho) / (1 - rho)) for n >> correlation time.
  const double rho = 0.9;
  const std::size_t n = 1 << 14;
  double mean_ratio = 0.0, naive_ratio = 0.0;
  const int trials = 20;
  for (int t = 0; t < trials; ++t) {
    const std::vector<double> e = normals(n, 100 + t);
    std::vector<double> x(n);
    x[0] = e[0] / std::sqrt(1.0 - rho * rho);
    for (std::size_t i = 1; i < n; ++i) x[i] = rho * x[i - 1] + e[i];
    const double expected = std::sqrt(1.0 / (1.0 - rho * rho) / n * (1.0 + rho) / (1.0 - rho));
    const BlockAverage b = block_average(x);
    mean_ratio += b.standard_error / expected / trials;
    naive_ratio += std::sqrt(1.0 / (1.0 - rho * rho) / n) / expected / trials;
    EXPECT_GT(b.block_length, 8);
  }
  EXPECT_NEAR(mean_ratio, 1.0, 0.2);
  EXPECT_LT(naive_ratio, 0.25);  // what the plain error would have said
}

TEST(BlockAverage, EdgeCases) {
  EXPECT_EQ(block_average(std::vector<double>{}).standard_error, 0.0);
  const BlockAverage one = block_average(std::vector<double>{2.5});
  EXPECT_EQ(one.mean, 2.5);
  EXPECT_EQ(one.standard_error, 0.0);
  const BlockAverage flat = block_average(std::vector<double>(100, 0.3));
  EXPECT_NEAR(flat.mean, 0.3, 1e-15);
  EXPECT_NEAR(flat.standard_error, 0.0, 1e-15);
  const BlockAverage two = block_average(std::vector<double>{1.0, 3.0});
  EXPECT_EQ(two.mean, 2.0);
  EXPECT_DOUBLE_EQ(two.standard_error, 1.0);  // s = 1, sqrt(1 / (2 - 1))
  EXPECT_DOUBLE_EQ(rigid_sphere_relative_viscosity(0.1), 1.0 + 0.25 + 0.062);
}

}  // namespace
}  // namespace cellflow::scenes
