// The curve library a fit needs, as keys and as child jobs (issue 14, item
// 4). The server calls fit_library_children at SubmitJob: one compression or
// indentation job per (library key, grid w) at the library's reference cell,
// named by its curve key text (physics/calibration/curve_library.h), which
// the server queues as the fit's children unless its library table already
// holds that curve or another job is building it (server/store.h,
// "Library"). The fit job (jobs/fit/fit_job.h) finds the same keys with
// fit_library_keys and reads the curves the server attached to its spec.
#pragma once

#include <string>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "jobs/fit/fit_spec.h"
#include "physics/calibration/curve_library.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// One library key of a fit: every curve of one geometry, probe ratio, nu and
// numerics; `text` is its key text without w (curve_key_text with w = -1);
// the deepest deformation the fit will ask of its curves.
struct FitLibraryKey {
  calibration::CurveKey key;
  std::string text;
  double needed_max_deformation = 0.0;
};

// The library options a fit job uses (w grid, reference cell, code version).
calibration::LibraryOptions fit_library_options(int threads = 1);

// The distinct keys of the plan's curves (Hertz: none); INVALID_ARGUMENT
// naming "fit:" when a key is out of the library's range.
StatusOr<std::vector<FitLibraryKey>> fit_library_keys(const FitPlan& plan,
                                                      const calibration::LibraryOptions& options);

// The w values the fit reads per key: the grid (w free) or the fixed w.
std::vector<double> fit_library_w(const FitPlan& plan, const calibration::LibraryOptions& options);

// A simulation the fit needs: the curve at `key` (curve_key_text with w),
// made by running `spec` (compression or indentation at the reference cell,
// E = reference_modulus_pa, R = reference_radius_m).
struct FitLibraryChild {
  std::string key;
  std::string base;  // the key text without w (FitLibraryKey::text)
  double mooney_rivlin_w = 1.0;
  double needed_deformation = 0.0;  // FitLibraryKey::needed_max_deformation
  v1::JobSpec spec;
};

// Every curve the fit reads, in the order the fit job reads them (per key,
// w from 1 down). `name` prefixes the children's names.
StatusOr<std::vector<FitLibraryChild>> fit_library_children(const FitPlan& plan, const std::string& name);

}  // namespace cellflow::jobs
