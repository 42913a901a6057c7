// The result of a fit job (layout: jobs/fit/result_schema.json) on the
// client: the fit document, the table `cellflow fit` prints, the JSON it
// prints with --json, the curves as CSV columns (`cellflow result --csv`) and
// as an SVG plot (`cellflow plot`): data, best model curve and Hertz curve.
#pragma once

#include <string>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::client {

// True when the HDF5 result at `h5_path` is a fit job's.
bool is_fit_result(const std::string& h5_path);

// /summary/fit_json.
StatusOr<std::string> read_fit_json(const std::string& h5_path);

struct FitCurveSeries {
  std::string name;
  std::vector<long long> sample;  // index in the spec's arrays
  std::vector<double> indentation_m, deformation, force_n, model_force_n, hertz_force_n, joint_model_force_n;
};

StatusOr<std::vector<FitCurveSeries>> read_fit_curves(const std::string& h5_path);

// Columns
// curve,name,sample,indentation_m,deformation,force_n,model_force_n,hertz_force_n,joint_model_force_n.
std::string fit_curves_csv(const std::vector<FitCurveSeries>& curves);

// Force against deformation: per curve the data (markers), the model (line) and Hertz (dashed).
std::string fit_svg(const std::vector<FitCurveSeries>& curves, const std::string& title);

// What `cellflow fit` prints. `files` and `contact_estimates_m` (one per
// curve, in order) put the file names in and shift contact_point_m from the
// client's contact estimate to the file's tip-position coordinates.
struct FitReport {
  std::string job_id;
  std::vector<std::string> files;
  std::vector<double> contact_estimates_m;
};
StatusOr<std::string> fit_json_report(const std::string& fit_json, const FitReport& report);
StatusOr<std::string> fit_table(const std::string& fit_json, const FitReport& report);

}  // namespace cellflow::client
