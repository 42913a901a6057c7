#include "jobs/fit/library_curve.h"

#include <algorithm>
#include <cmath>

namespace cellflow::jobs {

StatusOr<v1::FitLibraryCurve> library_curve_from_samples(const std::string& key, const v1::JobSpec& child,
                                                         std::vector<v1::ForceSample> samples,
                                                         const std::string& failure) {
  const v1::CellSpec* cell = nullptr;
  int load_points = 0;
  if (child.has_compression()) {
    cell = &child.compression().cell();
    load_points = child.compression().load_points();
  } else if (child.has_indentation()) {
    cell = &child.indentation().cell();
    load_points = child.indentation().load_points();
  } else {
    return invalid_argument("library child: not a compression or indentation scene");
  }
  const double modulus = cell->material().youngs_modulus_pa(), radius = cell->radius_m();
  if (!(modulus > 0.0 && radius > 0.0 && std::isfinite(modulus * radius * radius))) {
    return invalid_argument("library child: the cell needs E > 0 and R > 0");
  }
  if (samples.empty()) return invalid_argument("library child: no force sample");
  if (static_cast<int>(samples.size()) > std::min(load_points, kMaxLibraryCurvePoints)) {
    return invalid_argument("library child: " + std::to_string(samples.size()) + " samples, more than its " +
                            std::to_string(load_points) + " load points");
  }
  if (failure.empty() && static_cast<int>(samples.size()) != load_points) {
    return invalid_argument("library child: succeeded with " + std::to_string(samples.size()) + " of its " +
                            std::to_string(load_points) + " load points");
  }
  std::sort(samples.begin(), samples.end(),
            [](const v1::ForceSample& a, const v1::ForceSample& b) { return a.index() < b.index(); });
  v1::FitLibraryCurve curve;
  curve.set_key(key);
  curve.set_mooney_rivlin_w(cell->material().has_mooney_rivlin_w() ? cell->material().mooney_rivlin_w()
                                                                   : 1.0);
  curve.set_failure(failure.substr(0, kMaxLibraryFailureBytes));
  const double scale = modulus * radius * radius;  // f = F / (E R^2)
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].index() != static_cast<int>(i)) {
      return invalid_argument("library child: force sample " + std::to_string(i) + " has index " +
                              std::to_string(samples[i].index()) + " (a gap or a repeat)");
    }
    curve.add_deformation(samples[i].deformation());
    curve.add_force_scaled(samples[i].force_n() / scale);
  }
  if (Status s = check_library_curve(curve); !s.ok()) return s;
  return curve;
}

Status check_library_curve(const v1::FitLibraryCurve& c) {
  if (c.key().empty() || c.key().size() > kMaxLibraryKeyBytes) {
    return invalid_argument("library curve: key of " + std::to_string(c.key().size()) + " bytes; 1 to " +
                            std::to_string(kMaxLibraryKeyBytes));
  }
  if (c.failure().size() > kMaxLibraryFailureBytes) {
    return invalid_argument("library curve: failure text over " + std::to_string(kMaxLibraryFailureBytes) +
                            " bytes");
  }
  if (!(c.mooney_rivlin_w() >= 0.0 && c.mooney_rivlin_w() <= 1.0)) {
    return invalid_argument("library curve: mooney_rivlin_w outside [0, 1]");
  }
  const int n = c.deformation_size();
  if (n < 1 || n > kMaxLibraryCurvePoints || c.force_scaled_size() != n) {
    return invalid_argument("library curve: " + std::to_string(n) + " deformations and " +
                            std::to_string(c.force_scaled_size()) + " forces; equal, 1 to " +
                            std::to_string(kMaxLibraryCurvePoints));
  }
  for (int i = 0; i < n; ++i) {
    const double e = c.deformation(i), f = c.force_scaled(i);
    if (!(e > 0.0 && e <= kMaxLibraryDeformation * (1.0 + 1e-12)) || (i > 0 && !(e > c.deformation(i - 1)))) {
      return invalid_argument("library curve: deformation[" + std::to_string(i) +
                              "] not increasing in (0, 0.9]");
    }
    if (!(f >= 0.0 && f <= kMaxLibraryForceScaled)) {
      return invalid_argument("library curve: force_scaled[" + std::to_string(i) + "] outside [0, 1000]");
    }
  }
  return {};
}

}  // namespace cellflow::jobs
