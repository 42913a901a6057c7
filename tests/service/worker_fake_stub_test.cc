// The worker against a fake server: a hand-written v1::WorkerService::StubInterface
// (no channel, no server process) that leases one tiny compression job and
// records what the worker reports, uploads and finishes. Every call of the
// worker goes through the one stub it was given (worker/worker.h).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "cellflow/v1/worker.grpc.pb.h"
#include "worker/worker.h"

namespace cellflow::worker {
namespace {

namespace fs = std::filesystem;

v1::JobSpec tiny_compression() {
  v1::JobSpec spec;
  spec.set_name("fake-stub");
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1000.0);
  c->mutable_cell()->set_target_vertex_count(300);
  c->set_max_deformation(0.1);
  c->set_load_points(3);
  return spec;
}

// What the fake server saw; shared by the stub and its streams (the reporter
// writes and reads on two threads of its own).
struct FakeServer {
  std::mutex mutex;
  int unavailable_leases = 0;  // LeaseJob calls answered UNAVAILABLE before the job is handed out
  bool job_handed_out = false;
  v1::LeaseJobResponse job;

  int lease_calls = 0;
  std::vector<v1::LeaseJobRequest> lease_requests;
  std::vector<v1::WorkerReport> reports;
  int report_streams = 0;
  struct Upload {
    v1::Lease lease;
    v1::ResultPart part = v1::RESULT_PART_HDF5;
    std::string data;
    std::int64_t next_offset = 0;
    bool offsets_contiguous = true;
  };
  std::vector<Upload> uploads;
  std::vector<v1::FinishJobRequest> finishes;
  std::vector<v1::FailJobRequest> failures;
  std::vector<v1::ReleaseJobRequest> releases;
  // Called by LeaseJob before it answers (outside the lock): a signal that
  // arrives while the poll is in flight.
  std::function<void()> on_lease;
};

// ReportJob: every report is recorded and acknowledged at once (lease valid).
class FakeReportStream final : public grpc::ClientReaderWriterInterface<v1::WorkerReport, v1::ReportAck> {
 public:
  explicit FakeReportStream(FakeServer& server) : server_(server) {}

  void WaitForInitialMetadata() override {}
  bool NextMessageSize(uint32_t* size) override {
    *size = 1u << 20;
    return true;
  }
  bool Write(const v1::WorkerReport& report, grpc::WriteOptions) override {
    {
      std::lock_guard lock(server_.mutex);
      server_.reports.push_back(report);
    }
    v1::ReportAck ack;
    ack.set_report_id(report.report_id());
    ack.set_lease_valid(true);
    std::lock_guard lock(mutex_);
    acks_.push_back(ack);
    changed_.notify_all();
    return true;
  }
  bool Read(v1::ReportAck* ack) override {
    std::unique_lock lock(mutex_);
    // The worker ends a healthy stream with WritesDone; the bound only keeps a
    // broken test from hanging (a fake cannot see ClientContext::TryCancel).
    changed_.wait_for(lock, std::chrono::seconds(20), [&] { return !acks_.empty() || writes_done_; });
    if (acks_.empty()) return false;
    *ack = acks_.front();
    acks_.pop_front();
    return true;
  }
  bool WritesDone() override {
    std::lock_guard lock(mutex_);
    writes_done_ = true;
    changed_.notify_all();
    return true;
  }
  grpc::Status Finish() override { return grpc::Status::OK; }

 private:
  FakeServer& server_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<v1::ReportAck> acks_;
  bool writes_done_ = false;
};

// UploadResult: the chunks are joined and recorded when the call finishes.
class FakeUploadWriter final : public grpc::ClientWriterInterface<v1::UploadChunk> {
 public:
  FakeUploadWriter(FakeServer& server, v1::UploadResultResponse* response)
      : server_(server), response_(response) {}

  bool Write(const v1::UploadChunk& chunk, grpc::WriteOptions) override {
    if (first_) upload_.lease = chunk.lease();
    if (first_) upload_.part = chunk.part();
    first_ = false;
    if (chunk.offset() != upload_.next_offset) upload_.offsets_contiguous = false;
    upload_.data += chunk.data();
    upload_.next_offset = chunk.offset() + static_cast<std::int64_t>(chunk.data().size());
    return true;
  }
  bool WritesDone() override { return true; }
  grpc::Status Finish() override {
    response_->set_size_bytes(static_cast<std::int64_t>(upload_.data.size()));
    std::lock_guard lock(server_.mutex);
    server_.uploads.push_back(upload_);
    return grpc::Status::OK;
  }

