// Statistics of the suspension's time series: the mean and its standard
// error from block averaging (Flyvbjerg and Petersen 1989), for samples that
// are correlated in time (a cell's D wobbles over a tank-treading period and
// the cells' collisions correlate the mean over several strain units).
#pragma once

#include <span>

namespace cellflow::scenes {

struct BlockAverage {
  double mean = 0.0;
  double standard_error = 0.0;  // 0 with fewer than 2 values
  int blocks = 0;               // blocks of the level the error was taken from
  int block_length = 0;         // samples per block there
};

// Fewest blocks a level may have to count towards the error.
inline constexpr int kMinBlocks = 8;

// The series is halved level by level (neighbouring values averaged, an odd
// last value dropped); at each level with at least kMinBlocks blocks the
// naive standard error of the block means, s / sqrt(blocks - 1), is computed
// (s the population standard deviation of the block means); the largest over
// the levels is returned: it grows with the block length until the blocks
// are longer than the correlation time and then stays flat (the plateau),
// so the largest value is the plateau or, for series too short to reach it,
// the best lower bound the data give. For uncorrelated values it equals the
// plain s / sqrt(n - 1). Fewer than 2 * kMinBlocks values: the plain error of
// the values themselves.
BlockAverage block_average(std::span<const double> series);

// Unbounded suspension of rigid spheres at volume fraction phi:
// eta_r = 1 + 2.5 phi + 6.2 phi^2 (Einstein's term and Batchelor and Green's
// 1977 second-order coefficient for a pure straining flow, as the issue quotes).
double rigid_sphere_relative_viscosity(double volume_fraction);

}  // namespace cellflow::scenes
