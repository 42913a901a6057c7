#include "client/fit_input.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "io/afm/preprocess.h"
#include "io/afm/read_force_curve.h"
#include "jobs/fit/fit_spec.h"
#include "physics/core/violations.h"

namespace cellflow::client {
namespace {

Status file_error(const std::string& path, const std::string& message) {
  // The readers name the file in most messages; say it once, in front.
  std::string m = message;
  if (m.rfind(path + ": ", 0) == 0) m = m.substr(path.size() + 2);
  return invalid_argument(path + ": " + m);
}

bool strictly_increasing(const std::vector<double>& x, std::size_t* bad) {
  for (std::size_t i = 1; i < x.size(); ++i) {
    if (!(x[i] > x[i - 1])) {
      *bad = i;
      return false;
    }
  }
  return true;
}

}  // namespace

StatusOr<FitInputCurve> read_fit_curve(const std::string& path, double radius_m,
                                       const FitInputOptions& options) {
  afm::ReadOptions read;
  read.spring_constant_n_per_m = options.spring_constant_n_per_m;
  read.sensitivity_m_per_v = options.sensitivity_m_per_v;
  StatusOr<afm::ForceCurve> curve = afm::read_force_curve(path, read);
  if (!curve.ok()) return file_error(path, curve.status().message());
  const afm::Segment* seg = curve->find(afm::SegmentKind::kApproach);
  if (seg == nullptr && curve->segments.size() == 1) seg = &curve->segments.front();
  if (seg == nullptr) return file_error(path, "no approach segment");
  if (seg->size() < 5) {
    return file_error(path, "the approach segment holds " + std::to_string(seg->size()) +
                                " samples: too few for a baseline, a contact and a fit");
  }
  const bool derived_tip =
      !seg->tip_position_m.empty() && !seg->deflection_m.empty() && !seg->height_m.empty();
  const std::vector<double>& x_read = !seg->tip_position_m.empty() ? seg->tip_position_m : seg->height_m;
  if (x_read.size() != seg->force_n.size()) return file_error(path, "no tip position or height channel");
  for (std::size_t i = 0; i < x_read.size(); ++i) {
    if (!std::isfinite(x_read[i]) || !std::isfinite(seg->force_n[i])) {
      return file_error(path, "approach sample " + std::to_string(i) + ": position " +
                                  number_text(x_read[i]) + " m, force " + number_text(seg->force_n[i]) +
                                  " N: not a finite number");
    }
  }
  // The order of the samples: as read, or sorted by tip position when the
  // height increases and only the deflection makes the tip position jitter.
  std::vector<std::size_t> order(x_read.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::size_t bad = 0;
  if (!strictly_increasing(x_read, &bad)) {
    if (!derived_tip) {
      return file_error(path, "approach sample " + std::to_string(bad) + ": position " +
                                  number_text(x_read[bad]) + " m is not above sample " +
                                  std::to_string(bad - 1) + "'s " + number_text(x_read[bad - 1]) +
                                  " m: the deformation must increase over the approach (non-monotonic)");
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return x_read[a] < x_read[b]; });
    order.erase(std::unique(order.begin(), order.end(),
                            [&](std::size_t a, std::size_t b) { return x_read[a] == x_read[b]; }),
                order.end());
  }
  std::vector<double> x, f;
  for (std::size_t i : order) {
    x.push_back(x_read[i]);
    f.push_back(seg->force_n[i]);
  }
  if (options.contact_at_zero) {
    FitInputCurve out;
    out.file = path;
    out.contact_estimate_m = 0.0;
    out.curve.set_name(std::filesystem::path(path).filename().string());
    out.curve.set_force_noise_n(0.0);
    for (std::size_t k = 0; k < x.size(); ++k) {
      out.curve.add_indentation_m(x[k]);
      out.curve.add_force_n(f[k]);
      out.approach_sample.push_back(static_cast<int>(order[k]));
    }
    return out;
  }
  // Negative forces (beyond the free cantilever's noise and 1 % of the
  // maximum) against the baseline of the free part: a sign or baseline
  // problem the contact estimate would only hide.
  const std::size_t free_end = std::max<std::size_t>(3, x.size() * 2 / 5);
  if (StatusOr<afm::Baseline> free = afm::fit_baseline(x, f, 0, free_end, true); free.ok()) {
    const std::vector<double> g = afm::subtract_baseline(x, f, *free);
    const double g_max = *std::max_element(g.begin(), g.end());
    const double limit = 3.0 * free->noise_sigma_n + 0.01 * std::max(g_max, 0.0);
    for (std::size_t k = 0; k < g.size(); ++k) {
      if (g[k] < -limit) {
        return file_error(path, "approach sample " + std::to_string(order[k]) +
                                    ": force_n = " + number_text(g[k], 4) +
                                    " N against the free baseline is negative (beyond 3 noise sigma + 1 % of "
                                    "the maximum force = " +
                                    number_text(limit, 4) + " N): check the force's sign and the baseline");
      }
    }
  }
  StatusOr<afm::ContactPoint> contact = afm::contact_by_baseline_deviation(x, f, {});
  if (!contact.ok()) return file_error(path, "contact point estimate: " + contact.status().message());
  const std::vector<double> f0 = afm::subtract_baseline(x, f, contact->baseline);

  FitInputCurve out;
  out.file = path;
  out.contact_estimate_m = contact->tip_position_m;
  out.curve.set_name(std::filesystem::path(path).filename().string());
  // The noise floor: the baseline's RMS residual, raised to a third of the
  // deepest negative excursion before the contact estimate (the fit refuses
  // forces below -3 force_noise_n; a 1000-sample free approach has spikes past 3 sigma).
  double noise = contact->baseline.noise_sigma_n;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double d = x[k] - contact->tip_position_m;
    if (d <= 0.0 && d >= -0.1 * 2.0 * radius_m) noise = std::max(noise, -f0[k] / 3.0);
  }
  out.curve.set_force_noise_n(noise);
  const double margin = 0.1 * 2.0 * radius_m;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double d = x[k] - contact->tip_position_m;
    if (d < -margin) continue;
    out.curve.add_indentation_m(d);
    out.curve.add_force_n(f0[k]);
    out.approach_sample.push_back(static_cast<int>(order[k]));
  }
  if (out.curve.force_n_size() == 0) return file_error(path, "no sample past the contact estimate");
  return out;
}

