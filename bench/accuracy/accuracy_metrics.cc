#include "bench/accuracy/accuracy_metrics.h"

#include <cmath>
#include <limits>

namespace cellflow::bench {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool valid_positive(double x) {
  return std::isfinite(x) && x > 0.0;
}
}  // namespace

std::vector<double> uniform_grid(double from, double to, double step) {
  std::vector<double> grid;
  const int n = static_cast<int>(std::floor((to - from) / step + 1e-9));
  for (int i = 0; i <= n; ++i) grid.push_back(from + i * step);
  return grid;
}

std::vector<double> forces_on_grid(std::span<const double> deformation, std::span<const double> force,
                                   std::span<const double> grid) {
  std::vector<double> out;
  out.reserve(grid.size());
  for (double eps : grid) {
    double value = kNaN;
    double x0 = 0.0, y0 = 0.0;
    for (std::size_t i = 0; i < deformation.size() && i < force.size(); ++i) {
      const double x1 = deformation[i], y1 = force[i];
      if (eps <= x1 + 1e-12) {
        value = x1 > x0 ? y0 + (y1 - y0) * (eps - x0) / (x1 - x0) : y1;
        break;
      }
      x0 = x1;
      y0 = y1;
    }
    out.push_back(value);
  }
  return out;
}

double max_relative_error(std::span<const double> test, std::span<const double> reference) {
  if (test.size() != reference.size() || test.empty()) return kNaN;
  double worst = 0.0;
  for (std::size_t i = 0; i < test.size(); ++i) {
    const double rel = std::abs(test[i] / reference[i] - 1.0);
    if (!std::isfinite(rel)) return kNaN;
    worst = std::max(worst, rel);
  }
  return worst;
}

double observed_order(double h1, double h2, double h3, double ratio) {
  const auto g = [&](double p) {
    return (std::pow(h3, p) - std::pow(h2, p)) / (std::pow(h2, p) - std::pow(h1, p));
  };
  double lo = 1e-6, hi = 20.0;
  if (!std::isfinite(ratio) || ratio < g(lo) || ratio > g(hi)) return kNaN;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (g(mid) < ratio ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Richardson richardson_extrapolate(double h1, double h2, double h3, std::span<const double> f1,
                                  std::span<const double> f2, std::span<const double> f3) {
  Richardson r;
  r.extrapolated.assign(f1.begin(), f1.end());
  r.order = kNaN;
  const std::size_t n = f1.size();
  if (f2.size() != n || f3.size() != n || n == 0 || !(h1 < h2 && h2 < h3)) return r;
  double dot = 0.0, norm2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double d21 = f2[i] - f1[i], d32 = f3[i] - f2[i];
    dot += d32 * d21;
    norm2 += d21 * d21;
    r.pointwise_order.push_back(d21 != 0.0 ? observed_order(h1, h2, h3, d32 / d21) : kNaN);
  }
  if (!(norm2 > 0.0) || !std::isfinite(dot)) return r;
  r.difference_ratio = dot / norm2;
  r.order = observed_order(h1, h2, h3, r.difference_ratio);
  r.usable = std::isfinite(r.order) && r.order > 0.5 && r.order < 4.0;
  if (r.usable) {
    const double denominator = std::pow(h2 / h1, r.order) - 1.0;
    for (std::size_t i = 0; i < n; ++i) r.extrapolated[i] = f1[i] + (f1[i] - f2[i]) / denominator;
  }
  return r;
}

std::vector<bool> pareto_front(std::span<const double> time_s, std::span<const double> error) {
  const std::size_t n = std::min(time_s.size(), error.size());
  std::vector<bool> front(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid_positive(time_s[i]) || !valid_positive(error[i])) continue;
    bool dominated = false;
    for (std::size_t j = 0; j < n && !dominated; ++j) {
      if (j == i || !valid_positive(time_s[j]) || !valid_positive(error[j])) continue;
      dominated =
          time_s[j] <= time_s[i] && error[j] <= error[i] && (time_s[j] < time_s[i] || error[j] < error[i]);
    }
    front[i] = !dominated;
  }
  return front;
}

}  // namespace cellflow::bench
