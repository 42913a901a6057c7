// Block averaging of correlated time series (see suspension_statistics.h).
#include "physics/scenes/suspension/suspension_statistics.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cellflow::scenes {

namespace {

// Naive standard error of the mean of `v`: s / sqrt(n - 1), s^2 = mean (v - mean)^2.
double naive_error(const std::vector<double>& v, double mean) {
  if (v.size() < 2) return 0.0;
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return std::sqrt(ss / static_cast<double>(v.size()) / static_cast<double>(v.size() - 1));
}

}  // namespace

BlockAverage block_average(std::span<const double> series) {
  BlockAverage out;
  const std::size_t n = series.size();
  if (n == 0) return out;
  std::vector<double> level(series.begin(), series.end());
  double sum = 0.0;
  for (double x : level) sum += x;
  out.mean = sum / static_cast<double>(n);
  out.blocks = static_cast<int>(n);
  out.block_length = 1;
  out.standard_error = naive_error(level, out.mean);
  int length = 1;
  while (level.size() >= 2 * static_cast<std::size_t>(kMinBlocks)) {
    std::vector<double> next(level.size() / 2);
    for (std::size_t i = 0; i < next.size(); ++i) next[i] = 0.5 * (level[2 * i] + level[2 * i + 1]);
    level = std::move(next);
    length *= 2;
    double level_sum = 0.0;
    for (double x : level) level_sum += x;
    const double error = naive_error(level, level_sum / static_cast<double>(level.size()));
    if (error > out.standard_error) {
      out.standard_error = error;
      out.blocks = static_cast<int>(level.size());
      out.block_length = length;
    }
  }
  return out;
}

double rigid_sphere_relative_viscosity(double phi) {
  return 1.0 + 2.5 * phi + 6.2 * phi * phi;
}

}  // namespace cellflow::scenes
