// The suspension scene as a job (physics/scenes/suspension, paper section
// 7.2): the proto spec converted, validated and placed once, the result file
// (every cell's positions at snapshots as one particle group "cell", the kind
// of each cell, per-cell and mean observables, the averages; layout in
// jobs/suspension/result_schema.json), SuspensionSample messages (the first
// kMaxStreamedSuspensionCells cells) and the mean D(t) CSV.
#pragma once

#include <memory>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "jobs/scene.h"
#include "physics/core/status.h"
#include "physics/scenes/suspension/suspension.h"

namespace cellflow::jobs {

// Registry entry (jobs/registry.cc).
StatusOr<std::unique_ptr<PreparedJob>> prepare_suspension(const v1::JobSpec& spec);

// A suspension sample as the sample message of the API: angles in radians,
// the first kMaxStreamedSuspensionCells cells.
v1::SuspensionSample suspension_sample_from(const scenes::SuspensionSample& sample);

// The suspension CSV (cellflow-run, `cellflow result --csv`): sample, time_s,
// strain, cell_count, mean_taylor_deformation, mean_inclination_rad,
// relative_viscosity, contact_pairs, average_taylor_deformation,
// average_taylor_deformation_error, average_relative_viscosity,
// average_relative_viscosity_error.
std::string suspension_csv_header();
std::string suspension_csv_row(const scenes::SuspensionSample& sample);

}  // namespace cellflow::jobs
