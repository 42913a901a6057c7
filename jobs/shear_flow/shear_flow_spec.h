// The edge between the protobuf ShearFlowSpec (proto/cellflow/v1/shear_flow.proto)
// and scenes::ShearFlowParams: unset optional fields take the scene's
// documented defaults, and every field is validated here, once, with messages
// naming the field path (prefix "shear_flow.") and its allowed range.
#pragma once

#include <string_view>

#include "cellflow/v1/shear_flow.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::jobs {

// The set fields of `in` over `numerics` (which holds the scene's defaults:
// the suspension scene shares these numerics with its own defaults); errors
// name field_prefix + field (e.g. "shear_flow.numerics.ibm_kernel").
Status convert_numerics(const v1::ShearFlowNumerics& in, scenes::ShearFlowNumerics& numerics,
                        std::string_view field_prefix);

// Converts: the fields of `spec` over the scene's defaults, the drive and the
// kernel name checked; ranges are left to scenes::plan_shear_flow.
StatusOr<scenes::ShearFlowParams> convert(const v1::ShearFlowSpec& spec,
                                          std::string_view field_prefix = "shear_flow.");

// Converts and validates (fields, ranges, the IBM kernel name, the Mach
// number and the lattice memory: everything that needs no mesh).
// kInvalidArgument / kResourceExhausted name the field.
StatusOr<scenes::ShearFlowParams> to_params(const v1::ShearFlowSpec& spec,
                                            std::string_view field_prefix = "shear_flow.");

// to_params(spec).status(): what the job validation calls before queueing.
Status validate(const v1::ShearFlowSpec& spec, std::string_view field_prefix = "shear_flow.");

}  // namespace cellflow::jobs