Status check_fit_spec(const v1::FitSpec& spec, const std::vector<FitInputCurve>& inputs) {
  jobs::FitSpecError where;
  StatusOr<jobs::FitPlan> plan = jobs::to_fit_plan(spec, &where);
  if (plan.ok()) return Status::ok_status();
  std::string message = plan.status().message();
  if (where.curve < 0 || where.curve >= static_cast<int>(inputs.size())) return plan.status();
  const FitInputCurve& input = inputs[where.curve];
  // "fit.curves[2].force_n[17] = ..." -> "FILE: approach sample 123: force_n = ..."
  const std::string prefix = "fit.curves[" + std::to_string(where.curve) + "].";
  if (message.rfind(prefix, 0) == 0) message = message.substr(prefix.size());
  std::string at;
  if (where.sample >= 0 && where.sample < static_cast<int>(input.approach_sample.size())) {
    at = "approach sample " + std::to_string(input.approach_sample[where.sample]) + " (indentation " +
         number_text(input.curve.indentation_m(where.sample), 4) + " m past the contact estimate): ";
    const std::size_t bracket = message.find('[');
    const std::size_t close = message.find(']');
    if (bracket != std::string::npos && close != std::string::npos && bracket < message.find(' ')) {
      message.erase(bracket, close - bracket + 1);  // the spec's index: the file's is named above
    }
  }
  return invalid_argument(input.file + ": " + at + message);
}

}  // namespace cellflow::client
