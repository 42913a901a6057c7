// The job spec as text: the protobuf JSON mapping in both directions and the
// scene a spec names. Light (protobuf only): the client parses specs with the
// same function the server and cellflow-run use, without linking physics.
#pragma once

#include <string>
#include <string_view>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Parses `json` (a misspelt field is an error, not a silent default).
StatusOr<v1::JobSpec> job_spec_from_json(const std::string& json);
std::string job_spec_to_json(const v1::JobSpec& spec);

// The name of the scene field set in `spec` ("compression", "shear_flow"),
// read from the proto's oneof; empty when none is set.
std::string_view scene_name(const v1::JobSpec& spec);

// The cell of the spec's scene (the message field "cell" of the scene
// oneof's set field, found through reflection), or nullptr when the scene or
// its cell is unset; *scene (if not null) gets the scene's field name.
v1::CellSpec* mutable_scene_cell(v1::JobSpec& spec, std::string* scene = nullptr);

}  // namespace cellflow::jobs
