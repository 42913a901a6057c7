// The job spec as text: the protobuf JSON mapping in both directions and the
// scene a spec names. Light (protobuf only): the client parses specs with the
// same function the server and cellflow-run use, without linking physics.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Parses `json` (a misspelt field is an error, not a silent default).
StatusOr<v1::JobSpec> job_spec_from_json(const std::string& json);
std::string job_spec_to_json(const v1::JobSpec& spec);

// The name of the scene field set in `spec` ("compression", "shear_flow"),
// read from the proto's oneof; empty when none is set.
std::string_view scene_name(const v1::JobSpec& spec);

// A cell of the spec's scene and its field path ("shear_flow.cell",
// "suspension.cells[1].cell").
struct SceneCell {
  std::string field;
  v1::CellSpec* cell = nullptr;
};

// Every cell of the spec's scene, found through reflection: the scene
// oneof's set field's message field "cell", and the field "cell" of each
// element of its repeated message fields (a suspension's kinds); empty when
// the scene or its cells are unset. *scene (if not null) gets the scene's
// field name. Whatever reads or checks a cell's mesh goes through this, so
// that no scene's cells escape the service's mesh rules.
std::vector<SceneCell> scene_cells(v1::JobSpec& spec, std::string* scene = nullptr);

}  // namespace cellflow::jobs
