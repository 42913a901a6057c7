// The fit job's spec (proto/cellflow/v1/fit.proto) converted and validated
// into plain arrays and options, with no physics linked: the client runs the
// same checks before it submits (naming the file and the data row), the
// server's registry runs them again at submit, and the worker's fit job
// (jobs/fit/fit_job.h) converts the plan into physics/calibration's types.
//
// Checks, each naming its field path ("fit.curves[2].force_n[17]"):
//   geometry set; the cell radius (fit.radius_m or the curve's) > 0; the probe
//   (tip) radius > 0 for the probe (tip) geometry; w fixed in [0, 1] or free
//   (free only with MOONEY_RIVLIN); nu in (-1, 0.5); 1..kMaxFitCurves curves
//   of kMaxFitPoints samples in all; per curve exactly one of indentation_m /
//   tip_position_m, force_n of the same length, finite values, the position
//   strictly increasing (sort or bin the approach: the client does), x/(2R) < 1,
//   force_n >= -3 force_noise_n (baseline-subtracted), at least one sample in
//   the fit range and a positive force there; the library numerics in range
//   and reaching the deepest deformation a fitted contact may ask of them.
//
// The indentation of a curve sent as tip_position_m is measured from a first
// contact estimate taken from the data: the tip position of the last sample
// before the force first exceeds 5 % of its maximum (the fit then refines the
// contact within +-contact_window_radii R).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Bounds of one request. 200,000 samples are 3.2 MB of packed doubles, under
// gRPC's default 4 MiB message limit with room for the rest of the spec (a
// typical AFM approach holds 1,000-10,000 samples).
inline constexpr std::int64_t kMaxFitPoints = 200000;
inline constexpr int kMaxFitCurves = 1000;

enum class FitGeometryKind { kPlates, kProbe, kTip };
enum class FitModelKind { kMooneyRivlin, kNeoHookean, kHertz };

const char* fit_geometry_name(FitGeometryKind geometry);  // "plates", "probe", "tip"
const char* fit_model_name(FitModelKind model);           // "mooney_rivlin", "neo_hookean", "hertz"

// One curve, restricted to the samples in the fit range.
struct FitCurvePlan {
  std::string name;
  double radius_m = 0.0;
  double probe_radius_m = 0.0;        // probe: Rp; tip: the tip radius; plates: 0
  double contact_estimate_m = 0.0;    // tip position of the contact estimate (0 for indentation_m)
  std::vector<double> indentation_m;  // from the contact estimate, strictly increasing
  std::vector<double> force_n;
  std::vector<int> sample;  // index of each sample in the spec's arrays
  double force_noise_n = 0.0;
};

struct FitPlan {
  FitGeometryKind geometry = FitGeometryKind::kPlates;
  FitModelKind model = FitModelKind::kMooneyRivlin;
  std::optional<double> mooney_rivlin_w;  // fixed w; unset: fitted
  double poisson_ratio = 0.48;
  double min_deformation = -0.05;  // the fit range on x / (2R) (metre ranges converted per curve)
  double max_deformation = 0.7;
  bool fit_contact_point = true;
  double contact_window_radii = 0.1;
  double hertz_max_deformation = 0.1;
  bool per_curve = true;
  bool joint = true;
  int target_vertex_count = 3000;  // library numerics
  int load_points = 30;
  double library_max_deformation = 0.75;
  double residual_tolerance = 1e-6;
  std::vector<FitCurvePlan> curves;
  std::int64_t total_samples = 0;  // in the spec, all curves
};

// Where a refused spec is wrong, for messages that name a file and a row.
struct FitSpecError {
  int curve = -1;   // index into fit.curves, -1: not one curve
  int sample = -1;  // index into that curve's arrays, -1: not one sample
};

// INVALID_ARGUMENT naming the field path (prefix "fit."); `where` (if not
// null) says which curve and sample.
StatusOr<FitPlan> to_fit_plan(const v1::FitSpec& spec, FitSpecError* where = nullptr);

}  // namespace cellflow::jobs
