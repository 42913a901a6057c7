// Baseline fit and subtraction of preprocess.h.
#include <cmath>
#include <string>

#include "io/afm/preprocess.h"

namespace cellflow::afm {

StatusOr<Baseline> fit_baseline(std::span<const double> x_m, std::span<const double> f_n, std::size_t begin,
                                std::size_t end, bool fit_tilt) {
  if (x_m.size() != f_n.size()) return invalid_argument("fit_baseline: x and f have different lengths");
  end = std::min(end, f_n.size());
  const std::size_t need = fit_tilt ? 3 : 2;
  if (end < begin + need) {
    return invalid_argument("fit_baseline: " + std::to_string(end > begin ? end - begin : 0) +
                            " points in the baseline range, need " + std::to_string(need));
  }
  // Centre x so the normal equations stay well conditioned at micrometre
  // offsets with nanometre spreads.
  const double n = static_cast<double>(end - begin);
  double xm = 0.0, fm = 0.0;
  for (std::size_t i = begin; i < end; ++i) {
    xm += x_m[i];
    fm += f_n[i];
  }
  xm /= n;
  fm /= n;
  double sxx = 0.0, sxf = 0.0;
  for (std::size_t i = begin; i < end; ++i) {
    sxx += (x_m[i] - xm) * (x_m[i] - xm);
    sxf += (x_m[i] - xm) * (f_n[i] - fm);
  }
  Baseline b;
  b.begin = begin;
  b.end = end;
  if (fit_tilt) {
    if (!(sxx > 0.0)) return invalid_argument("fit_baseline: all tip positions equal, cannot fit a tilt");
    b.slope_n_per_m = sxf / sxx;
  }
  b.offset_n = fm - b.slope_n_per_m * xm;
  double ss = 0.0;
  for (std::size_t i = begin; i < end; ++i) {
    const double r = f_n[i] - b.at(x_m[i]);
    ss += r * r;
  }
  b.noise_sigma_n = std::sqrt(ss / (n - static_cast<double>(need - 1)));
  return b;
}

std::vector<double> subtract_baseline(std::span<const double> x_m, std::span<const double> f_n,
                                      const Baseline& baseline) {
  const std::size_t n = std::min(x_m.size(), f_n.size());
  std::vector<double> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = f_n[i] - baseline.at(x_m[i]);
  return out;
}

}  // namespace cellflow::afm
