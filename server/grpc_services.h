// Thin gRPC handlers over JobService: translate messages and status codes,
// nothing else. Synchronous API; streaming handlers check for client
// cancellation.
#pragma once

#include <grpcpp/grpcpp.h>

#include "cellflow/v1/service.grpc.pb.h"
#include "cellflow/v1/worker.grpc.pb.h"
#include "server/auth.h"
#include "server/job_service.h"

namespace cellflow::server {

// cellflow::Status -> grpc::Status. While the service drains, refusals and
// interrupted streams become UNAVAILABLE so that clients retry elsewhere/later.
grpc::Status to_grpc(const Status& status, bool draining = false);

class CellflowServiceImpl final : public v1::CellflowService::Service {
 public:
  // `auth`: the verdicts of the listener's interceptor (server/auth.h); null:
  // every call is the local admin (in-process use only).
  explicit CellflowServiceImpl(JobService& jobs, const CallAuth* auth = nullptr) : jobs_(jobs), auth_(auth) {}

  grpc::Status SubmitJob(grpc::ServerContext* context, const v1::SubmitJobRequest* request,
                         v1::SubmitJobResponse* response) override;
  grpc::Status GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                      v1::Job* response) override;
  grpc::Status ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest* request,
                        v1::ListJobsResponse* response) override;
  grpc::Status CancelJob(grpc::ServerContext* context, const v1::CancelJobRequest* request,
                         v1::Job* response) override;
  grpc::Status WatchJob(grpc::ServerContext* context, const v1::WatchJobRequest* request,
                        grpc::ServerWriter<v1::JobEvent>* writer) override;
  grpc::Status DownloadResult(grpc::ServerContext* context, const v1::DownloadResultRequest* request,
                              grpc::ServerWriter<v1::ResultChunk>* writer) override;
  grpc::Status UploadMesh(grpc::ServerContext* context, grpc::ServerReader<v1::MeshChunk>* reader,
                          v1::MeshRef* response) override;
  grpc::Status DeleteJob(grpc::ServerContext* context, const v1::DeleteJobRequest* request,
                         v1::DeleteJobResponse* response) override;

 private:
  JobService& jobs_;
  const CallAuth* auth_;
};

class WorkerServiceImpl final : public v1::WorkerService::Service {
 public:
  explicit WorkerServiceImpl(JobService& jobs, const CallAuth* auth = nullptr) : jobs_(jobs), auth_(auth) {}

  grpc::Status LeaseJob(grpc::ServerContext* context, const v1::LeaseJobRequest* request,
                        v1::LeaseJobResponse* response) override;
  grpc::Status ReportJob(grpc::ServerContext* context,
                         grpc::ServerReaderWriter<v1::ReportAck, v1::WorkerReport>* stream) override;
  grpc::Status UploadResult(grpc::ServerContext* context, grpc::ServerReader<v1::UploadChunk>* reader,
                            v1::UploadResultResponse* response) override;
  grpc::Status FinishJob(grpc::ServerContext* context, const v1::FinishJobRequest* request,
                         v1::FinishJobResponse* response) override;
  grpc::Status FailJob(grpc::ServerContext* context, const v1::FailJobRequest* request,
                       v1::FinishJobResponse* response) override;
  grpc::Status ReleaseJob(grpc::ServerContext* context, const v1::ReleaseJobRequest* request,
                          v1::FinishJobResponse* response) override;
  grpc::Status FetchMesh(grpc::ServerContext* context, const v1::FetchMeshRequest* request,
                         grpc::ServerWriter<v1::MeshChunk>* writer) override;
  grpc::Status UploadCheckpoint(grpc::ServerContext* context, grpc::ServerReader<v1::CheckpointChunk>* reader,
                                v1::UploadCheckpointResponse* response) override;
  grpc::Status FetchCheckpoint(grpc::ServerContext* context, const v1::FetchCheckpointRequest* request,
                               grpc::ServerWriter<v1::CheckpointChunk>* writer) override;

 private:
  JobService& jobs_;
  const CallAuth* auth_;
};

}  // namespace cellflow::server
