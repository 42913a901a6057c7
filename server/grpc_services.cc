#include "server/grpc_services.h"

namespace cellflow::server {

grpc::Status to_grpc(const Status& status, bool draining) {
  if (status.ok()) return grpc::Status::OK;
  if (draining) return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down: " + status.message()};
  switch (status.code()) {
    case StatusCode::kOk:
      return grpc::Status::OK;
    case StatusCode::kInvalidArgument:
      return {grpc::StatusCode::INVALID_ARGUMENT, status.message()};
    case StatusCode::kNotFound:
      return {grpc::StatusCode::NOT_FOUND, status.message()};
    case StatusCode::kFailedPrecondition:
      return {grpc::StatusCode::FAILED_PRECONDITION, status.message()};
    case StatusCode::kResourceExhausted:
      return {grpc::StatusCode::RESOURCE_EXHAUSTED, status.message()};
    case StatusCode::kCancelled:
      return {grpc::StatusCode::CANCELLED, status.message()};
    case StatusCode::kNumericalFailure:
    case StatusCode::kInternal:
      break;
  }
  return {grpc::StatusCode::INTERNAL, status.to_string()};
}

namespace {

template <class T, class Out>
grpc::Status reply(StatusOr<T> result, Out* out, bool draining = false) {
  if (!result.ok()) return to_grpc(result.status(), draining);
  *out = std::move(*result);
  return grpc::Status::OK;
}

// The caller as the listener's interceptor identified it; a refused call
// stops here, before the service logic.
grpc::Status authorize(const CallAuth* auth, const grpc::ServerContextBase* context, Identity* caller) {
  if (auth == nullptr) {
    *caller = Identity::local();
    return grpc::Status::OK;
  }
  return auth->caller(context, caller);
}

#define CELLFLOW_AUTHORIZE(context, caller)                                       \
  [[maybe_unused]] Identity caller;                                               \
  if (grpc::Status refused = authorize(auth_, context, &caller); !refused.ok()) { \
    return refused;                                                               \
  }

}  // namespace

grpc::Status CellflowServiceImpl::SubmitJob(grpc::ServerContext* context, const v1::SubmitJobRequest* request,
                                            v1::SubmitJobResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  if (jobs_.draining()) return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down"};
  return reply(jobs_.submit(*request, caller), response);
}

grpc::Status CellflowServiceImpl::GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                                         v1::Job* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.get(request->job_id(), caller), response);
}

grpc::Status CellflowServiceImpl::ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest* request,
                                           v1::ListJobsResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.list(*request, caller), response);
}

grpc::Status CellflowServiceImpl::CancelJob(grpc::ServerContext* context, const v1::CancelJobRequest* request,
                                            v1::Job* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.cancel(request->job_id(), caller), response);
}

grpc::Status CellflowServiceImpl::WatchJob(grpc::ServerContext* context, const v1::WatchJobRequest* request,
                                           grpc::ServerWriter<v1::JobEvent>* writer) {
  CELLFLOW_AUTHORIZE(context, caller)
  Status status = jobs_.watch(
      *request, [&](const v1::JobEvent& event) { return writer->Write(event); },
      [&] { return context->IsCancelled(); }, caller);
  // A watch cut short by shutdown: UNAVAILABLE, so the client resumes.
  return to_grpc(status, !status.ok() && status.code() == StatusCode::kCancelled && jobs_.draining());
}

grpc::Status CellflowServiceImpl::DownloadResult(grpc::ServerContext* context,
                                                 const v1::DownloadResultRequest* request,
                                                 grpc::ServerWriter<v1::ResultChunk>* writer) {
  CELLFLOW_AUTHORIZE(context, caller)
  return to_grpc(jobs_.download(
      request->job_id(),
      [&](const v1::ResultChunk& chunk) { return !context->IsCancelled() && writer->Write(chunk); }, caller,
      request->part()));
}

grpc::Status CellflowServiceImpl::UploadMesh(grpc::ServerContext* context,
                                             grpc::ServerReader<v1::MeshChunk>* reader,
                                             v1::MeshRef* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  if (jobs_.draining()) return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down"};
  const std::uint64_t limit = jobs_.options().max_mesh_bytes;
  std::string bytes;
  std::string name;
  v1::MeshChunk chunk;
  bool first = true;
  while (reader->Read(&chunk)) {
    if (context->IsCancelled()) return {grpc::StatusCode::CANCELLED, "the client went away"};
    if (first) name = chunk.file_name();
    first = false;
    // Refused as soon as the limit is passed, before more is kept.
    if (bytes.size() + chunk.data().size() > limit) {
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "mesh: over this server's limit of " + std::to_string(limit) + " bytes (--max-mesh-bytes)"};
    }
    bytes += chunk.data();
  }
  if (bytes.empty()) return {grpc::StatusCode::INVALID_ARGUMENT, "mesh: the upload is empty"};
  return reply(jobs_.upload_mesh(bytes, name), response);
}

