// Helpers shared by the AFM reader tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

namespace cellflow::afm::testing {

inline std::string data_file(const std::string& name) {
  return std::string(CELLFLOW_AFM_DATA_DIR) + "/" + name;
}

// Noise of a slowly varying signal from successive differences (a drift or a
// tilt does not inflate it): sigma = RMS(diff) / sqrt(2).
inline double diff_noise(const std::vector<double>& v, std::size_t begin, std::size_t end) {
  double ss = 0.0;
  for (std::size_t i = begin + 1; i < end; ++i) ss += (v[i] - v[i - 1]) * (v[i] - v[i - 1]);
  return std::sqrt(ss / static_cast<double>(end - begin - 1) / 2.0);
}

inline double mean(const std::vector<double>& v, std::size_t begin, std::size_t end) {
  return std::accumulate(v.begin() + begin, v.begin() + end, 0.0) / static_cast<double>(end - begin);
}

}  // namespace cellflow::afm::testing
