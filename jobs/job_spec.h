// The edge between the protobuf job spec (proto/cellflow/v1/spec.proto) and
// the physics parameter structs: defaults are applied and every field is
// validated here, once, with messages naming the field path and its range.
#pragma once

#include <string>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "jobs/shear_flow/shear_flow_spec.h"  // to_params / validate of ShearFlowSpec

namespace cellflow::jobs {

StatusOr<scenes::CompressionParams> to_params(const v1::CompressionSpec& spec);
StatusOr<scenes::IndentationParams> to_params(const v1::IndentationSpec& spec);

// Validates the whole job (whichever scene is set); INVALID_ARGUMENT names the field.
Status validate(const v1::JobSpec& spec);

// protobuf JSON mapping in both directions.
StatusOr<v1::JobSpec> job_spec_from_json(const std::string& json);
std::string job_spec_to_json(const v1::JobSpec& spec);

}  // namespace cellflow::jobs
