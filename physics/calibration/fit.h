// Fit of E, the Mooney-Rivlin ratio w and the contact point to measured force
// curves with cellflow's compression or indentation scene as the model
// (issue 14, items 2-4). The caller passes arrays (io/afm reads and
// preprocesses the instrument's files; this module reads none).
//
// Model of curve c, point i: F_ci = E R_c^2 f_c(w, (x_ci - s_c) / (2 R_c)), f the
// library's dimensionless scene curve (curve_library.h), x_ci the indentation
// the caller measured from a first contact estimate, s_c the contact offset
// (the fitted contact lies s_c beyond that estimate).
//
// Objective (noise model): relative residuals with an absolute floor,
//   S = sum_ci ((F_ci - model_ci) / sigma_ci)^2,  sigma_ci = max(|F_ci|, floor_c),
//   floor_c = max(force_noise_n, relative_force_floor * max_i F_ci),
// i.e. multiplicative noise of unknown size (the force of a cell spans three
// decades over a curve; an absolute residual would fit the last points only)
// with the instrument's noise as a floor near contact. sigma depends on the
// data alone, so E stays a closed-form solve:
//   E = sum w F g / sum w g^2,  w = 1/sigma^2,  g = R^2 f,  S = sum w F^2 - (sum w F g)^2 / sum w g^2.
// s_c is fitted by minimise_1d (grid scan + golden section) in
// [-contact_window_radii R_c, +contact_window_radii R_c] on the profile over E;
// w (when free) by minimise_1d in [0, 1] on the profile over E and s.
// In a joint fit E and w are shared and every curve keeps its own s_c
// (coordinate descent over the s_c, each on the joint objective with E re-solved).
//
// 95 % intervals from the profile of S: with the residual variance estimated
// from the fit, sigma2 = S_min / (N - p) (N points, p fitted parameters), a
// value theta of one parameter is inside when
//   S_prof(theta) - S_min <= 3.841 sigma2       (chi-square, 1 degree of freedom, 95 %)
// where S_prof(theta) minimises S over all other parameters at that theta.
// The bounds are found by doubling steps, then the crossing of the threshold
// by Brent's root finding to 2^-16 of the last step; a bound that reaches
// the parameter's range (w in [0, 1], the contact window, E > 0) is reported
// there and flagged. Noiseless data (S_min = 0) give intervals of zero width.
// Each profile point's minimisation starts from the previous point's optimum
// (local Brent searches of w and the s_c; FitOptions::exact_profiles re-solves
// each from scratch with the global scans instead).
// When library curves of small w end before the deepest deformation the fit
// needs (coarse meshes crush there), w is searched only down to the last
// grid w whose curve reaches it; FitResult::notes says so, and an estimate at
// that end is flagged lower_at_bound.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "physics/calibration/curve_library.h"
#include "physics/core/status.h"

namespace cellflow::calibration {

struct MeasuredCurve {
  std::string name;  // for messages and results
  Geometry geometry = Geometry::kPlates;
  double radius_m = 0.0;        // cell radius R, > 0
  double probe_radius_m = 0.0;  // probe radius Rp, > 0 for kProbe
  // Indentation x (plate or probe travel) from a first contact estimate, m,
  // strictly increasing, x / (2R) < 1; samples before that estimate (x < 0)
  // may be included and count as pre-contact when the fit puts the contact
  // beyond them.
  std::vector<double> indentation_m;
  std::vector<double> force_n;  // baseline-subtracted; >= -3 force_noise_n
  double force_noise_n = 0.0;   // noise of the free cantilever (Baseline::noise_sigma_n); >= 0
};

struct FitOptions {
  double poisson_ratio = 0.48;            // nu, fixed; in (-1, 0.5)
  std::optional<double> mooney_rivlin_w;  // fixed w in [0, 1]; unset: fitted in [0, 1]
  double min_deformation = -0.05;         // fit range on x / (2R); in (-1, max_deformation)
  double max_deformation = 0.7;           // in (min_deformation, 0.9)
  bool fit_contact_point = true;          // false: s_c = 0
  double contact_window_radii = 0.1;      // s_c in [-c R, c R]; c in [0, 0.5]
  double hertz_max_deformation = 0.1;     // Hertz E over 0 < (x - s)/(2R) <= this; in (0, 0.9]
  double relative_force_floor = 0.01;     // in [0, 1)
  bool per_curve = true;                  // one fit per curve
  bool joint = true;                      // one fit of all curves (shared E and w)
  LibraryNumerics numerics;               // of the library curves
  // Profile intervals: false (default) warm-starts each profile point's
  // optimisation (local Brent searches of w and the s_c) from the previous
  // point's optimum; true re-solves every point from scratch (global grid
  // scans; slow for joint fits), the reference the default is tested against.
  bool exact_profiles = false;
};

// A fitted value with its 95 % profile interval.
struct Estimate {
  double value = 0.0;
  double lower = 0.0, upper = 0.0;
  bool lower_at_bound = false, upper_at_bound = false;  // the interval reached the parameter's range
  bool fixed = false;                                   // not fitted (lower = upper = value)
};

// One curve within a fit.
struct CurvePart {
  std::string name;
  Estimate contact_offset_m;           // s: deformation = (indentation - s) / (2R)
  std::vector<std::size_t> points;     // indices of the input samples in the fit range
  std::vector<double> deformation;     // (x - s) / (2R) of those samples
  std::vector<double> model_force_n;   // the fitted model there
  double rms_relative_residual = 0.0;  // sqrt(mean ((F - model)/sigma)^2) over its points
};

// One fit: a set of curves sharing E and w.
struct ParameterFit {
  Estimate youngs_modulus_pa;
  Estimate mooney_rivlin_w;
  std::vector<CurvePart> curves;
  int points = 0;                      // N
  int parameters = 0;                  // p
  double objective = 0.0;              // S at the minimum
  double rms_relative_residual = 0.0;  // sqrt(S / N)
  // Hertz E (plates: hertz_plates_force_n; probe: hertz_probe_force_n) by
  // the closed form over the points with 0 < deformation <= hertz_max_deformation,
  // at the fitted contact points; unset when there are none.
  std::optional<double> hertz_youngs_modulus_pa;
  int hertz_points = 0;
};

struct FitResult {
  std::vector<ParameterFit> per_curve;  // options.per_curve: one per input curve, in order
  std::optional<ParameterFit> joint;    // options.joint
  int simulations_run = 0;              // scene runs this call made the library do
  std::vector<std::string> notes;       // e.g. the w range narrowed because a library curve ended early
};

// kInvalidArgument naming the field (curves[i].force_n[j], fit.max_deformation,
// ...) for bad input; the library's errors for failed simulations.
StatusOr<FitResult> fit_curves(const std::vector<MeasuredCurve>& curves, const FitOptions& options,
                               CurveLibrary& library);

// F = E R^2 f(w, delta/(2R)), f the library's interpolant of the key's scene
// curves (one simulation at exactly w when w is not a grid value and not yet known).
StatusOr<double> scene_force_n(CurveLibrary& library, const CurveKey& key, double youngs_modulus_pa,
                               double mooney_rivlin_w, double radius_m, double indentation_m);

}  // namespace cellflow::calibration
