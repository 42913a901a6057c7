// Element-wise conversions and fit-range selection of preprocess.h. The
// baseline and the two contact-point methods live in their own files.
#include "io/afm/preprocess.h"

#include <algorithm>

namespace cellflow::afm {

std::vector<double> tip_position_m(std::span<const double> height_m, std::span<const double> deflection_m) {
  const std::size_t n = std::min(height_m.size(), deflection_m.size());
  std::vector<double> tip(n);
  for (std::size_t i = 0; i < n; ++i) tip[i] = height_m[i] - deflection_m[i];
  return tip;
}

std::vector<double> indentation_m(std::span<const double> x_m, double contact_tip_position_m) {
  std::vector<double> d(x_m.size());
  for (std::size_t i = 0; i < x_m.size(); ++i) d[i] = x_m[i] - contact_tip_position_m;
  return d;
}

std::vector<std::size_t> select_fit_range(std::span<const double> x_m, double contact_tip_position_m,
                                          const FitRange& range) {
  const double shift = range.mode == FitRange::Mode::kRelativeToContact ? contact_tip_position_m : 0.0;
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < x_m.size(); ++i) {
    const double v = x_m[i] - shift;
    if (v >= range.min_m && v <= range.max_m) idx.push_back(i);
  }
  return idx;
}

}  // namespace cellflow::afm
