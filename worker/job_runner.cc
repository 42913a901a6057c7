#include "worker/job_runner.h"

namespace cellflow::worker {

RunOutcome run_job(const jobs::SceneRegistry& registry, const v1::JobSpec& spec, const RunOptions& options,
                   const JobEvents& events) {
  return run_job(registry, spec, spec, options, events);
}

RunOutcome run_job(const jobs::SceneRegistry& registry, const v1::JobSpec& spec, const v1::JobSpec& recorded,
                   const RunOptions& options, const JobEvents& events) {
  auto prepared = registry.prepare(spec);
  if (!prepared.ok()) return {prepared.status()};
  return (*prepared)->run(recorded, options, events);
}

}  // namespace cellflow::worker
