#include "jobs/job_spec.h"

#include "jobs/registry.h"

namespace cellflow::jobs {

Status validate(const v1::JobSpec& spec) {
  return SceneRegistry().prepare(spec).status();
}

}  // namespace cellflow::jobs
