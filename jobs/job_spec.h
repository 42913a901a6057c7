// The job spec layer in one include: the JSON mapping (jobs/spec_json.h), the
// per-scene conversions (to_params) and validate(), which prepares a spec
// through a scene registry of its own. Programs that go on to run or estimate
// a job use jobs::SceneRegistry::prepare instead, so that they convert once.
#pragma once

#include "cellflow/v1/spec.pb.h"
#include "jobs/quasi_static/quasi_static_job.h"
#include "jobs/shear_flow/shear_flow_spec.h"
#include "jobs/spec_json.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Validates the whole job (whichever scene is set); INVALID_ARGUMENT names the field.
Status validate(const v1::JobSpec& spec);

}  // namespace cellflow::jobs
