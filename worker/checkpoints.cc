#include "worker/checkpoints.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <vector>

#include "rpc/rpc.h"
#include "worker/file_upload.h"

namespace cellflow::worker {

using namespace std::chrono_literals;

namespace {

// A checkpoint this large is refused before a byte is fetched (the server's
// own limit is the job's memory estimate times a small factor).
constexpr std::int64_t kMaxCheckpointBytes = std::int64_t{64} << 30;

rpc::RetryOptions checkpoint_retry() {
  rpc::RetryOptions retry;
  retry.deadline = 10min;
  retry.max_attempts = 0;
  retry.give_up_after = 10s;
  retry.initial_backoff = 100ms;
  retry.max_backoff = 2000ms;
  return retry;
}

}  // namespace

Status upload_checkpoint(v1::WorkerService::StubInterface& stub, const v1::Lease& lease,
                         const jobs::CheckpointWritten& written) {
  const grpc::Status status = rpc::call_with_retry(checkpoint_retry(), [&](grpc::ClientContext& context) {
    v1::UploadCheckpointResponse response;
    return upload_file_chunks<v1::CheckpointChunk>(
        stub.UploadCheckpoint(&context, &response), written.path, "checkpoint file",
        [&](v1::CheckpointChunk& chunk) {
          *chunk.mutable_lease() = lease;
          chunk.mutable_info()->set_time_step(written.time_step);
          chunk.mutable_info()->set_last_sample_index(written.last_sample_index);
        });
  });
  if (!status.ok()) return Status(StatusCode::kInternal, "checkpoint upload: " + status.error_message());
  return {};
}

Status fetch_checkpoint(v1::WorkerService::StubInterface& stub, const v1::Lease& lease,
                        const v1::CheckpointInfo& info, const std::string& path) {
  const std::int64_t expected = info.size_bytes();
  if (expected <= 0 || expected > kMaxCheckpointBytes) {
    return invalid_argument("checkpoint: announced size " + std::to_string(expected) + " outside (0, " +
                            std::to_string(kMaxCheckpointBytes) + "]");
  }
  std::int64_t received = 0;
  std::string error;
  const grpc::Status status = rpc::call_with_retry(checkpoint_retry(), [&](grpc::ClientContext& context) {
    received = 0;
    error.clear();
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) return grpc::Status(grpc::StatusCode::INTERNAL, "cannot create " + path);
    v1::FetchCheckpointRequest request;
    *request.mutable_lease() = lease;
    auto reader = stub.FetchCheckpoint(&context, request);
    if (!reader) return grpc::Status(grpc::StatusCode::UNIMPLEMENTED, "no checkpoint fetch");
    v1::CheckpointChunk chunk;
    while (reader->Read(&chunk)) {
      if (chunk.offset() != received ||
          received + static_cast<std::int64_t>(chunk.data().size()) > expected) {
        error = "chunk at offset " + std::to_string(chunk.offset()) + " beyond the announced size";
        context.TryCancel();
        break;
      }
      out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
      received += static_cast<std::int64_t>(chunk.data().size());
    }
    grpc::Status finished = reader->Finish();
    out.close();
    if (!out) return grpc::Status(grpc::StatusCode::INTERNAL, "cannot write " + path);
    return finished;
  });
  std::error_code ignored;
  if (!error.empty() || !status.ok() || received != expected) {
    std::filesystem::remove(path, ignored);
    if (!error.empty()) return Status(StatusCode::kFailedPrecondition, "checkpoint fetch: " + error);
    if (!status.ok()) return Status(StatusCode::kInternal, "checkpoint fetch: " + status.error_message());
    return Status(StatusCode::kFailedPrecondition, "checkpoint fetch: " + std::to_string(received) + " of " +
                                                       std::to_string(expected) + " bytes");
  }
  return {};
}

}  // namespace cellflow::worker