 private:
  FakeServer& server_;
  v1::UploadResultResponse* response_;
  FakeServer::Upload upload_;
  bool first_ = true;
};

class FakeWorkerStub final : public v1::WorkerService::StubInterface {
 public:
  explicit FakeWorkerStub(std::shared_ptr<FakeServer> server) : server_(std::move(server)) {}

  grpc::Status LeaseJob(grpc::ClientContext*, const v1::LeaseJobRequest& request,
                        v1::LeaseJobResponse* response) override {
    if (server_->on_lease) server_->on_lease();
    std::lock_guard lock(server_->mutex);
    ++server_->lease_calls;
    server_->lease_requests.push_back(request);
    if (server_->unavailable_leases > 0) {
      --server_->unavailable_leases;
      return {grpc::StatusCode::UNAVAILABLE, "fake server: not yet"};
    }
    if (server_->job_handed_out) {
      response->set_found(false);
      return grpc::Status::OK;
    }
    server_->job_handed_out = true;
    *response = server_->job;
    return grpc::Status::OK;
  }
  grpc::Status FinishJob(grpc::ClientContext*, const v1::FinishJobRequest& request,
                         v1::FinishJobResponse* response) override {
    std::lock_guard lock(server_->mutex);
    server_->finishes.push_back(request);
    response->set_state(v1::Job::SUCCEEDED);
    return grpc::Status::OK;
  }
  grpc::Status FailJob(grpc::ClientContext*, const v1::FailJobRequest& request,
                       v1::FinishJobResponse* response) override {
    std::lock_guard lock(server_->mutex);
    server_->failures.push_back(request);
    response->set_state(v1::Job::FAILED);
    return grpc::Status::OK;
  }
  grpc::Status ReleaseJob(grpc::ClientContext*, const v1::ReleaseJobRequest& request,
                          v1::FinishJobResponse* response) override {
    std::lock_guard lock(server_->mutex);
    server_->releases.push_back(request);
    response->set_state(v1::Job::QUEUED);
    return grpc::Status::OK;
  }

 private:
  grpc::ClientReaderWriterInterface<v1::WorkerReport, v1::ReportAck>* ReportJobRaw(
      grpc::ClientContext*) override {
    std::lock_guard lock(server_->mutex);
    ++server_->report_streams;
    return new FakeReportStream(*server_);
  }
  grpc::ClientWriterInterface<v1::UploadChunk>* UploadResultRaw(grpc::ClientContext*,
                                                                v1::UploadResultResponse* response) override {
    return new FakeUploadWriter(*server_, response);
  }