grpc::Status CellflowServiceImpl::DeleteJob(grpc::ServerContext* context, const v1::DeleteJobRequest* request,
                                            v1::DeleteJobResponse*) {
  CELLFLOW_AUTHORIZE(context, caller)
  return to_grpc(jobs_.delete_job(request->job_id(), caller));
}

grpc::Status WorkerServiceImpl::FetchMesh(grpc::ServerContext* context, const v1::FetchMeshRequest* request,
                                          grpc::ServerWriter<v1::MeshChunk>* writer) {
  CELLFLOW_AUTHORIZE(context, caller)
  return to_grpc(jobs_.fetch_mesh(
      *request, [&](const v1::MeshChunk& chunk) { return !context->IsCancelled() && writer->Write(chunk); }));
}

grpc::Status WorkerServiceImpl::LeaseJob(grpc::ServerContext* context, const v1::LeaseJobRequest* request,
                                         v1::LeaseJobResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.lease(*request, [&] { return context->IsCancelled(); }), response);
}

grpc::Status WorkerServiceImpl::ReportJob(grpc::ServerContext* context,
                                          grpc::ServerReaderWriter<v1::ReportAck, v1::WorkerReport>* stream) {
  CELLFLOW_AUTHORIZE(context, caller)
  v1::WorkerReport report;
  while (stream->Read(&report)) {
    auto ack = jobs_.report(report);
    if (!ack.ok()) return to_grpc(ack.status());
    if (!stream->Write(*ack)) return {grpc::StatusCode::CANCELLED, "the worker went away"};
    if (!ack->lease_valid()) break;  // the attempt is over; the worker stops
  }
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::UploadResult(grpc::ServerContext* context,
                                             grpc::ServerReader<v1::UploadChunk>* reader,
                                             v1::UploadResultResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  v1::UploadChunk chunk;
  if (!reader->Read(&chunk)) return {grpc::StatusCode::INVALID_ARGUMENT, "upload without chunks"};
  auto upload = jobs_.begin_upload(chunk.lease(), chunk.part());
  if (!upload.ok()) return to_grpc(upload.status());
  do {
    if (context->IsCancelled()) return {grpc::StatusCode::CANCELLED, "the worker went away"};
    if (Status s = (*upload)->write(chunk.offset(), chunk.data()); !s.ok()) return to_grpc(s);
  } while (reader->Read(&chunk));
  auto size = (*upload)->complete();
  if (!size.ok()) return to_grpc(size.status());
  response->set_size_bytes(*size);
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::UploadCheckpoint(grpc::ServerContext* context,
                                                 grpc::ServerReader<v1::CheckpointChunk>* reader,
                                                 v1::UploadCheckpointResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  v1::CheckpointChunk chunk;
  if (!reader->Read(&chunk)) return {grpc::StatusCode::INVALID_ARGUMENT, "checkpoint upload without chunks"};
  const v1::Lease lease = chunk.lease();
  const v1::CheckpointInfo info = chunk.info();
  auto upload = jobs_.begin_checkpoint_upload(lease);
  if (!upload.ok()) return to_grpc(upload.status());
  do {
    if (context->IsCancelled()) return {grpc::StatusCode::CANCELLED, "the worker went away"};
    if (Status s = (*upload)->write(chunk.offset(), chunk.data()); !s.ok()) return to_grpc(s);
  } while (reader->Read(&chunk));
  auto size = jobs_.commit_checkpoint(lease, info, **upload);
  if (!size.ok()) return to_grpc(size.status());
  response->set_size_bytes(*size);
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::FetchCheckpoint(grpc::ServerContext* context,
                                                const v1::FetchCheckpointRequest* request,
                                                grpc::ServerWriter<v1::CheckpointChunk>* writer) {
  CELLFLOW_AUTHORIZE(context, caller)
  return to_grpc(jobs_.fetch_checkpoint(*request, [&](const v1::CheckpointChunk& chunk) {
    return !context->IsCancelled() && writer->Write(chunk);
  }));
}

grpc::Status WorkerServiceImpl::FinishJob(grpc::ServerContext* context, const v1::FinishJobRequest* request,
                                          v1::FinishJobResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.finish(*request), response);
}

grpc::Status WorkerServiceImpl::FailJob(grpc::ServerContext* context, const v1::FailJobRequest* request,
                                        v1::FinishJobResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.fail(*request), response);
}

grpc::Status WorkerServiceImpl::ReleaseJob(grpc::ServerContext* context, const v1::ReleaseJobRequest* request,
                                           v1::FinishJobResponse* response) {
  CELLFLOW_AUTHORIZE(context, caller)
  return reply(jobs_.release(*request), response);
}

}  // namespace cellflow::server
