// The worker's side of checkpoint and restart (flow jobs): uploads a
// checkpoint file the running job wrote (UploadCheckpoint, fenced by the
// lease, chunked like UploadResult) and fetches the one a re-leased attempt
// was told about (FetchCheckpoint, bounded by the announced size).
#pragma once

#include <cstdint>
#include <string>

#include "cellflow/v1/worker.grpc.pb.h"
#include "jobs/scene.h"
#include "physics/core/status.h"

namespace cellflow::worker {

// Uploads `written.path` as the job's checkpoint. Tries again while the
// server is UNAVAILABLE for a few seconds; a failure leaves the previous
// checkpoint in place (the run goes on).
Status upload_checkpoint(v1::WorkerService::StubInterface& stub, const v1::Lease& lease,
                         const jobs::CheckpointWritten& written);

// Writes the job's checkpoint (announced as `info`) to `path`; at most
// info.size_bytes, and exactly that many, or an error (the file is removed).
Status fetch_checkpoint(v1::WorkerService::StubInterface& stub, const v1::Lease& lease,
                        const v1::CheckpointInfo& info, const std::string& path);

}  // namespace cellflow::worker
