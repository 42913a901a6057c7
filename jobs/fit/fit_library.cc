#include "jobs/fit/fit_library.h"

#include <algorithm>
#include <cstdio>
#include <map>

namespace cellflow::jobs {

namespace cal = cellflow::calibration;

calibration::LibraryOptions fit_library_options(int threads) {
  cal::LibraryOptions options;
  options.threads = threads > 0 ? threads : 1;
  return options;
}

StatusOr<std::vector<FitLibraryKey>> fit_library_keys(const FitPlan& plan,
                                                      const cal::LibraryOptions& options) {
  std::vector<FitLibraryKey> keys;
  if (plan.model == FitModelKind::kHertz) return keys;
  cal::CurveLibrary checker(options);
  std::map<std::string, std::size_t> index;
  for (const FitCurvePlan& c : plan.curves) {
    cal::CurveKey key;
    key.geometry = plan.geometry == FitGeometryKind::kPlates ? cal::Geometry::kPlates : cal::Geometry::kProbe;
    key.probe_to_cell_radius = key.geometry == cal::Geometry::kProbe ? c.probe_radius_m / c.radius_m : 0.0;
    key.poisson_ratio = plan.poisson_ratio;
    key.numerics.target_vertex_count = plan.target_vertex_count;
    key.numerics.load_points = plan.load_points;
    key.numerics.max_deformation = plan.library_max_deformation;
    key.numerics.residual_tolerance = plan.residual_tolerance;
    if (Status s = checker.validate(key); !s.ok()) return invalid_argument("fit: " + s.message());
    // The deepest deformation a curve asks of the library: its last sample
    // with the contact moved to the end of its window (fit_curves does the same).
    const double window = plan.fit_contact_point ? plan.contact_window_radii * c.radius_m : 0.0;
    const double reach =
        std::min(plan.library_max_deformation, (c.indentation_m.back() + window) / (2.0 * c.radius_m));
    const std::string text = cal::curve_key_text(key, -1.0, options);
    auto [it, inserted] = index.emplace(text, keys.size());
    if (inserted) keys.push_back({key, text, 0.0});
    keys[it->second].needed_max_deformation = std::max(keys[it->second].needed_max_deformation, reach);
  }
  return keys;
}

std::vector<double> fit_library_w(const FitPlan& plan, const cal::LibraryOptions& options) {
  if (plan.model == FitModelKind::kNeoHookean) return {1.0};
  return plan.mooney_rivlin_w ? std::vector<double>{*plan.mooney_rivlin_w} : options.w_grid;
}

StatusOr<std::vector<FitLibraryChild>> fit_library_children(const FitPlan& plan, const std::string& name) {
  const cal::LibraryOptions options = fit_library_options();
  StatusOr<std::vector<FitLibraryKey>> keys = fit_library_keys(plan, options);
  if (!keys.ok()) return keys.status();
  const std::vector<double> ws = fit_library_w(plan, options);
  std::vector<FitLibraryChild> children;
  for (const FitLibraryKey& k : *keys) {
    for (auto w = ws.rbegin(); w != ws.rend(); ++w) {
      FitLibraryChild child;
      child.key = cal::curve_key_text(k.key, *w, options);
      child.base = k.text;
      child.mooney_rivlin_w = *w;
      child.needed_deformation = k.needed_max_deformation;
      // The run CurveLibrary::curve makes: the reference cell, the key's numerics.
      v1::CellSpec cell;
      cell.set_radius_m(options.reference_radius_m);
      cell.mutable_material()->set_youngs_modulus_pa(options.reference_modulus_pa);
      cell.mutable_material()->set_poisson_ratio(k.key.poisson_ratio);
      cell.mutable_material()->set_mooney_rivlin_w(*w);
      cell.set_target_vertex_count(k.key.numerics.target_vertex_count);
      v1::QuasiStaticNumerics numerics;
      numerics.set_residual_tolerance(k.key.numerics.residual_tolerance);
      numerics.set_volumetric_term(k.key.numerics.volumetric == elastic::VolumetricTerm::kPerTet
                                       ? v1::VOLUMETRIC_TERM_PER_TET
                                       : v1::VOLUMETRIC_TERM_NODAL_AVERAGE);
      char label[160];
      if (k.key.geometry == cal::Geometry::kPlates) {
        v1::CompressionSpec* s = child.spec.mutable_compression();
        *s->mutable_cell() = cell;
        s->set_max_deformation(k.key.numerics.max_deformation);
        s->set_load_points(k.key.numerics.load_points);
        *s->mutable_numerics() = numerics;
        std::snprintf(label, sizeof label, "library plates w=%g", *w);
      } else {
        v1::IndentationSpec* s = child.spec.mutable_indentation();
        *s->mutable_cell() = cell;
        s->set_probe_radius_m(k.key.probe_to_cell_radius * options.reference_radius_m);
        s->set_max_indentation_m(k.key.numerics.max_deformation * 2.0 * options.reference_radius_m);
        s->set_load_points(k.key.numerics.load_points);
        *s->mutable_numerics() = numerics;
        std::snprintf(label, sizeof label, "library probe Rp/R=%g w=%g", k.key.probe_to_cell_radius, *w);
      }
      child.spec.set_name((name.empty() ? std::string() : name + " ") + "[" + label + "]");
      children.push_back(std::move(child));
    }
  }
  return children;
}

}  // namespace cellflow::jobs