  // The worker makes no asynchronous calls.
  grpc::ClientAsyncResponseReaderInterface<v1::LeaseJobResponse>* AsyncLeaseJobRaw(
      grpc::ClientContext*, const v1::LeaseJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::LeaseJobResponse>* PrepareAsyncLeaseJobRaw(
      grpc::ClientContext*, const v1::LeaseJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderWriterInterface<v1::WorkerReport, v1::ReportAck>* AsyncReportJobRaw(
      grpc::ClientContext*, grpc::CompletionQueue*, void*) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderWriterInterface<v1::WorkerReport, v1::ReportAck>* PrepareAsyncReportJobRaw(
      grpc::ClientContext*, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncWriterInterface<v1::UploadChunk>* AsyncUploadResultRaw(grpc::ClientContext*,
                                                                          v1::UploadResultResponse*,
                                                                          grpc::CompletionQueue*,
                                                                          void*) override {
    return nullptr;
  }
  grpc::ClientAsyncWriterInterface<v1::UploadChunk>* PrepareAsyncUploadResultRaw(
      grpc::ClientContext*, v1::UploadResultResponse*, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* AsyncFinishJobRaw(
      grpc::ClientContext*, const v1::FinishJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* PrepareAsyncFinishJobRaw(
      grpc::ClientContext*, const v1::FinishJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* AsyncFailJobRaw(
      grpc::ClientContext*, const v1::FailJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* PrepareAsyncFailJobRaw(
      grpc::ClientContext*, const v1::FailJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* AsyncReleaseJobRaw(
      grpc::ClientContext*, const v1::ReleaseJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientAsyncResponseReaderInterface<v1::FinishJobResponse>* PrepareAsyncReleaseJobRaw(
      grpc::ClientContext*, const v1::ReleaseJobRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }
  // The fake's jobs name no uploaded mesh: the worker never fetches one.
  grpc::ClientReaderInterface<v1::MeshChunk>* FetchMeshRaw(grpc::ClientContext*,
                                                           const v1::FetchMeshRequest&) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderInterface<v1::MeshChunk>* AsyncFetchMeshRaw(grpc::ClientContext*,
                                                                     const v1::FetchMeshRequest&,
                                                                     grpc::CompletionQueue*, void*) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderInterface<v1::MeshChunk>* PrepareAsyncFetchMeshRaw(grpc::ClientContext*,
                                                                            const v1::FetchMeshRequest&,
                                                                            grpc::CompletionQueue*) override {
    return nullptr;
  }
  // The fake's jobs are no flow jobs and announce no checkpoint: the worker
  // neither uploads nor fetches one.
  grpc::ClientWriterInterface<v1::CheckpointChunk>* UploadCheckpointRaw(
      grpc::ClientContext*, v1::UploadCheckpointResponse*) override {
    return nullptr;
  }
  grpc::ClientAsyncWriterInterface<v1::CheckpointChunk>* AsyncUploadCheckpointRaw(
      grpc::ClientContext*, v1::UploadCheckpointResponse*, grpc::CompletionQueue*, void*) override {
    return nullptr;
  }
  grpc::ClientAsyncWriterInterface<v1::CheckpointChunk>* PrepareAsyncUploadCheckpointRaw(
      grpc::ClientContext*, v1::UploadCheckpointResponse*, grpc::CompletionQueue*) override {
    return nullptr;
  }
  grpc::ClientReaderInterface<v1::CheckpointChunk>* FetchCheckpointRaw(
      grpc::ClientContext*, const v1::FetchCheckpointRequest&) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderInterface<v1::CheckpointChunk>* AsyncFetchCheckpointRaw(
      grpc::ClientContext*, const v1::FetchCheckpointRequest&, grpc::CompletionQueue*, void*) override {
    return nullptr;
  }
  grpc::ClientAsyncReaderInterface<v1::CheckpointChunk>* PrepareAsyncFetchCheckpointRaw(
      grpc::ClientContext*, const v1::FetchCheckpointRequest&, grpc::CompletionQueue*) override {
    return nullptr;
  }

  std::shared_ptr<FakeServer> server_;
};

class WorkerFakeStubTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scratch_ = fs::temp_directory_path() / ("cellflow_worker_fake_stub_" + std::to_string(::getpid()) + "_" +
                                            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(scratch_);
    server_ = std::make_shared<FakeServer>();
    auto& job = server_->job;
    job.set_found(true);
    job.mutable_lease()->set_job_id("job-1");
    job.mutable_lease()->set_lease_token("lease-token-7f3a");
    job.mutable_lease()->set_attempt(1);
    *job.mutable_spec() = tiny_compression();
    job.set_lease_ttl_s(10.0);
    job.set_heartbeat_interval_s(0.1);
    job.set_last_delivered_sample_index(-1);
  }
  void TearDown() override { fs::remove_all(scratch_); }

  WorkerOptions options() const {
    WorkerOptions options;
    options.server_address = "fake";
    options.name = "fake-stub-test";
    options.scratch_dir = scratch_.string();
    options.lease_wait_s = 0.1;
    options.max_jobs = 1;
    options.threads = 1;
    return options;
  }

  // The worker with the fake as its only stub; runs until its one attempt is over.
  void run_worker(std::int64_t* conversions) {
    Worker worker(options(), std::make_unique<FakeWorkerStub>(server_));
    ASSERT_EQ(worker.run(), 0);
    *conversions = worker.conversions();
    std::lock_guard lock(server_->mutex);
    for (const auto& request : server_->lease_requests) EXPECT_EQ(request.worker_id(), worker.id());
  }

  // The attempt ran to the end: 3 force samples in order, the XDMF sidecar
  // and the HDF5 upload, FinishJob, all under the lease token the fake handed out.
  void expect_job_ran() {
    std::lock_guard lock(server_->mutex);
    const std::string& token = server_->job.lease().lease_token();
    std::vector<int> indices;
    std::int64_t last_report_id = 0;
    for (const auto& report : server_->reports) {
      EXPECT_EQ(report.lease().lease_token(), token);
      EXPECT_EQ(report.lease().job_id(), "job-1");
      if (report.has_heartbeat()) continue;
      EXPECT_GT(report.report_id(), last_report_id);
      last_report_id = report.report_id();
      if (report.has_force_sample()) indices.push_back(report.force_sample().index());
    }
    ASSERT_EQ(indices.size(), 3u);
    for (std::size_t i = 1; i < indices.size(); ++i) EXPECT_GT(indices[i], indices[i - 1]);
    EXPECT_EQ(indices.front(), 0);

    ASSERT_EQ(server_->uploads.size(), 2u);
    const auto& sidecar = server_->uploads.front();
    EXPECT_EQ(sidecar.part, v1::RESULT_PART_XDMF);
    EXPECT_EQ(sidecar.lease.lease_token(), token);
    EXPECT_NE(sidecar.data.find("./job-1.h5:/particles/cell/position/value"), std::string::npos)
        << sidecar.data;
    const auto& upload = server_->uploads.back();
    EXPECT_EQ(upload.part, v1::RESULT_PART_HDF5);
    EXPECT_EQ(upload.lease.lease_token(), token);
    EXPECT_TRUE(upload.offsets_contiguous);
    ASSERT_GE(upload.data.size(), 8u);
    EXPECT_EQ(upload.data.substr(0, 8), std::string("\x89HDF\r\n\x1a\n", 8));

    ASSERT_EQ(server_->finishes.size(), 1u);
    EXPECT_EQ(server_->finishes.front().lease().lease_token(), token);
    EXPECT_EQ(server_->finishes.front().lease().job_id(), "job-1");
    EXPECT_TRUE(server_->failures.empty());
    EXPECT_TRUE(server_->releases.empty());
    EXPECT_GE(server_->report_streams, 1);
  }

  fs::path scratch_;
  std::shared_ptr<FakeServer> server_;
};

TEST_F(WorkerFakeStubTest, RunsOneLeasedJobThroughTheStub) {
  std::int64_t conversions = -1;
  run_worker(&conversions);
  expect_job_ran();
  EXPECT_EQ(conversions, 1);
  std::lock_guard lock(server_->mutex);
  EXPECT_EQ(server_->lease_calls, 1);
}

TEST_F(WorkerFakeStubTest, RetriesLeaseJobWhileTheServerIsUnavailable) {
  server_->unavailable_leases = 2;
  std::int64_t conversions = -1;
  run_worker(&conversions);
  expect_job_ran();
  EXPECT_EQ(conversions, 1);
  std::lock_guard lock(server_->mutex);
  EXPECT_EQ(server_->lease_calls, 3);  // two UNAVAILABLE, then the job
}

// SIGTERM while the LeaseJob poll is in flight (an idle worker of a
// cancelled Slurm job): the lease that still arrives goes straight back with
// ReleaseJob, unrun (no conversion, no report stream), and the worker polls
// no more. Before the fix it ran the attempt, which stopped at once: the job
// went attempt 1 -> 2 for nothing.
TEST_F(WorkerFakeStubTest, StopDuringTheLeasePollHandsTheLeaseBackUnrun) {
  WorkerOptions limits = options();
  limits.max_jobs = 0;  // no limit: only the stop ends the loop
  Worker worker(limits, std::make_unique<FakeWorkerStub>(server_));
  server_->on_lease = [&worker] { worker.stop(); };
  ASSERT_EQ(worker.run(), 0);
  std::lock_guard lock(server_->mutex);
  EXPECT_EQ(server_->lease_calls, 1);
  ASSERT_EQ(server_->releases.size(), 1u);
  EXPECT_EQ(server_->releases.front().lease().lease_token(), server_->job.lease().lease_token());
  EXPECT_EQ(worker.conversions(), 0);
  EXPECT_EQ(server_->report_streams, 0);
  EXPECT_TRUE(server_->reports.empty());
  EXPECT_TRUE(server_->finishes.empty());
  EXPECT_TRUE(server_->failures.empty());
}

// A worker stopped before it polls never calls LeaseJob.
TEST_F(WorkerFakeStubTest, StoppedWorkerNeverLeases) {
  WorkerOptions limits = options();
  limits.max_jobs = 0;
  Worker worker(limits, std::make_unique<FakeWorkerStub>(server_));
  worker.stop();
  ASSERT_EQ(worker.run(), 0);
  std::lock_guard lock(server_->mutex);
  EXPECT_EQ(server_->lease_calls, 0);
  EXPECT_TRUE(server_->releases.empty());
}

}  // namespace
}  // namespace cellflow::worker
