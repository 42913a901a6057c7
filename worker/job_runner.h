// Runs one leased job spec in this process: the scene registry converts and
// validates the spec once (jobs/registry.h), and the prepared job runs with
// callbacks that report every sample as it is computed and writes the HDF5
// result (io/, H5MD layout). No gRPC here: the worker passes callbacks that
// forward to the server; tests call it directly.
#pragma once

#include "cellflow/v1/spec.pb.h"
#include "jobs/registry.h"
#include "jobs/scene.h"

namespace cellflow::worker {

using jobs::JobEvents;
using jobs::RunOptions;
using jobs::RunOutcome;

RunOutcome run_job(const jobs::SceneRegistry& registry, const v1::JobSpec& spec, const RunOptions& options,
                   const JobEvents& events);
// The same with the spec that runs (e.g. with an uploaded mesh's bytes filled
// in, CellSpec.mesh_bytes) apart from the one recorded as /parameters.
RunOutcome run_job(const jobs::SceneRegistry& registry, const v1::JobSpec& spec, const v1::JobSpec& recorded,
                   const RunOptions& options, const JobEvents& events);

}  // namespace cellflow::worker
