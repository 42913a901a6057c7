// The quasi-static contact scenes as jobs (compression between plates, probe
// indentation; physics/scenes/quasi_static): the proto spec converted and
// validated into their parameters, the result file (mesh, position frames,
// every curve point as an H5MD observable; layout in
// jobs/quasi_static/result_schema.json), ForceSample messages and the curve CSV.
#pragma once

#include <memory>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "jobs/scene.h"
#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::jobs {

// Converts and validates (field paths "compression." / "indentation.").
StatusOr<scenes::CompressionParams> to_params(const v1::CompressionSpec& spec);
StatusOr<scenes::IndentationParams> to_params(const v1::IndentationSpec& spec);

// Registry entries (jobs/registry.cc).
StatusOr<std::unique_ptr<PreparedJob>> prepare_compression(const v1::JobSpec& spec);
StatusOr<std::unique_ptr<PreparedJob>> prepare_indentation(const v1::JobSpec& spec);

// A curve point as the sample message of the API.
v1::ForceSample force_sample_from(const scenes::CurvePoint& point);

// Header of the curve CSV (the column names carry their SI units) and one
// row; doubles with 17 significant digits so they read back exactly.
std::string curve_csv_header();
std::string curve_csv_row(const scenes::CurvePoint& point);

}  // namespace cellflow::jobs
