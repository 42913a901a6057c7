// The D3Q19 velocity set in lattice units (dx = dt = 1, c_s^2 = 1/3).
// Ordering: 0 is the rest population; 1..9 point into the positive half
// space and i + 9 is the opposite of i, so TRT pairs are (i, i + 9).
#pragma once

#include <array>

namespace cellflow::lb {

inline constexpr int kQ = 19;     // number of lattice velocities
inline constexpr int kPairs = 9;  // (i, i + 9), i = 1..9

// c_i, one array per component
inline constexpr std::array<int, kQ> kCx = {0, 1, 0, 0, 1, 1, 1, 1, 0, 0, -1, 0, 0, -1, -1, -1, -1, 0, 0};
inline constexpr std::array<int, kQ> kCy = {0, 0, 1, 0, 1, -1, 0, 0, 1, 1, 0, -1, 0, -1, 1, 0, 0, -1, -1};
inline constexpr std::array<int, kQ> kCz = {0, 0, 0, 1, 0, 0, 1, -1, 1, -1, 0, 0, -1, 0, 0, -1, 1, -1, 1};

// w_0 = 1/3, w_axis = 1/18, w_diagonal = 1/36
inline constexpr std::array<double, kQ> kWeight = {1.0 / 3.0,  1.0 / 18.0, 1.0 / 18.0, 1.0 / 18.0, 1.0 / 36.0,
                                                   1.0 / 36.0, 1.0 / 36.0, 1.0 / 36.0, 1.0 / 36.0, 1.0 / 36.0,
                                                   1.0 / 18.0, 1.0 / 18.0, 1.0 / 18.0, 1.0 / 36.0, 1.0 / 36.0,
                                                   1.0 / 36.0, 1.0 / 36.0, 1.0 / 36.0, 1.0 / 36.0};

inline constexpr double kCs2 = 1.0 / 3.0;  // speed of sound squared

// Index of -c_i.
constexpr int opposite(int i) {
  return i == 0 ? 0 : (i <= kPairs ? i + kPairs : i - kPairs);
}

}  // namespace cellflow::lb
