#include "jobs/fit/fit_spec.h"

#include <algorithm>
#include <cmath>

#include "physics/core/violations.h"

namespace cellflow::jobs {
namespace {

bool finite_positive(double v) {
  return std::isfinite(v) && v > 0.0;
}

std::string at(int i) {
  std::string s = "[";  // in steps: GCC 12 warns (-Wrestrict, a false positive) on "[" + to_string
  s += std::to_string(i);
  s += ']';
  return s;
}

Status refuse(std::string_view field, std::string_view problem, FitSpecError* where, int curve = -1,
              int sample = -1) {
  if (where != nullptr) {
    where->curve = curve;
    where->sample = sample;
  }
  return invalid_argument("fit." + std::string(field) + " " + std::string(problem));
}

}  // namespace

const char* fit_geometry_name(FitGeometryKind geometry) {
  switch (geometry) {
    case FitGeometryKind::kPlates:
      return "plates";
    case FitGeometryKind::kProbe:
      return "probe";
    case FitGeometryKind::kTip:
      return "tip";
  }
  return "?";
}

const char* fit_model_name(FitModelKind model) {
  switch (model) {
    case FitModelKind::kMooneyRivlin:
      return "mooney_rivlin";
    case FitModelKind::kNeoHookean:
      return "neo_hookean";
    case FitModelKind::kHertz:
      return "hertz";
  }
  return "?";
}

StatusOr<FitPlan> to_fit_plan(const v1::FitSpec& spec, FitSpecError* where) {
  if (where != nullptr) *where = {};
  FitPlan plan;
  switch (spec.geometry()) {
    case v1::FIT_GEOMETRY_PLATES:
      plan.geometry = FitGeometryKind::kPlates;
      break;
    case v1::FIT_GEOMETRY_PROBE:
      plan.geometry = FitGeometryKind::kProbe;
      break;
    case v1::FIT_GEOMETRY_TIP:
      plan.geometry = FitGeometryKind::kTip;
      break;
    default:
      return refuse("geometry", "must be set: PLATES, PROBE or TIP", where);
  }
  double probe_radius = 0.0;
  if (plan.geometry == FitGeometryKind::kProbe) {
    if (!spec.has_probe_radius_m() || !finite_positive(spec.probe_radius_m())) {
      return refuse("probe_radius_m",
                    spec.has_probe_radius_m()
                        ? "= " + number_text(spec.probe_radius_m()) + " must be > 0 and finite"
                        : "must be set for the probe geometry (the colloidal probe's radius)",
                    where);
    }
    probe_radius = spec.probe_radius_m();
  }
  if (plan.geometry == FitGeometryKind::kTip) {
    if (!spec.has_tip_radius_m() || !finite_positive(spec.tip_radius_m())) {
      return refuse("tip_radius_m",
                    spec.has_tip_radius_m()
                        ? "= " + number_text(spec.tip_radius_m()) + " must be > 0 and finite"
                        : "must be set for the tip geometry (the tip's apex radius)",
                    where);
    }
    probe_radius = spec.tip_radius_m();
  }
  switch (spec.model()) {
    case v1::FIT_MODEL_UNSPECIFIED:
    case v1::FIT_MODEL_MOONEY_RIVLIN:
      plan.model = FitModelKind::kMooneyRivlin;
      break;
    case v1::FIT_MODEL_NEO_HOOKEAN:
      plan.model = FitModelKind::kNeoHookean;
      break;
    case v1::FIT_MODEL_HERTZ:
      plan.model = FitModelKind::kHertz;
      break;
    default:
      return refuse("model", "= " + std::to_string(spec.model()) + " is not a model", where);
  }
  if (spec.w_case() == v1::FitSpec::kMooneyRivlinW) {
    const double w = spec.mooney_rivlin_w();
    if (!(w >= 0.0 && w <= 1.0))
      return refuse("mooney_rivlin_w", "= " + number_text(w) + " must lie in [0, 1]", where);
    if (plan.model != FitModelKind::kMooneyRivlin && w != 1.0) {
      return refuse("mooney_rivlin_w",
                    "= " + number_text(w) + " contradicts model " + fit_model_name(plan.model) + " (w = 1)",
                    where);
    }
    plan.mooney_rivlin_w = w;
  } else if (spec.w_case() == v1::FitSpec::kWFree && spec.w_free()) {
    if (plan.model != FitModelKind::kMooneyRivlin) {
      return refuse(
          "w_free",
          std::string("needs model MOONEY_RIVLIN (model ") + fit_model_name(plan.model) + " has w = 1)",
          where);
    }
  } else if (plan.model == FitModelKind::kMooneyRivlin) {
    return refuse("w", "must be set: mooney_rivlin_w (fixed, in [0, 1]) or w_free", where);
  }
  if (plan.model != FitModelKind::kMooneyRivlin) plan.mooney_rivlin_w = 1.0;

  if (spec.has_poisson_ratio()) plan.poisson_ratio = spec.poisson_ratio();
  if (!(plan.poisson_ratio > -1.0 && plan.poisson_ratio < 0.5)) {
    return refuse("poisson_ratio", "= " + number_text(plan.poisson_ratio) + " must lie in (-1, 0.5)", where);
  }
  if (spec.has_fit_contact_point()) plan.fit_contact_point = spec.fit_contact_point();
  if (spec.has_contact_window_radii()) plan.contact_window_radii = spec.contact_window_radii();
  if (!(plan.contact_window_radii >= 0.0 && plan.contact_window_radii <= 0.5)) {
    return refuse("contact_window_radii",
                  "= " + number_text(plan.contact_window_radii) + " must lie in [0, 0.5]", where);
  }
  if (spec.has_hertz_max_deformation()) plan.hertz_max_deformation = spec.hertz_max_deformation();
  if (!(plan.hertz_max_deformation > 0.0 && plan.hertz_max_deformation <= 0.9)) {
    return refuse("hertz_max_deformation",
                  "= " + number_text(plan.hertz_max_deformation) + " must lie in (0, 0.9]", where);
  }
  if (spec.has_per_curve()) plan.per_curve = spec.per_curve();
  if (spec.has_joint()) plan.joint = spec.joint();
  if (!plan.per_curve && !plan.joint)
    return refuse("per_curve", "and fit.joint are both false: nothing to fit", where);

  const v1::FitLibraryNumerics& n = spec.numerics();
  if (n.has_target_vertex_count()) plan.target_vertex_count = n.target_vertex_count();
  if (n.has_load_points()) plan.load_points = n.load_points();
  if (n.has_max_deformation()) plan.library_max_deformation = n.max_deformation();
  if (n.has_residual_tolerance()) plan.residual_tolerance = n.residual_tolerance();
  if (!(plan.target_vertex_count >= 200 && plan.target_vertex_count <= 20000)) {
    return refuse("numerics.target_vertex_count",
                  "= " + std::to_string(plan.target_vertex_count) + " must lie in [200, 20000]", where);
  }
  if (!(plan.load_points >= 2 && plan.load_points <= 200)) {
    return refuse("numerics.load_points", "= " + std::to_string(plan.load_points) + " must lie in [2, 200]",
                  where);
  }
  if (!(plan.library_max_deformation > 0.0 && plan.library_max_deformation <= 0.9)) {
    return refuse("numerics.max_deformation",
                  "= " + number_text(plan.library_max_deformation) + " must lie in (0, 0.9]", where);
  }
  if (!(plan.residual_tolerance > 0.0 && plan.residual_tolerance < 1.0)) {
    return refuse("numerics.residual_tolerance",
                  "= " + number_text(plan.residual_tolerance) + " must lie in (0, 1)", where);
  }

  // The fit range.
  const v1::FitRange& range = spec.range();
  const v1::FitRange::Mode mode =
      range.mode() == v1::FitRange::MODE_UNSPECIFIED ? v1::FitRange::DEFORMATION : range.mode();
  double lo = -0.05, hi = 0.7;
  if (mode != v1::FitRange::DEFORMATION && (!range.has_min() || !range.has_max())) {
    return refuse(range.has_min() ? "range.max" : "range.min", "must be set for a range in metres", where);
  }
  if (range.has_min()) lo = range.min();
  if (range.has_max()) hi = range.max();
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi)) {
    return refuse("range", "[" + number_text(lo) + ", " + number_text(hi) + "] is empty or not finite",
                  where);
  }
  if (mode == v1::FitRange::DEFORMATION) {
    if (!(lo > -1.0)) return refuse("range.min", "= " + number_text(lo) + " must be > -1", where);
    if (!(hi < 0.9)) return refuse("range.max", "= " + number_text(hi) + " must be < 0.9", where);
  }

  // The curves.
  if (spec.curves_size() == 0) return refuse("curves", "is empty: no curve to fit", where);
  if (spec.curves_size() > kMaxFitCurves) {
    return refuse(
        "curves",
        "holds " + std::to_string(spec.curves_size()) + " curves, more than " + std::to_string(kMaxFitCurves),
        where);
  }
  for (const v1::FitCurve& c : spec.curves()) plan.total_samples += c.force_n_size();
  if (plan.total_samples > kMaxFitPoints) {
    return refuse("curves",
                  "hold " + std::to_string(plan.total_samples) + " samples in all, more than " +
                      std::to_string(kMaxFitPoints) + " (thin the curves)",
                  where);
  }
  double eps_min = 1e300, eps_max = -1e300;
  for (int ci = 0; ci < spec.curves_size(); ++ci) {
    const v1::FitCurve& c = spec.curves(ci);
    const std::string path = "curves" + at(ci) + ".";
    FitCurvePlan cp;
    cp.name = c.name().empty() ? "curves" + at(ci) : c.name();
    const double radius = c.has_radius_m() ? c.radius_m() : spec.radius_m();
    if (!finite_positive(radius)) {
      if (c.has_radius_m()) {
        return refuse(path + "radius_m", "= " + number_text(radius) + " must be > 0 and finite", where, ci);
      }
      return refuse("radius_m",
                    spec.has_radius_m()
                        ? "= " + number_text(radius) + " must be > 0 and finite"
                        : "must be set: the cell radius (or curves[i].radius_m for each curve)",
                    where);
    }
    cp.radius_m = radius;
    cp.probe_radius_m = probe_radius;
    cp.force_noise_n = c.has_force_noise_n() ? c.force_noise_n() : 0.0;
    if (!(cp.force_noise_n >= 0.0 && std::isfinite(cp.force_noise_n))) {
      return refuse(path + "force_noise_n", "= " + number_text(cp.force_noise_n) + " must be >= 0 and finite",
                    where, ci);
    }
    const bool by_tip = c.tip_position_m_size() > 0;
    if (by_tip && c.indentation_m_size() > 0) {
      return refuse(path + "indentation_m", "and tip_position_m are both given: send one", where, ci);
    }
    if (mode == v1::FitRange::ABSOLUTE_M && !by_tip) {
      return refuse(path + "tip_position_m", "is empty: an ABSOLUTE_M fit range needs tip positions", where,
                    ci);
    }
    const auto& x = by_tip ? c.tip_position_m() : c.indentation_m();
    const std::string x_name = by_tip ? "tip_position_m" : "indentation_m";
    if (x.empty()) return refuse(path + "indentation_m", "is empty (and so is tip_position_m)", where, ci);
    if (c.force_n_size() != x.size()) {
      return refuse(
          path + "force_n",
          "has " + std::to_string(c.force_n_size()) + " samples, " + x_name + " " + std::to_string(x.size()),
          where, ci);
    }
    const double two_r = 2.0 * radius;
    double max_force = 0.0;
    for (int i = 0; i < x.size(); ++i) {
      if (!std::isfinite(x[i]))
        return refuse(path + x_name + at(i), "= " + number_text(x[i]) + " must be finite", where, ci, i);
      if (i > 0 && !(x[i] > x[i - 1])) {
        return refuse(path + x_name + at(i),
                      "= " + number_text(x[i]) + " is not above " + x_name + at(i - 1) + " = " +
                          number_text(x[i - 1]) +
                          ": the deformation must increase strictly (sort or bin the approach)",
                      where, ci, i);
      }
      const double f = c.force_n(i);
      if (!std::isfinite(f))
        return refuse(path + "force_n" + at(i), "= " + number_text(f) + " must be finite", where, ci, i);
      if (f < -3.0 * cp.force_noise_n) {
        return refuse(path + "force_n" + at(i),
                      "= " + number_text(f) +
                          " is negative (beyond 3 force_noise_n = " + number_text(3.0 * cp.force_noise_n) +
                          "): subtract the baseline so the free cantilever reads 0, or give force_noise_n",
                      where, ci, i);
      }
      max_force = std::max(max_force, f);
    }
    // The contact estimate of tip positions: the last sample before the force exceeds 5 % of its maximum.
    if (by_tip) {
      int first = 0;
      while (first < x.size() && c.force_n(first) <= 0.05 * max_force) ++first;
      cp.contact_estimate_m = x[std::max(first - 1, 0)];
    }
    for (int i = 0; i < x.size(); ++i) {
      const double d = x[i] - cp.contact_estimate_m;
      if (d / two_r >= 1.0) {
        return refuse(path + x_name + at(i),
                      "= " + number_text(x[i]) + " is a deformation x/(2R) = " + number_text(d / two_r, 4) +
                          " >= 1: more than the cell's diameter (check radius_m and the units)",
                      where, ci, i);
      }
      const double eps = d / two_r;
      const double in = mode == v1::FitRange::DEFORMATION ? eps : mode == v1::FitRange::RELATIVE_M ? d : x[i];
      if (in >= lo && in <= hi) {
        cp.indentation_m.push_back(d);
        cp.force_n.push_back(c.force_n(i));
        cp.sample.push_back(i);
      }
    }
    const char* unit = mode == v1::FitRange::DEFORMATION ? "" : " m";
    if (cp.indentation_m.empty()) {
      return refuse(path + x_name,
                    "has no sample in the fit range [" + number_text(lo) + unit + ", " + number_text(hi) +
                        unit + "] (" +
                        std::string(mode == v1::FitRange::DEFORMATION  ? "deformation x/(2R)"
                                    : mode == v1::FitRange::RELATIVE_M ? "metres past the contact estimate"
                                                                       : "tip position") +
                        "; the curve spans deformation [" +
                        number_text((x[0] - cp.contact_estimate_m) / two_r, 4) + ", " +
                        number_text((x[x.size() - 1] - cp.contact_estimate_m) / two_r, 4) + "])",
                    where, ci);
    }
    if (!(*std::max_element(cp.force_n.begin(), cp.force_n.end()) > 0.0)) {
      return refuse(path + "force_n", "has no positive force in the fit range: nothing to fit E to", where,
                    ci);
    }
    eps_min = std::min(eps_min, cp.indentation_m.front() / two_r);
    eps_max = std::max(eps_max, cp.indentation_m.back() / two_r);
    plan.curves.push_back(std::move(cp));
  }
  if (mode == v1::FitRange::DEFORMATION) {
    plan.min_deformation = lo;
    plan.max_deformation = hi;
  } else {
    plan.min_deformation = std::max(eps_min, -0.99);
    plan.max_deformation = eps_max;
    if (!(plan.max_deformation < 0.9)) {
      return refuse("range.max",
                    "= " + number_text(hi) + " m reaches deformation " +
                        number_text(plan.max_deformation, 4) + ", must stay below 0.9",
                    where);
    }
    if (!(plan.max_deformation > plan.min_deformation)) {
      return refuse("range", "holds a single deformation " + number_text(eps_max, 4) + ": widen it", where);
    }
  }
  if (plan.model != FitModelKind::kHertz) {
    const double window = plan.fit_contact_point ? plan.contact_window_radii : 0.0;
    const double reach = plan.max_deformation + 0.5 * window;
    if (plan.library_max_deformation < reach * (1.0 - 1e-12)) {
      return refuse("numerics.max_deformation",
                    "= " + number_text(plan.library_max_deformation) +
                        " must reach the fit range's deepest deformation + contact_window_radii / 2 = " +
                        number_text(reach, 6) + " (lower fit.range.max or raise numerics.max_deformation)",
                    where);
    }
  }
  return plan;
}

}  // namespace cellflow::jobs
