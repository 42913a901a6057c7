// The logic of `cellflow-run SPEC.json`: read a job spec in the protobuf JSON
// mapping, validate it, run its scene and write CSV: the force curve of a
// quasi-static scene, the deformation time series D(t) of a shear flow.
// main() only parses the command line (tools/cellflow_run_main.cc).
#pragma once

#include <ostream>
#include <string>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::tools {

// Exit codes of cellflow-run.
enum ExitCode : int {
  kExitOk = 0,
  kExitUsage = 1,             // bad command line
  kExitInvalidSpec = 2,       // unreadable or invalid spec, bad mesh file; the message names the field
  kExitNumericalFailure = 3,  // the run failed (curve so far still written)
};

// Header of the curve CSV: the column names carry their SI units.
std::string curve_csv_header();
// One row; doubles with 17 significant digits so they read back exactly.
std::string curve_csv_row(const scenes::CurvePoint& point);

// The shear-flow CSV (the columns of `cellflow result --csv` for a flow job):
// sample, time_s, strain (gammadot t), taylor_deformation, inclination_rad,
// net_strain, a1_m, a2_m, a3_m, tank_treading_frequency_per_s, volume_m3.
std::string deformation_csv_header();
std::string deformation_csv_row(const scenes::ShearFlowSample& sample);

struct RunOutcome {
  ExitCode exit_code = kExitOk;
  Status status;
};

// Reads the file at spec_path (JSON) and runs it. threads > 0 overrides the
// OpenMP thread count of the solve (0: the OpenMP default).
RunOutcome run_spec_file(const std::string& spec_path, std::ostream& csv, std::ostream* progress,
                         int threads = 0);

// Validates and runs `spec`; writes the CSV header and one row per converged
// point (flow: per sample) to `csv` as the run goes (so a failed run keeps its
// curve), progress lines to `progress` when it is not null.
RunOutcome run_job(const v1::JobSpec& spec, std::ostream& csv, std::ostream* progress, int threads = 0);

}  // namespace cellflow::tools
