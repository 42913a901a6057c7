#include "physics/calibration/fit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>

#include "physics/calibration/models.h"
#include "physics/core/violations.h"

namespace cellflow::calibration {

namespace {

// chi-square quantile, 1 degree of freedom, 95 %
constexpr double kChiSquare95 = 3.841458820694124;

// One curve's samples in the fit range, with their weights and its model.
struct Prepared {
  std::string name;
  Geometry geometry = Geometry::kPlates;
  double radius = 0.0, probe_radius = 0.0, r2 = 0.0, two_r = 0.0;
  double window = 0.0;  // s in [-window, window]
  std::vector<double> x, f, weight;
  std::vector<std::size_t> index;
  double c = 0.0;  // sum w F^2
  const CurveInterpolant* model = nullptr;
};

struct Sums {
  double a = 0.0, b = 0.0, c = 0.0;  // sum w F g, sum w g^2, sum w F^2
  Sums& operator+=(const Sums& o) {
    a += o.a;
    b += o.b;
    c += o.c;
    return *this;
  }
  Sums operator-(const Sums& o) const { return {a - o.a, b - o.b, c - o.c}; }
};

// g_i = R^2 f(w, (x_i - s)/(2R)): the model force per unit E
Sums curve_sums(const Prepared& p, double w, double s) {
  Sums out;
  out.c = p.c;
  CurveInterpolant::AtW model = p.model->at_w(w);  // x increasing: eps walks the segments
  for (std::size_t i = 0; i < p.x.size(); ++i) {
    const double g = p.r2 * model.force_scaled((p.x[i] - s) / p.two_r);
    out.a += p.weight[i] * p.f[i] * g;
    out.b += p.weight[i] * g * g;
  }
  return out;
}

// min_E sum w (F - E g)^2 = C - A^2 / B
double objective_free_e(const Sums& t) {
  return t.b > 0.0 ? std::max(0.0, t.c - t.a * t.a / t.b) : t.c;
}
// sum w (F - E g)^2 = C - 2 E A + E^2 B
double objective_at_e(const Sums& t, double e) {
  return std::max(0.0, t.c - 2.0 * e * t.a + e * e * t.b);
}

struct Fix {
  std::optional<double> w, e;
  int s_curve = -1;  // this curve's s fixed at s_value
  double s_value = 0.0;
};

Fix fix_w(double w) {
  Fix f;
  f.w = w;
  return f;
}
Fix fix_e(double e) {
  Fix f;
  f.e = e;
  return f;
}
Fix fix_s(int curve, double s) {
  Fix f;
  f.s_curve = curve;
  f.s_value = s;
  return f;
}

struct Solution {
  double w = 1.0, e = 0.0, objective = 0.0;
  std::vector<double> s;
};

// Brent's minimisation (golden section with parabolic steps) of f on [a, b]
// from x0, to an interval shorter than tolerance: the warm-started searches of
// the profiles, where the previous profile point's optimum lies near the new one.
Minimum brent_1d(const std::function<double(double)>& f, double a, double b, double x0, double tolerance) {
  constexpr double kGolden = 0.3819660112501051;
  Minimum m;
  if (!(b > a)) {
    m.x = a;
    m.value = f(a);
    m.evaluations = 1;
    return m;
  }
  double x = std::clamp(x0, a, b), w = x, v = x;
  double fx = f(x), fw = fx, fv = fx;
  int evaluations = 1;
  double d = 0.0, e = 0.0;
  for (int iter = 0; iter < 200; ++iter) {
    const double mid = 0.5 * (a + b);
    const double tol1 = 0.25 * tolerance, tol2 = 2.0 * tol1;
    if (std::abs(x - mid) <= tol2 - 0.5 * (b - a)) break;
    bool golden = true;
    if (std::abs(e) > tol1) {
      double r = (x - w) * (fx - fv), q = (x - v) * (fx - fw), p = (x - v) * q - (x - w) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      const double e_old = e;
      e = d;
      if (std::abs(p) < std::abs(0.5 * q * e_old) && p > q * (a - x) && p < q * (b - x)) {
        d = p / q;
        const double u = x + d;
        if (u - a < tol2 || b - u < tol2) d = mid >= x ? tol1 : -tol1;
        golden = false;
      }
    }
    if (golden) {
      e = (x >= mid ? a : b) - x;
      d = kGolden * e;
    }
    const double u = std::abs(d) >= tol1 ? x + d : x + (d > 0.0 ? tol1 : -tol1);
    const double fu = f(u);
    ++evaluations;
    if (fu <= fx) {
      (u >= x ? a : b) = x;
      v = w, fv = fw, w = x, fw = fx, x = u, fx = fu;
    } else {
      (u < x ? a : b) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw, w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  m.x = x;
  m.value = fx;
  m.evaluations = evaluations;
  return m;
}

// Local minimum of f in [lo, hi] near x0: Brent in a window of half-width
// `half` around x0, moved and widened while the minimum lies at a window edge
// that is not the range's.
Minimum local_minimise_1d(const std::function<double(double)>& f, double x0, double half, double lo,
                          double hi, double tolerance) {
  Minimum m;
  for (int k = 0; k < 30; ++k) {
    const double a = std::max(lo, x0 - half), b = std::min(hi, x0 + half);
    m = brent_1d(f, a, b, x0, tolerance);
    const bool at_lower = a > lo && m.x - a <= tolerance, at_upper = b < hi && b - m.x <= tolerance;
    if (!at_lower && !at_upper) break;
    x0 = m.x;
    half *= 2.0;
  }
  return m;
}

// A set of curves sharing E and w.
class Problem {
 public:
  Problem(std::vector<const Prepared*> curves, double w_lo, double w_hi, bool fit_contact)
      : curves_(std::move(curves)), w_lo_(w_lo), w_hi_(w_hi), fit_contact_(fit_contact) {}

  std::size_t size() const { return curves_.size(); }
  const Prepared& curve(std::size_t c) const { return *curves_[c]; }
  bool w_free() const { return w_hi_ > w_lo_; }
  double w_lo() const { return w_lo_; }
  double w_hi() const { return w_hi_; }
  bool s_free(std::size_t c) const { return fit_contact_ && curves_[c]->window > 0.0; }

  // min S over the parameters fix leaves free
  Solution solve(const Fix& fix) const {
    Solution sol;
    if (fix.w || !w_free()) {
      sol.w = fix.w ? *fix.w : w_lo_;
    } else {
      Solution scratch;
      sol.w = minimise_1d([&](double w) { return solve_at_w(w, fix, scratch); }, w_lo_, w_hi_, 1e-5, 9).x;
    }
    solve_at_w(sol.w, fix, sol);
    return sol;
  }

  // min S over the parameters fix leaves free, by local searches from start
  // (the optimum of a neighbouring profile point)
  Solution solve_warm(const Fix& fix, const Solution& start) const {
    Solution sol;
    if (fix.w || !w_free()) {
      sol.w = fix.w ? *fix.w : w_lo_;
    } else {
      Solution scratch;
      sol.w = local_minimise_1d([&](double w) { return solve_at_w_warm(w, fix, start.s, scratch); }, start.w,
                                0.02, w_lo_, w_hi_, 1e-5)
                  .x;
    }
    solve_at_w_warm(sol.w, fix, start.s, sol);
    return sol;
  }

 private:
  // Best s_c (and E) at w; returns S and fills sol.s, sol.e, sol.objective.
  double solve_at_w(double w, const Fix& fix, Solution& sol) const {
    const std::size_t n = curves_.size();
    sol.s.assign(n, 0.0);
    sol.w = w;
    std::vector<Sums> sums(n);
    std::vector<bool> free(n);
    for (std::size_t c = 0; c < n; ++c) {
      free[c] = s_free(c) && fix.s_curve != static_cast<int>(c);
      if (fix.s_curve == static_cast<int>(c)) sol.s[c] = fix.s_value;
    }
    const auto minimise_s = [&](std::size_t c, const std::function<double(const Sums&)>& objective, double lo,
                                double hi, int grid) {
      const Prepared& p = *curves_[c];
      const Minimum m = minimise_1d([&](double s) { return objective(curve_sums(p, w, s)); }, lo, hi,
                                    1e-7 * p.radius, grid);
      sol.s[c] = m.x;
      sums[c] = curve_sums(p, w, m.x);
    };
    if (fix.e) {
      // E fixed: the curves separate
      const double e = *fix.e;
      for (std::size_t c = 0; c < n; ++c) {
        if (free[c]) {
          minimise_s(
              c, [e](const Sums& t) { return objective_at_e(t, e); }, -curves_[c]->window, curves_[c]->window,
              11);
        } else {
          sums[c] = curve_sums(*curves_[c], w, sol.s[c]);
        }
      }
      Sums total;
      for (const Sums& t : sums) total += t;
      sol.e = e;
      sol.objective = objective_at_e(total, e);
      return sol.objective;
    }
    // E free: each curve with its own E first, then coordinate descent over
    // the s_c on the joint objective (E re-solved for every trial s_c)
    for (std::size_t c = 0; c < n; ++c) {
      if (free[c]) {
        minimise_s(c, objective_free_e, -curves_[c]->window, curves_[c]->window, 11);
      } else {
        sums[c] = curve_sums(*curves_[c], w, sol.s[c]);
      }
    }
    if (n > 1) {
      for (int sweep = 0; sweep < 30; ++sweep) {
        double largest_move = 0.0, tolerance = 0.0;
        for (std::size_t c = 0; c < n; ++c) {
          if (!free[c]) continue;
          Sums total;
          for (const Sums& t : sums) total += t;
          const Sums others = total - sums[c];
          const double h = curves_[c]->window;
          const double before = sol.s[c];
          minimise_s(
              c,
              [&](const Sums& t) {
                return objective_free_e({others.a + t.a, others.b + t.b, others.c + t.c});
              },
              std::max(-h, before - 0.25 * h), std::min(h, before + 0.25 * h), 5);
          largest_move = std::max(largest_move, std::abs(sol.s[c] - before));
          tolerance = std::max(tolerance, 1e-6 * curves_[c]->radius);
        }
        if (largest_move <= tolerance) break;
      }
    }
    Sums total;
    for (const Sums& t : sums) total += t;
    sol.e = total.b > 0.0 ? total.a / total.b : 0.0;
    sol.objective = objective_free_e(total);
    return sol.objective;
  }

  // solve_at_w by local searches of each s_c from s0
  double solve_at_w_warm(double w, const Fix& fix, const std::vector<double>& s0, Solution& sol) const {
    const std::size_t n = curves_.size();
    sol.s = s0;
    sol.s.resize(n, 0.0);
    sol.w = w;
    std::vector<Sums> sums(n);
    std::vector<bool> free(n);
    for (std::size_t c = 0; c < n; ++c) {
      free[c] = s_free(c) && fix.s_curve != static_cast<int>(c);
      if (fix.s_curve == static_cast<int>(c)) sol.s[c] = fix.s_value;
      if (!s_free(c)) sol.s[c] = 0.0;
    }
    const auto minimise_s = [&](std::size_t c, const std::function<double(const Sums&)>& objective) {
      const Prepared& p = *curves_[c];
      const Minimum m = local_minimise_1d([&](double s) { return objective(curve_sums(p, w, s)); }, sol.s[c],
                                          0.02 * p.window, -p.window, p.window, 1e-7 * p.radius);
      sol.s[c] = m.x;
      sums[c] = curve_sums(p, w, m.x);
    };
    if (fix.e) {
      const double e = *fix.e;
      for (std::size_t c = 0; c < n; ++c) {
        if (free[c]) {
          minimise_s(c, [e](const Sums& t) { return objective_at_e(t, e); });
        } else {
          sums[c] = curve_sums(*curves_[c], w, sol.s[c]);
        }
      }
      Sums total;
      for (const Sums& t : sums) total += t;
      sol.e = e;
      sol.objective = objective_at_e(total, e);
      return sol.objective;
    }
    for (std::size_t c = 0; c < n; ++c) sums[c] = curve_sums(*curves_[c], w, sol.s[c]);
    for (int sweep = 0; sweep < 30; ++sweep) {
      double largest_move = 0.0, tolerance = 0.0;
      int n_free = 0;
      for (std::size_t c = 0; c < n; ++c) {
        if (!free[c]) continue;
        ++n_free;
        Sums total;
        for (const Sums& t : sums) total += t;
        const Sums others = total - sums[c];
        const double before = sol.s[c];
        minimise_s(c, [&](const Sums& t) {
          return objective_free_e({others.a + t.a, others.b + t.b, others.c + t.c});
        });
        largest_move = std::max(largest_move, std::abs(sol.s[c] - before));
        tolerance = std::max(tolerance, 1e-6 * curves_[c]->radius);
      }
      if (n_free <= 1 || largest_move <= tolerance) break;
    }
    Sums total;
    for (const Sums& t : sums) total += t;
    sol.e = total.b > 0.0 ? total.a / total.b : 0.0;
    sol.objective = objective_free_e(total);
    return sol.objective;
  }

  std::vector<const Prepared*> curves_;
  double w_lo_ = 0.0, w_hi_ = 1.0;
  bool fit_contact_ = true;
};

// The root of g in the bracket [inside, outside], g(inside) <= 0 < g(outside),
// by Brent's method (inverse quadratic and secant steps, bisection when they
// fail), to a bracket of width 2 tolerance; returns the end with g <= 0. A
// profile is smooth near its threshold: about 5 evaluations where bisection
// to the same tolerance takes 16.
double threshold_crossing(const std::function<double(double)>& g, double inside, double g_inside,
                          double outside, double g_outside, double tolerance) {
  double a = inside, b = outside, c = outside, fa = g_inside, fb = g_outside, fc = g_outside;
  double d = b - a, e = d;
  for (int iter = 0; iter < 100; ++iter) {
    if ((fb > 0.0) == (fc > 0.0)) {
      c = a, fc = fa;
      d = e = b - a;
    }
    if (std::abs(fc) < std::abs(fb)) {
      a = b, b = c, c = a;
      fa = fb, fb = fc, fc = fa;
    }
    const double tol1 = 2.0 * std::numeric_limits<double>::epsilon() * std::abs(b) + 0.5 * tolerance;
    const double xm = 0.5 * (c - b);
    if (std::abs(xm) <= tol1 || fb == 0.0) break;
    if (std::abs(e) >= tol1 && std::abs(fa) > std::abs(fb)) {
      double p, q;
      const double s = fb / fa;
      if (a == c) {  // secant
        p = 2.0 * xm * s;
        q = 1.0 - s;
      } else {  // inverse quadratic
        const double qa = fa / fc, r = fb / fc;
        p = s * (2.0 * xm * qa * (qa - r) - (b - a) * (r - 1.0));
        q = (qa - 1.0) * (r - 1.0) * (s - 1.0);
      }
      if (p > 0.0) q = -q;
      p = std::abs(p);
      if (2.0 * p < std::min(3.0 * xm * q - std::abs(tol1 * q), std::abs(e * q))) {
        e = d;
        d = p / q;
      } else {
        d = e = xm;
      }
    } else {
      d = e = xm;
    }
    a = b, fa = fb;
    b += std::abs(d) > tol1 ? d : (xm > 0.0 ? tol1 : -tol1);
    fb = g(b);
  }
  // b and c bracket the crossing (or b is on it): the end inside the threshold
  return fb <= 0.0 ? b : c;
}

// The 95 % profile interval of one parameter at its optimum `best` (where
// the profile is best_value): profile(theta) <= threshold inside; bounded by
// [lo, hi]. Steps doubling from `step` until outside, then the crossing to
// 2^-16 of the last step.
Estimate profile_interval(double best, double best_value, double lo, double hi, double step, double threshold,
                          const std::function<double(double)>& profile) {
  Estimate est;
  est.value = best;
  for (const int direction : {+1, -1}) {
    const double bound = direction > 0 ? hi : lo;
    double inside = best, delta = step, outside = best;
    double value_inside = best_value, value_outside = 0.0;
    bool at_bound = false;
    for (;;) {
      double trial = best + direction * delta;
      if (direction > 0 ? trial >= bound : trial <= bound) trial = bound;
      const double value = profile(trial);
      if (value > threshold) {
        outside = trial;
        value_outside = value;
        break;
      }
      inside = trial;
      value_inside = value;
      if (trial == bound) {
        at_bound = true;
        break;
      }
      delta *= 2.0;
    }
    if (!at_bound) {
      const auto g = [&](double theta) { return profile(theta) - threshold; };
      inside = threshold_crossing(g, inside, std::min(0.0, value_inside - threshold), outside,
                                  value_outside - threshold, std::ldexp(std::abs(outside - inside), -16));
    }
    if (direction > 0) {
      est.upper = inside;
      est.upper_at_bound = at_bound;
    } else {
      est.lower = inside;
      est.lower_at_bound = at_bound;
    }
  }
  return est;
}

Estimate fixed_estimate(double value) {
  return Estimate{.value = value, .lower = value, .upper = value, .fixed = true};
}

// F / E of the Hertz model of the curve's geometry at deformation eps
double hertz_shape(const Prepared& p, double poisson_ratio, double eps) {
  const double delta = eps * p.two_r;
  return p.geometry == Geometry::kProbe
             ? hertz_probe_force_n(1.0, poisson_ratio, p.radius, p.probe_radius, delta)
             : hertz_plates_force_n(1.0, poisson_ratio, p.radius, delta);
}

ParameterFit run_fit(const Problem& problem, const FitOptions& options) {
  const Solution best = problem.solve({});
  ParameterFit fit;
  int n_points = 0;
  for (std::size_t c = 0; c < problem.size(); ++c) n_points += static_cast<int>(problem.curve(c).x.size());
  int n_params = 1 + (problem.w_free() ? 1 : 0);
  for (std::size_t c = 0; c < problem.size(); ++c) n_params += problem.s_free(c) ? 1 : 0;
  fit.points = n_points;
  fit.parameters = n_params;
  fit.objective = best.objective;
  fit.rms_relative_residual = std::sqrt(best.objective / n_points);
  // S_prof(theta) - S_min <= 3.841 S_min / (N - p)
  const double threshold = best.objective * (1.0 + kChiSquare95 / (n_points - n_params));

  // Each profile point's optimum starts from the previous point's (from the
  // optimum at the start of each direction); exact_profiles re-solves each from scratch.
  const auto profile = [&](double centre, const std::function<Fix(double)>& fix) {
    auto last = std::make_shared<Solution>(best);
    auto side = std::make_shared<int>(0);
    return [&problem, &options, &best, centre, fix, last, side](double theta) {
      if (options.exact_profiles) return problem.solve(fix(theta)).objective;
      const int now = theta > centre ? 1 : -1;
      if (now != *side) *last = best, *side = now;
      *last = problem.solve_warm(fix(theta), *last);
      return last->objective;
    };
  };
  fit.youngs_modulus_pa = profile_interval(best.e, best.objective, 1e-6 * best.e, 1e6 * best.e, 0.01 * best.e,
                                           threshold, profile(best.e, fix_e));
  fit.mooney_rivlin_w = problem.w_free()
                            ? profile_interval(best.w, best.objective, problem.w_lo(), problem.w_hi(), 0.01,
                                               threshold, profile(best.w, fix_w))
                            : fixed_estimate(best.w);
  for (std::size_t c = 0; c < problem.size(); ++c) {
    const Prepared& p = problem.curve(c);
    CurvePart part;
    part.name = p.name;
    part.contact_offset_m =
        problem.s_free(c)
            ? profile_interval(best.s[c], best.objective, -p.window, p.window, 0.002 * p.radius, threshold,
                               profile(best.s[c], [c](double s) { return fix_s(static_cast<int>(c), s); }))
            : fixed_estimate(best.s[c]);
    part.points = p.index;
    double sum = 0.0;
    for (std::size_t i = 0; i < p.x.size(); ++i) {
      const double eps = (p.x[i] - best.s[c]) / p.two_r;
      const double model = best.e * p.r2 * p.model->force_scaled(best.w, eps);
      part.deformation.push_back(eps);
      part.model_force_n.push_back(model);
      sum += p.weight[i] * (p.f[i] - model) * (p.f[i] - model);
    }
    part.rms_relative_residual = std::sqrt(sum / std::max<std::size_t>(1, p.x.size()));
    fit.curves.push_back(std::move(part));
  }
  // Hertz E beside it, at the fitted contact points
  std::vector<double> shape, force, weight;
  for (std::size_t c = 0; c < problem.size(); ++c) {
    const Prepared& p = problem.curve(c);
    for (std::size_t i = 0; i < p.x.size(); ++i) {
      const double eps = (p.x[i] - best.s[c]) / p.two_r;
      if (eps > 0.0 && eps <= options.hertz_max_deformation) {
        shape.push_back(hertz_shape(p, options.poisson_ratio, eps));
        force.push_back(p.f[i]);
        weight.push_back(p.weight[i]);
      }
    }
  }
  fit.hertz_points = static_cast<int>(shape.size());
  if (StatusOr<double> e = closed_form_modulus(shape, force, weight); e.ok() && !shape.empty()) {
    fit.hertz_youngs_modulus_pa = *e;
  }
  return fit;
}

Status validate_options(const FitOptions& o) {
  Violations v;
  if (!(o.poisson_ratio > -1.0 && o.poisson_ratio < 0.5))
    v.add_value("poisson_ratio", o.poisson_ratio, "lie in (-1, 0.5)");
  if (o.mooney_rivlin_w && !(*o.mooney_rivlin_w >= 0.0 && *o.mooney_rivlin_w <= 1.0)) {
    v.add_value("mooney_rivlin_w", *o.mooney_rivlin_w, "lie in [0, 1] (or be unset to fit it)");
  }
  if (!(o.max_deformation > 0.0 && o.max_deformation < 0.9)) {
    v.add_value("max_deformation", o.max_deformation, "lie in (0, 0.9)");
  }
  if (!(o.min_deformation > -1.0 && o.min_deformation < o.max_deformation)) {
    v.add_value("min_deformation", o.min_deformation,
                "lie in (-1, max_deformation = " + number_text(o.max_deformation) + ")");
  }
  if (!(o.contact_window_radii >= 0.0 && o.contact_window_radii <= 0.5)) {
    v.add_value("contact_window_radii", o.contact_window_radii, "lie in [0, 0.5]");
  }
  if (!(o.hertz_max_deformation > 0.0 && o.hertz_max_deformation <= 0.9)) {
    v.add_value("hertz_max_deformation", o.hertz_max_deformation, "lie in (0, 0.9]");
  }
  if (!(o.relative_force_floor >= 0.0 && o.relative_force_floor < 1.0)) {
    v.add_value("relative_force_floor", o.relative_force_floor, "lie in [0, 1)");
  }
  if (!o.per_curve && !o.joint) v.add("per_curve", "and joint are both false: nothing to fit");
  const double window = o.fit_contact_point ? o.contact_window_radii : 0.0;
  const double reach = o.max_deformation + 0.5 * window;
  if (v.empty() && o.numerics.max_deformation < reach * (1.0 - 1e-12)) {
    v.add_value("numerics.max_deformation", o.numerics.max_deformation,
                "reach max_deformation + contact_window_radii / 2 = " + number_text(reach) +
                    " (the deepest deformation a fitted contact point can ask of the library curves)");
  }
  return v.status("fit.");
}

// Every field of one curve; the samples in the fit range.
Status prepare_curve(const MeasuredCurve& m, std::size_t index, const FitOptions& o, Prepared& p) {
  Violations v;
  const std::size_t n = m.indentation_m.size();
  if (!(m.radius_m > 0.0 && std::isfinite(m.radius_m)))
    v.add_value("radius_m", m.radius_m, "be > 0 and finite");
  if (m.geometry == Geometry::kProbe && !(m.probe_radius_m > 0.0 && std::isfinite(m.probe_radius_m))) {
    v.add_value("probe_radius_m", m.probe_radius_m,
                "be > 0 for the probe geometry (the probe radius is missing)");
  }
  if (!(m.force_noise_n >= 0.0 && std::isfinite(m.force_noise_n))) {
    v.add_value("force_noise_n", m.force_noise_n, "be >= 0 and finite");
  }
  if (m.force_n.size() != n) {
    v.add("force_n",
          "has " + std::to_string(m.force_n.size()) + " samples, indentation_m " + std::to_string(n));
  }
  if (n == 0) v.add("indentation_m", "is empty");
  if (!v.empty()) return v.status("curves[" + std::to_string(index) + "].");
  const double two_r = 2.0 * m.radius_m;
  for (std::size_t i = 0; i < n; ++i) {
    std::string at = "[";  // built in steps: GCC 12 warns (-Wrestrict, a false positive) on "[" + to_string
    at += std::to_string(i);
    at += ']';
    if (!std::isfinite(m.indentation_m[i])) {
      v.add_value("indentation_m" + at, m.indentation_m[i], "be finite");
    } else if (i > 0 && !(m.indentation_m[i] > m.indentation_m[i - 1])) {
      v.add("indentation_m" + at, "= " + number_text(m.indentation_m[i]) + " is not above indentation_m[" +
                                      std::to_string(i - 1) + "] = " + number_text(m.indentation_m[i - 1]) +
                                      ": the deformation must increase strictly (sort or bin the approach)");
    } else if (m.indentation_m[i] / two_r >= 1.0) {
      v.add("indentation_m" + at, "= " + number_text(m.indentation_m[i]) + " is a deformation x/(2R) = " +
                                      number_text(m.indentation_m[i] / two_r, 4) +
                                      " >= 1: more than the cell's diameter (check radius_m and the units)");
    }
    if (!std::isfinite(m.force_n[i])) {
      v.add_value("force_n" + at, m.force_n[i], "be finite");
    } else if (m.force_n[i] < -3.0 * m.force_noise_n) {
      v.add("force_n" + at,
            "= " + number_text(m.force_n[i]) +
                " is negative (beyond 3 force_noise_n = " + number_text(3.0 * m.force_noise_n) +
                "): subtract the baseline so the free cantilever reads 0, or give force_noise_n");
    }
    if (!v.empty()) break;  // the first bad sample is named; the rest likely follow it
  }
  if (!v.empty()) return v.status("curves[" + std::to_string(index) + "].");

  p.name = m.name.empty() ? "curves[" + std::to_string(index) + "]" : m.name;
  p.geometry = m.geometry;
  p.radius = m.radius_m;
  p.probe_radius = m.probe_radius_m;
  p.r2 = m.radius_m * m.radius_m;
  p.two_r = two_r;
  p.window = o.fit_contact_point ? o.contact_window_radii * m.radius_m : 0.0;
  double max_force = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double eps = m.indentation_m[i] / two_r;
    if (eps >= o.min_deformation && eps <= o.max_deformation) {
      p.index.push_back(i);
      p.x.push_back(m.indentation_m[i]);
      p.f.push_back(m.force_n[i]);
      max_force = std::max(max_force, m.force_n[i]);
    }
  }
  if (p.index.empty()) {
    return invalid_argument("curves[" + std::to_string(index) + "] (" + p.name +
                            "): no sample in the fit range: deformation x/(2R) in [" +
                            number_text(o.min_deformation) + ", " + number_text(o.max_deformation) +
                            "] (the curve spans [" + number_text(m.indentation_m.front() / two_r, 4) + ", " +
                            number_text(m.indentation_m.back() / two_r, 4) + "])");
  }
  if (!(max_force > 0.0)) {
    return invalid_argument("curves[" + std::to_string(index) + "] (" + p.name +
                            "): no positive force in the fit range: nothing to fit E to");
  }
  // sigma_i = max(|F_i|, floor), floor = max(force_noise_n, relative_force_floor max F)
  const double floor = std::max({m.force_noise_n, o.relative_force_floor * max_force, 1e-300});
  for (std::size_t i = 0; i < p.f.size(); ++i) {
    const double sigma = std::max(std::abs(p.f[i]), floor);
    p.weight.push_back(1.0 / (sigma * sigma));
    p.c += p.weight.back() * p.f[i] * p.f[i];
  }
  return Status::ok_status();
}

}  // namespace

StatusOr<FitResult> fit_curves(const std::vector<MeasuredCurve>& curves, const FitOptions& options,
                               CurveLibrary& library) {
  if (curves.empty()) return invalid_argument("curves: no curve to fit");
  if (Status s = validate_options(options); !s.ok()) return s;
  std::vector<Prepared> prepared(curves.size());
  for (std::size_t c = 0; c < curves.size(); ++c) {
    if (Status s = prepare_curve(curves[c], c, options, prepared[c]); !s.ok()) return s;
  }
  const int sims_before = library.simulations_run();
  FitResult result;

  // One interpolant per library key, covering the deepest deformation its curves can ask for.
  std::map<std::string, CurveKey> keys;
  std::map<std::string, double> needed;
  std::vector<std::string> key_of(curves.size());
  for (std::size_t c = 0; c < curves.size(); ++c) {
    CurveKey key;
    key.geometry = curves[c].geometry;
    key.probe_to_cell_radius =
        key.geometry == Geometry::kProbe ? curves[c].probe_radius_m / curves[c].radius_m : 0.0;
    key.poisson_ratio = options.poisson_ratio;
    key.numerics = options.numerics;
    key_of[c] = curve_key_text(key, -1.0, library.options());
    keys[key_of[c]] = key;
    const Prepared& p = prepared[c];
    const double reach = std::min(options.numerics.max_deformation, (p.x.back() + p.window) / p.two_r);
    needed[key_of[c]] = std::max(needed[key_of[c]], reach);
  }
  std::map<std::string, CurveInterpolant> models;
  double w_lo = 0.0, w_hi = 1.0;
  for (const auto& [text, key] : keys) {
    StatusOr<CurveInterpolant> model =
        options.mooney_rivlin_w ? library.fixed_w_interpolant(key, *options.mooney_rivlin_w, needed[text])
                                : library.grid_interpolant(key, needed[text]);
    if (!model.ok()) return model.status();
    w_lo = std::max(w_lo, model->w_min());
    w_hi = std::min(w_hi, model->w_max());
    models[text] = std::move(*model);
  }
  if (!options.mooney_rivlin_w && w_lo > 0.0) {
    result.notes.push_back("w searched in [" + number_text(w_lo) + ", " + number_text(w_hi) +
                           "]: library curves of smaller w end before the deformation the fit needs");
  }
  if (options.mooney_rivlin_w) w_lo = w_hi = *options.mooney_rivlin_w;
  for (std::size_t c = 0; c < curves.size(); ++c) prepared[c].model = &models[key_of[c]];

  const auto parameters = [&](std::size_t n_curves) {
    return 1 + (options.mooney_rivlin_w ? 0 : 1) +
           (options.fit_contact_point && options.contact_window_radii > 0.0 ? static_cast<int>(n_curves) : 0);
  };
  if (options.per_curve) {
    for (std::size_t c = 0; c < curves.size(); ++c) {
      if (static_cast<int>(prepared[c].x.size()) <= parameters(1)) {
        return invalid_argument("curves[" + std::to_string(c) + "] (" + prepared[c].name + "): " +
                                std::to_string(prepared[c].x.size()) + " samples in the fit range for " +
                                std::to_string(parameters(1)) + " parameters: widen the fit range");
      }
      result.per_curve.push_back(
          run_fit(Problem({&prepared[c]}, w_lo, w_hi, options.fit_contact_point), options));
    }
  }
  if (options.joint) {
    std::vector<const Prepared*> all;
    std::size_t n_points = 0;
    for (const Prepared& p : prepared) {
      all.push_back(&p);
      n_points += p.x.size();
    }
    if (static_cast<int>(n_points) <= parameters(curves.size())) {
      return invalid_argument("curves: " + std::to_string(n_points) + " samples in the fit range for " +
                              std::to_string(parameters(curves.size())) + " parameters: widen the fit range");
    }
    result.joint = run_fit(Problem(all, w_lo, w_hi, options.fit_contact_point), options);
  }
  result.simulations_run = library.simulations_run() - sims_before;
  return result;
}

// F = E R^2 f(w, delta/(2R))
StatusOr<double> scene_force_n(CurveLibrary& library, const CurveKey& key, double youngs_modulus_pa,
                               double mooney_rivlin_w, double radius_m, double indentation_m) {
  if (!(radius_m > 0.0)) return invalid_argument("radius_m = " + number_text(radius_m) + " must be > 0");
  const double eps = indentation_m / (2.0 * radius_m);
  StatusOr<CurveInterpolant> model =
      library.fixed_w_interpolant(key, mooney_rivlin_w, std::min(eps, key.numerics.max_deformation));
  if (!model.ok()) return model.status();
  if (eps > model->max_deformation() * (1.0 + 1e-12)) {
    return invalid_argument("deformation " + number_text(eps) + " beyond the library curve's " +
                            number_text(model->max_deformation()));
  }
  return youngs_modulus_pa * radius_m * radius_m * model->force_scaled(mooney_rivlin_w, eps);
}

}  // namespace cellflow::calibration
