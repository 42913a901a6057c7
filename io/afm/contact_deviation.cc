// Contact point method 1 of preprocess.h: deviation from the baseline.
#include <algorithm>
#include <cmath>
#include <string>

#include "io/afm/preprocess.h"

namespace cellflow::afm {
namespace {

// Index after the last sample (scanning back from the end) whose corrected
// force is at or below the threshold; size() when even the last one is.
std::size_t first_contact_index(std::span<const double> x_m, std::span<const double> f_n, const Baseline& b,
                                double threshold_n) {
  std::size_t i = f_n.size();
  while (i > 0 && f_n[i - 1] - b.at(x_m[i - 1]) > threshold_n) --i;
  return i;
}

}  // namespace

StatusOr<ContactPoint> contact_by_baseline_deviation(std::span<const double> x_m, std::span<const double> f_n,
                                                     const DeviationOptions& options) {
  if (x_m.size() != f_n.size())
    return invalid_argument("contact (deviation): x and f have different lengths");
  const std::size_t n = f_n.size();
  const std::size_t n_base =
      std::max<std::size_t>(3, static_cast<std::size_t>(options.baseline_fraction * static_cast<double>(n)));
  auto base = fit_baseline(x_m, f_n, 0, n_base, options.fit_tilt);
  if (!base.ok()) return base.status();

  std::size_t idx = first_contact_index(x_m, f_n, *base, options.k_sigma * base->noise_sigma_n);
  if (options.refit_baseline && idx < n) {
    const auto margin = static_cast<std::size_t>(options.refit_margin_fraction * static_cast<double>(n));
    if (idx > margin && idx - margin > n_base) {
      auto refit = fit_baseline(x_m, f_n, 0, idx - margin, options.fit_tilt);
      if (refit.ok()) {
        base = std::move(refit);
        idx = first_contact_index(x_m, f_n, *base, options.k_sigma * base->noise_sigma_n);
      }
    }
  }
  if (idx >= n) {
    return invalid_argument("contact (deviation): the force never rises " + std::to_string(options.k_sigma) +
                            " sigma above the baseline at the end of the segment");
  }
  if (idx < n_base) {
    return invalid_argument("contact (deviation): the force leaves the baseline inside the baseline range");
  }
  ContactPoint cp;
  cp.index = idx;
  cp.tip_position_m = x_m[idx];
  cp.baseline = *base;
  return cp;
}

}  // namespace cellflow::afm
