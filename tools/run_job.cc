#include "tools/run_job.h"

#include <cstdio>
#include <fstream>
#include <numbers>
#include <sstream>

#include "physics/scenes/shear_flow/shear_flow.h"
#include "jobs/job_spec.h"

namespace cellflow::tools {

namespace {

std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

RunOutcome outcome_for(const Status& status) {
  RunOutcome outcome;
  outcome.status = status;
  switch (status.code()) {
    case StatusCode::kOk:
      outcome.exit_code = kExitOk;
      break;
    case StatusCode::kInvalidArgument:
    case StatusCode::kNotFound:
    case StatusCode::kFailedPrecondition:
    case StatusCode::kResourceExhausted:
      outcome.exit_code = kExitInvalidSpec;
      break;
    default:
      outcome.exit_code = kExitNumericalFailure;
      break;
  }
  return outcome;
}

}  // namespace

std::string curve_csv_header() {
  return "point,deformation,displacement_m,force_n,hertz_force_n,force_over_hertz,taylor_deformation,a1_m,a2_"
         "m,a3_"
         "m,volume_m3,elastic_energy_j,max_penetration_m,newton_iterations,step_splits,residual";
}

std::string curve_csv_row(const scenes::CurvePoint& p) {
  const double ratio = p.hertz_force_n > 0.0 ? p.force_n / p.hertz_force_n : 0.0;
  std::string row = std::to_string(p.index);
  for (double v : {p.deformation, p.displacement_m, p.force_n, p.hertz_force_n, ratio, p.taylor_deformation,
                   p.semi_axes_m[0], p.semi_axes_m[1], p.semi_axes_m[2], p.volume_m3, p.elastic_energy_j,
                   p.max_penetration_m}) {
    row += ',' + number(v);
  }
  row += ',' + std::to_string(p.newton_iterations) + ',' + std::to_string(p.step_splits) + ',' +
         number(p.residual);
  return row;
}

std::string deformation_csv_header() {
  return "sample,time_s,strain,taylor_deformation,inclination_rad,net_strain,a1_m,a2_m,a3_m,"
         "tank_treading_frequency_per_s,volume_m3";
}

std::string deformation_csv_row(const scenes::ShearFlowSample& s) {
  std::string row = std::to_string(s.index);
  for (double v : {s.time_s, s.strain_units, s.taylor_deformation,
                   s.inclination_deg * std::numbers::pi / 180.0, s.net_strain, s.semi_axes_m[0],
                   s.semi_axes_m[1], s.semi_axes_m[2], s.tank_treading_frequency_per_s, s.volume_m3}) {
    row += ',' + number(v);
  }
  return row;
}

namespace {

RunOutcome run_shear_flow(const v1::ShearFlowSpec& spec, std::ostream& csv, std::ostream* progress,
                          int threads) {
  StatusOr<scenes::ShearFlowParams> params = jobs::to_params(spec);
  if (!params.ok()) return outcome_for(params.status());
  params->numerics.threads = threads;
  csv << deformation_csv_header() << '\n' << std::flush;
  scenes::ShearFlowCallbacks callbacks;
  callbacks.on_sample = [&](const scenes::ShearFlowSample& s) {
    csv << deformation_csv_row(s) << '\n' << std::flush;
    if (progress) {
      char line[200];
      std::snprintf(line, sizeof(line), "sample %d  strain %.2f/%.4g  D %.4f  inclination %.2f deg\n",
                    s.index, s.strain_units, params->numerics.max_strain, s.taylor_deformation,
                    s.inclination_deg);
      *progress << line << std::flush;
    }
  };
  const scenes::ShearFlowResult result = scenes::run_shear_flow(*params, callbacks);
  if (progress && !result.samples.empty()) {
    char line[300];
    std::snprintf(
        line, sizeof(line),
        "stopped: %s after %lld steps (%.1f s); Ca %.4g, steady D %.5f (5/4 Ca = %.5f), "
        "inclination %.2f deg\n",
        std::string(scenes::stop_name(result.stop)).c_str(), static_cast<long long>(result.time_steps),
        result.wall_time_s, result.setup.capillary_number, result.steady_taylor_deformation,
        scenes::small_ca_taylor_deformation(result.setup.capillary_number), result.steady_inclination_deg);
    *progress << line;
    for (const std::string& w : result.warnings) *progress << "warning: " << w << '\n';
    *progress << std::flush;
  }
  return outcome_for(result.status);
}

}  // namespace

RunOutcome run_spec_file(const std::string& spec_path, std::ostream& csv, std::ostream* progress,
                         int threads) {
  std::ifstream in(spec_path);
  if (!in) return outcome_for(invalid_argument("spec file '" + spec_path + "' cannot be opened for reading"));
  std::stringstream text;
  text << in.rdbuf();
  StatusOr<v1::JobSpec> spec = jobs::job_spec_from_json(text.str());
  if (!spec.ok()) return outcome_for(spec.status());
  return run_job(*spec, csv, progress, threads);
}

RunOutcome run_job(const v1::JobSpec& spec, std::ostream& csv, std::ostream* progress, int threads) {
  if (threads < 0)
    return outcome_for(invalid_argument("--threads = " + std::to_string(threads) + " must be >= 0"));
  if (Status s = jobs::validate(spec); !s.ok()) return outcome_for(s);
  if (spec.has_shear_flow()) return run_shear_flow(spec.shear_flow(), csv, progress, threads);
  scenes::SceneCallbacks callbacks;
  int total_points = 0;
  callbacks.on_point = [&](const scenes::CurvePoint& p) {
    csv << curve_csv_row(p) << '\n' << std::flush;
    if (progress) {
      char line[200];
      std::snprintf(line, sizeof(line),
                    "point %d/%d  deformation %.4f  force %.4g N  F/F_Hertz %.3f  Newton %d  splits %d\n",
                    p.index + 1, total_points, p.deformation, p.force_n,
                    p.hertz_force_n > 0 ? p.force_n / p.hertz_force_n : 0.0, p.newton_iterations,
                    p.step_splits);
      *progress << line << std::flush;
    }
  };
  csv << curve_csv_header() << '\n' << std::flush;
  scenes::QuasiStaticResult result;
  if (spec.has_compression()) {
    StatusOr<scenes::CompressionParams> params = jobs::to_params(spec.compression());
    if (!params.ok()) return outcome_for(params.status());
    total_points = params->load_points;
    params->numerics.threads = threads;
    result = scenes::run_compression(*params, callbacks);
  } else {
    StatusOr<scenes::IndentationParams> params = jobs::to_params(spec.indentation());
    if (!params.ok()) return outcome_for(params.status());
    total_points = params->load_points;
    params->numerics.threads = threads;
    result = scenes::run_indentation(*params, callbacks);
  }
  return outcome_for(result.status);
}

}  // namespace cellflow::tools
