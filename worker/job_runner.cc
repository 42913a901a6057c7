#include "worker/job_runner.h"

namespace cellflow::worker {

RunOutcome run_job(const jobs::SceneRegistry& registry, const v1::JobSpec& spec, const RunOptions& options,
                   const JobEvents& events) {
  auto prepared = registry.prepare(spec);
  if (!prepared.ok()) return {prepared.status()};
  return (*prepared)->run(spec, options, events);
}

}  // namespace cellflow::worker
