#include "physics/calibration/models.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "physics/core/violations.h"
#include "physics/elastic/material.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::calibration {

namespace {

double reduced_modulus(double youngs_modulus_pa, double poisson_ratio) {
  // E* = E / (1 - nu^2)
  return youngs_modulus_pa / (1.0 - poisson_ratio * poisson_ratio);
}

}  // namespace

// F = 4/3 E/(1 - nu^2) sqrt(r) d^1.5
double hertz_paraboloid_force_n(double youngs_modulus_pa, double poisson_ratio, double tip_radius_m,
                                double indentation_m) {
  const double d = std::max(0.0, indentation_m);
  return 4.0 / 3.0 * reduced_modulus(youngs_modulus_pa, poisson_ratio) * std::sqrt(tip_radius_m) * d *
         std::sqrt(d);
}

// F = 4/3 E/(1 - nu^2) sqrt(R) d^1.5
double hertz_sphere_on_flat_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                                    double indentation_m) {
  return hertz_paraboloid_force_n(youngs_modulus_pa, poisson_ratio, radius_m, indentation_m);
}

// F = 4/3 E/(1 - nu^2) R^2 eps^1.5, eps = delta/(2R)
double hertz_plates_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                            double compression_m) {
  const elastic::Material m{.youngs_modulus_pa = youngs_modulus_pa, .poisson_ratio = poisson_ratio};
  return scenes::hertz_plates_force_n(m, radius_m, compression_m);
}

// F = 4/3 E* sqrt(R12) d_top^1.5, d_top + d_bottom = delta, equal force through both contacts
double hertz_probe_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                           double probe_radius_m, double indentation_m) {
  const elastic::Material m{.youngs_modulus_pa = youngs_modulus_pa, .poisson_ratio = poisson_ratio};
  return scenes::hertz_probe_force_n(m, radius_m, probe_radius_m, indentation_m);
}

// E = sum w F s / sum w s^2
StatusOr<double> closed_form_modulus(std::span<const double> shape_n_per_pa, std::span<const double> force_n,
                                     std::span<const double> weights) {
  if (shape_n_per_pa.size() != force_n.size() || weights.size() != force_n.size()) {
    return invalid_argument("closed_form_modulus: shape (" + std::to_string(shape_n_per_pa.size()) +
                            "), force (" + std::to_string(force_n.size()) + ") and weights (" +
                            std::to_string(weights.size()) + ") differ in size");
  }
  double a = 0.0, b = 0.0;
  for (std::size_t i = 0; i < force_n.size(); ++i) {
    a += weights[i] * force_n[i] * shape_n_per_pa[i];
    b += weights[i] * shape_n_per_pa[i] * shape_n_per_pa[i];
  }
  if (!(b > 0.0))
    return invalid_argument("closed_form_modulus: no point in contact (every model force is 0)");
  return a / b;
}

// sum w (F - E s)^2 at E = sum w F s / sum w s^2:  sum w F^2 - (sum w F s)^2 / sum w s^2
double closed_form_objective(std::span<const double> shape_n_per_pa, std::span<const double> force_n,
                             std::span<const double> weights) {
  double a = 0.0, b = 0.0, c = 0.0;
  for (std::size_t i = 0; i < force_n.size(); ++i) {
    a += weights[i] * force_n[i] * shape_n_per_pa[i];
    b += weights[i] * shape_n_per_pa[i] * shape_n_per_pa[i];
    c += weights[i] * force_n[i] * force_n[i];
  }
  return b > 0.0 ? std::max(0.0, c - a * a / b) : c;
}

// Grid scan, then golden section: c = (3 - sqrt 5)/2 of the bracket from each end.
Minimum minimise_1d(const std::function<double(double)>& f, double lo, double hi, double tolerance,
                    int grid_points) {
  Minimum best;
  if (!(hi > lo)) {
    best.x = lo;
    best.value = f(lo);
    best.evaluations = 1;
    return best;
  }
  const int n = std::max(3, grid_points);
  const double h = (hi - lo) / (n - 1);
  int best_k = 0;
  best.value = std::numeric_limits<double>::infinity();
  for (int k = 0; k < n; ++k) {
    const double x = k + 1 == n ? hi : lo + k * h;
    const double v = f(x);
    ++best.evaluations;
    if (v < best.value) {
      best.value = v;
      best.x = x;
      best_k = k;
    }
  }
  double a = lo + std::max(0, best_k - 1) * h;
  double b = std::min(hi, lo + std::min(n - 1, best_k + 1) * h);
  constexpr double kGolden = 0.3819660112501051;  // (3 - sqrt 5) / 2
  double x1 = a + kGolden * (b - a), x2 = b - kGolden * (b - a);
  double f1 = f(x1), f2 = f(x2);
  best.evaluations += 2;
  const double tol = std::max(tolerance, 1e-15 * (std::abs(lo) + std::abs(hi)));
  while (b - a > tol) {
    if (f1 <= f2) {
      b = x2;
      x2 = x1;
      f2 = f1;
      x1 = a + kGolden * (b - a);
      f1 = f(x1);
    } else {
      a = x1;
      x1 = x2;
      f1 = f2;
      x2 = b - kGolden * (b - a);
      f2 = f(x2);
    }
    ++best.evaluations;
  }
  if (f1 < best.value) {
    best.value = f1;
    best.x = x1;
  }
  if (f2 < best.value) {
    best.value = f2;
    best.x = x2;
  }
  return best;
}

// P(x0) = min_E sum w (F - E s(x - x0))^2
StatusOr<ContactFit> fit_contact_point(std::span<const double> x_m, std::span<const double> force_n,
                                       std::span<const double> weights,
                                       const std::function<double(double indentation_m)>& shape_n_per_pa,
                                       double x0_lo_m, double x0_hi_m) {
  if (x_m.size() != force_n.size() || weights.size() != force_n.size()) {
    return invalid_argument("fit_contact_point: x (" + std::to_string(x_m.size()) + "), force (" +
                            std::to_string(force_n.size()) + ") and weights (" +
                            std::to_string(weights.size()) + ") differ in size");
  }
  if (!(x0_hi_m >= x0_lo_m) || !std::isfinite(x0_lo_m) || !std::isfinite(x0_hi_m)) {
    return invalid_argument("fit_contact_point: the contact window [" + number_text(x0_lo_m) + ", " +
                            number_text(x0_hi_m) + "] m is empty or not finite");
  }
  std::vector<double> shape(x_m.size());
  auto fill = [&](double x0) {
    for (std::size_t i = 0; i < x_m.size(); ++i) shape[i] = shape_n_per_pa(x_m[i] - x0);
  };
  auto profile = [&](double x0) {
    fill(x0);
    return closed_form_objective(shape, force_n, weights);
  };
  const double span = x0_hi_m - x0_lo_m;
  const Minimum m = minimise_1d(profile, x0_lo_m, x0_hi_m, 1e-9 * std::max(span, 1e-12), 21);
  fill(m.x);
  StatusOr<double> e = closed_form_modulus(shape, force_n, weights);
  if (!e.ok()) {
    return invalid_argument("fit_contact_point: no point in contact for any contact point in [" +
                            number_text(x0_lo_m) + ", " + number_text(x0_hi_m) + "] m");
  }
  ContactFit fit;
  fit.contact_m = m.x;
  fit.youngs_modulus_pa = *e;
  fit.objective = m.value;
  fit.points_in_contact =
      static_cast<int>(std::count_if(shape.begin(), shape.end(), [](double s) { return s > 0; }));
  return fit;
}

}  // namespace cellflow::calibration
