// The edge between the protobuf SuspensionSpec (proto/cellflow/v1/suspension.proto)
// and scenes::SuspensionParams: unset optional fields take the scene's
// documented defaults (suspension_numerics_defaults(): the paper's 5 x 8 x 4
// box, no steady stop, max_strain 20, 1000 vertices per cell), and errors
// name the proto's field path ("suspension.cells[1].viscosity_ratio") with its
// allowed range.
#pragma once

#include <string_view>

#include "cellflow/v1/suspension.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/suspension/suspension.h"

namespace cellflow::jobs {

// At most this many kinds of cell (scenes::SuspensionParams allows 64); more
// are refused before any is converted.
inline constexpr int kMaxSuspendedKinds = 64;

// Converts: the fields of `spec` over the scene's defaults, the drive, the
// IBM kernel name; ranges and placement are left to plan_suspension_run.
StatusOr<scenes::SuspensionParams> convert(const v1::SuspensionSpec& spec,
                                           std::string_view field_prefix = "suspension.");

// Converts, validates and plans (ranges, Mach number, memory, placement: a
// volume fraction that cannot be placed, overlapping or outside places).
// kInvalidArgument / kResourceExhausted name the proto field.
StatusOr<scenes::PlannedSuspension> plan(const v1::SuspensionSpec& spec,
                                         std::string_view field_prefix = "suspension.");

// The physics names a kind "kinds[k]", the proto "cells[k]": `status` with
// field_prefix + "kinds[" renamed to field_prefix + "cells[".
Status with_proto_field_names(Status status, std::string_view field_prefix);

}  // namespace cellflow::jobs
