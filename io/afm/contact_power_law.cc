// Contact point method 2 of preprocess.h: piecewise baseline + power law.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "io/afm/preprocess.h"

namespace cellflow::afm {
namespace {

struct Solution {
  double sse = std::numeric_limits<double>::infinity();
  std::array<double, 3> c{};  // offset, tilt, amplitude in scaled units
};

// Solves the m x m system a c = b (m <= 3) by Gaussian elimination with
// partial pivoting; false when singular.
bool solve(std::array<std::array<double, 3>, 3> a, std::array<double, 3> b, int m, std::array<double, 3>& c) {
  for (int col = 0; col < m; ++col) {
    int piv = col;
    for (int r = col + 1; r < m; ++r) {
      if (std::abs(a[r][col]) > std::abs(a[piv][col])) piv = r;
    }
    if (!(std::abs(a[piv][col]) > 1e-300)) return false;
    std::swap(a[piv], a[col]);
    std::swap(b[piv], b[col]);
    for (int r = col + 1; r < m; ++r) {
      const double q = a[r][col] / a[col][col];
      for (int k = col; k < m; ++k) a[r][k] -= q * a[col][k];
      b[r] -= q * b[col];
    }
  }
  for (int r = m - 1; r >= 0; --r) {
    double s = b[r];
    for (int k = r + 1; k < m; ++k) s -= a[r][k] * c[k];
    c[r] = s / a[r][r];
  }
  return true;
}

// Model in scaled coordinates u = (x - x_min) / L, g = f / f_scale:
// g = c0 + c1 u + c2 max(0, u - u0)^p. Linear in c for a fixed u0.
class ScaledProblem {
 public:
  ScaledProblem(std::span<const double> u, std::span<const double> g, double p, bool tilt)
      : u_(u), g_(g), p_(p), tilt_(tilt) {}

  Solution solve_at(double u0) const {
    // Columns: 1, [u], h = max(0, u - u0)^p. Unknowns packed as [c0, (c1), c2].
    const int m = tilt_ ? 3 : 2;
    std::array<std::array<double, 3>, 3> a{};
    std::array<double, 3> b{};
    std::size_t in_contact = 0;
    for (std::size_t i = 0; i < u_.size(); ++i) {
      const double d = u_[i] - u0;
      const double h = d > 0.0 ? std::pow(d, p_) : 0.0;
      in_contact += d > 0.0;
      const std::array<double, 3> col =
          tilt_ ? std::array<double, 3>{1.0, u_[i], h} : std::array<double, 3>{1.0, h, 0.0};
      for (int r = 0; r < m; ++r) {
        for (int k = 0; k < m; ++k) a[r][k] += col[r] * col[k];
        b[r] += col[r] * g_[i];
      }
    }
    Solution s;
    if (in_contact < 2) return s;
    std::array<double, 3> c{};
    if (!solve(a, b, m, c)) return s;
    s.c = tilt_ ? c : std::array<double, 3>{c[0], 0.0, c[1]};
    double sse = 0.0;
    for (std::size_t i = 0; i < u_.size(); ++i) {
      const double d = u_[i] - u0;
      const double h = d > 0.0 ? std::pow(d, p_) : 0.0;
      const double r = g_[i] - (s.c[0] + s.c[1] * u_[i] + s.c[2] * h);
      sse += r * r;
    }
    s.sse = sse;
    return s;
  }

 private:
  std::span<const double> u_, g_;
  double p_;
  bool tilt_;
};

}  // namespace

StatusOr<PowerLawFit> contact_by_power_law_fit(std::span<const double> x_m, std::span<const double> f_n,
                                               const PowerLawFitOptions& options) {
  const std::size_t n = f_n.size();
  if (x_m.size() != n) return invalid_argument("contact (power-law fit): x and f have different lengths");
  if (n < 8) return invalid_argument("contact (power-law fit): " + std::to_string(n) + " points, need 8");
  if (!(options.exponent > 0.0)) return invalid_argument("contact (power-law fit): exponent must be > 0");
  const auto [xmin_it, xmax_it] = std::minmax_element(x_m.begin(), x_m.end());
  const double x_min = *xmin_it;
  const double length = *xmax_it - x_min;
  if (!(length > 0.0)) return invalid_argument("contact (power-law fit): all tip positions equal");
  double f_scale = 0.0;
  for (double f : f_n) f_scale = std::max(f_scale, std::abs(f));
  if (!(f_scale > 0.0)) return invalid_argument("contact (power-law fit): force is zero everywhere");

  std::vector<double> u(n), g(n);
  for (std::size_t i = 0; i < n; ++i) {
    u[i] = (x_m[i] - x_min) / length;
    g[i] = f_n[i] / f_scale;
  }
  const ScaledProblem problem(u, g, options.exponent, options.fit_tilt);

  // Coarse grid first: the residual is not unimodal over the whole range
  // (noise and a tilted baseline make shallow local minima).
  const int grid = std::max(options.grid_points, 3);
  const double lo = options.search_begin_fraction, hi = options.search_end_fraction;
  int best = -1;
  Solution best_sol;
  for (int k = 0; k < grid; ++k) {
    const double u0 = lo + (hi - lo) * k / (grid - 1);
    const Solution s = problem.solve_at(u0);
    if (s.sse < best_sol.sse) {
      best_sol = s;
      best = k;
    }
  }
  if (best < 0) return invalid_argument("contact (power-law fit): no candidate contact could be fitted");

  // Golden-section refinement between the best grid point's neighbours.
  const double step = (hi - lo) / (grid - 1);
  double a = std::max(lo, lo + step * (best - 1)), b = std::min(hi, lo + step * (best + 1));
  const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - phi * (b - a), d = a + phi * (b - a);
  Solution sc = problem.solve_at(c), sd = problem.solve_at(d);
  for (int it = 0; it < 60 && (b - a) > 1e-9; ++it) {
    if (sc.sse < sd.sse) {
      b = d;
      d = c;
      sd = sc;
      c = b - phi * (b - a);
      sc = problem.solve_at(c);
    } else {
      a = c;
      c = d;
      sc = sd;
      d = a + phi * (b - a);
      sd = problem.solve_at(d);
    }
  }
  double u0 = lo + step * best;
  for (auto [uu, ss] : {std::pair{c, sc}, std::pair{d, sd}}) {
    if (ss.sse < best_sol.sse) {
      best_sol = ss;
      u0 = uu;
    }
  }
  if (!(best_sol.c[2] > 0.0)) {
    return invalid_argument("contact (power-law fit): best fit has no repulsive contact (amplitude <= 0)");
  }

  PowerLawFit fit;
  const double x0 = x_min + u0 * length;
  fit.contact.tip_position_m = x0;
  std::size_t idx = n;  // first sample beyond x0 counted back from the end
  while (idx > 0 && x_m[idx - 1] > x0) --idx;
  fit.contact.index = std::min(idx, n - 1);
  // Back to SI: f = f_scale (c0 + c1 (x - x_min)/L + c2 ((x - x0)/L)^p).
  Baseline& base = fit.contact.baseline;
  base.slope_n_per_m = f_scale * best_sol.c[1] / length;
  base.offset_n = f_scale * best_sol.c[0] - base.slope_n_per_m * x_min;
  base.begin = 0;
  base.end = fit.contact.index;
  fit.amplitude_n_per_m_pow = f_scale * best_sol.c[2] / std::pow(length, options.exponent);
  fit.rms_residual_n = f_scale * std::sqrt(best_sol.sse / static_cast<double>(n));
  base.noise_sigma_n = fit.rms_residual_n;
  return fit;
}

}  // namespace cellflow::afm
