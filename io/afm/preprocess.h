// Preprocessing of one force curve segment (normally the approach), as free
// functions over SI arrays. x is the tip position (positive towards the
// sample, see force_curve.h), f the force; x need not be monotonic (noise).
//
// Typical use:
//   auto x = tip_position_m(seg.height_m, seg.deflection_m);
//   auto cp = contact_by_baseline_deviation(x, seg.force_n, {});
//   auto f0 = subtract_baseline(x, seg.force_n, cp->baseline);
//   auto d = indentation_m(x, cp->tip_position_m);
//   auto idx = select_fit_range(x, cp->tip_position_m, FitRange::relative(0, 1e-6));
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::afm {

// tip = height - deflection, element by element (sizes must agree).
std::vector<double> tip_position_m(std::span<const double> height_m, std::span<const double> deflection_m);

// Force baseline of the free (non-contact) cantilever: f = offset + slope * x.
// The slope models the tilt caused by drift, viscous drag or optical
// interference; it is zero when the fit is offset-only.
struct Baseline {
  double offset_n = 0.0;
  double slope_n_per_m = 0.0;
  double noise_sigma_n = 0.0;  // RMS residual of the fit: the noise floor
  std::size_t begin = 0;       // index range the fit used
  std::size_t end = 0;

  double at(double x_m) const { return offset_n + slope_n_per_m * x_m; }
};

// Least-squares fit over indices [begin, end). Needs at least 3 points (2 for
// offset-only) and a non-degenerate x for the tilt.
StatusOr<Baseline> fit_baseline(std::span<const double> x_m, std::span<const double> f_n, std::size_t begin,
                                std::size_t end, bool fit_tilt);

// f - baseline(x).
std::vector<double> subtract_baseline(std::span<const double> x_m, std::span<const double> f_n,
                                      const Baseline& baseline);

struct ContactPoint {
  std::size_t index = 0;        // first sample in contact
  double tip_position_m = 0.0;  // contact position (interpolated for the fit method)
  Baseline baseline;            // baseline the estimate is based on
};

struct DeviationOptions {
  // The baseline is fitted on the first baseline_fraction of the segment: the
  // part farthest from the sample, assumed free of contact.
  double baseline_fraction = 0.4;
  bool fit_tilt = true;
  double k_sigma = 5.0;  // threshold above the baseline, in noise sigmas
  // A second baseline pass on all points before the first estimate minus this
  // fraction of the segment, so the baseline uses all the free part.
  bool refit_baseline = true;
  double refit_margin_fraction = 0.02;
};

// Method 1, baseline deviation: the contact is the point after the last
// sample whose baseline-corrected force is below k_sigma * noise. Scanning
// back from the end (deepest indentation) ignores noise spikes in the free
// part. It is biased late by the indentation at which the force reaches
// k_sigma * noise: for a Hertz sphere, (k sigma / A)^(2/3).
StatusOr<ContactPoint> contact_by_baseline_deviation(std::span<const double> x_m, std::span<const double> f_n,
                                                     const DeviationOptions& options);

struct PowerLawFitOptions {
  // f = b(x) for x < x0 and b(x) + A (x - x0)^exponent beyond: 1.5 is a Hertz
  // sphere (or paraboloid), 2 a cone, 1 a flat punch / linear spring.
  double exponent = 1.5;
  bool fit_tilt = true;
  // Candidate contacts are searched among the tip positions of the segment
  // between these fractions of its x range; a coarse grid, then golden-section
  // refinement between the grid neighbours of the best candidate.
  double search_begin_fraction = 0.05;
  double search_end_fraction = 0.98;
  int grid_points = 200;
};

struct PowerLawFit {
  ContactPoint contact;
  double amplitude_n_per_m_pow = 0.0;  // A in the model above
  double rms_residual_n = 0.0;
};

// Method 2, piecewise baseline + power-law fit: for each candidate contact
// x0 the baseline offset, tilt and amplitude A are linear, so they are solved
// exactly by least squares; the x0 with the smallest residual wins. Unbiased
// when the model holds, and it uses every point rather than a threshold.
StatusOr<PowerLawFit> contact_by_power_law_fit(std::span<const double> x_m, std::span<const double> f_n,
                                               const PowerLawFitOptions& options);

// indentation (or deformation) = x - x_contact: positive into the sample.
std::vector<double> indentation_m(std::span<const double> x_m, double contact_tip_position_m);

// Which samples a model fit uses: either absolute tip positions, or
// indentations relative to the contact point (e.g. 0 to 1 um past contact).
struct FitRange {
  enum class Mode { kAbsolute, kRelativeToContact };
  Mode mode = Mode::kRelativeToContact;
  double min_m = 0.0;
  double max_m = 0.0;

  static FitRange absolute(double min_m, double max_m) { return {Mode::kAbsolute, min_m, max_m}; }
  static FitRange relative(double min_m, double max_m) { return {Mode::kRelativeToContact, min_m, max_m}; }
};

// Indices of the samples with x (or x - x_contact) in [min_m, max_m], in order.
std::vector<std::size_t> select_fit_range(std::span<const double> x_m, double contact_tip_position_m,
                                          const FitRange& range);

}  // namespace cellflow::afm
