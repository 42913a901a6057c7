// The logic of both gRPC services, free of gRPC: validation, idempotent
// submission, paging, cancellation, the watch loop, leasing, fenced worker
// reports and result files. The gRPC handlers (server/grpc_services.h) only
// translate messages and status codes.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/worker.pb.h"
#include "jobs/registry.h"
#include "jobs/study/study.h"
#include "physics/core/status.h"
#include "server/identity.h"
#include "server/mesh_store.h"
#include "server/notifier.h"
#include "server/store.h"

namespace cellflow::server {

struct JobServiceOptions {
  std::filesystem::path data_dir;       // database and results/
  std::int64_t memory_limit_bytes = 0;  // refuse larger jobs; 0: no limit
  double lease_ttl_s = 10.0;            // a lease not renewed for this long expires
  double heartbeat_interval_s = 0.25;   // what workers are told; bounds the cancel latency
  int default_page_size = 50;
  int max_page_size = 1000;
  int max_request_id_length = 128;
  std::size_t download_chunk_bytes = 1 << 20;  // < the 4 MiB gRPC message limit
  std::function<std::int64_t()> now_ms;        // the clock; unset: system clock
  // Hostile input. Uploaded meshes at most this large (MeshStore).
  std::uint64_t max_mesh_bytes = std::uint64_t{64} << 20;
  std::size_t max_name_bytes = 1024;    // JobSpec.name at submit
  std::size_t max_reason_bytes = 4096;  // FailJob/ReleaseJob reasons and progress stages (truncated)
  // A result upload may be at most this multiple of the job's memory estimate
  // plus upload_slack_bytes (a result holds a fraction of what the run keeps).
  double upload_memory_factor = 4.0;
  std::int64_t upload_slack_bytes = 64LL << 20;
  double max_run_time_s = 0.0;                   // > 0: an attempt leased longer ago loses its lease
  int max_study_points = jobs::kMaxStudyPoints;  // children of one study (SubmitJob of a StudySpec)
  // A checkpoint upload may be at most this large; 0: the result upload's
  // limit (upload_memory_factor x the job's memory estimate + upload_slack_bytes;
  // a flow checkpoint holds the lattice populations, below the estimate).
  std::int64_t max_checkpoint_bytes = 0;
  // Library simulations one fit may need (its keys x the w grid); more is RESOURCE_EXHAUSTED.
  int max_fit_library_children = 2000;
};

// Valid UTF-8 of at most max_bytes: invalid sequences become U+FFFD, the end
// is cut at a character boundary (with "..." when cut).
std::string sanitize_text(const std::string& text, std::size_t max_bytes);

// A result file being uploaded by a worker, written under a temporary name
// per attempt; it becomes the job's result only on a fenced FinishJob/FailJob.
class ResultUpload {
 public:
  ResultUpload(std::filesystem::path path, int fd, std::int64_t max_bytes = 0)
      : path_(std::move(path)), fd_(fd), max_bytes_(max_bytes) {}
  ~ResultUpload();
  ResultUpload(const ResultUpload&) = delete;
  ResultUpload& operator=(const ResultUpload&) = delete;
  Status write(std::int64_t offset, const std::string& data);
  // Syncs and closes; the file stays until the attempt ends.
  StatusOr<std::int64_t> complete();

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::int64_t size_ = 0;
  std::int64_t max_bytes_ = 0;  // > 0: a write past it is refused (RESOURCE_EXHAUSTED)
  bool completed_ = false;
};

class JobService {
 public:
  JobService(Store& store, Notifier& notifier, JobServiceOptions options);

  // --- public API ---
  // Each call acts for `caller`: a job belongs to the identity that submitted
  // it, and another user's job is kNotFound (as if it did not exist) unless
  // the caller is an admin. The default is the single local admin of
  // `--auth none`.
  StatusOr<v1::SubmitJobResponse> submit(const v1::SubmitJobRequest& request,
                                         const Identity& caller = Identity::local());
  StatusOr<v1::Job> get(const std::string& job_id, const Identity& caller = Identity::local());
  StatusOr<v1::ListJobsResponse> list(const v1::ListJobsRequest& request,
                                      const Identity& caller = Identity::local());
  StatusOr<v1::Job> cancel(const std::string& job_id, const Identity& caller = Identity::local());
  // Sends the events after request.after_sequence, then follows live until
  // the terminal state event was sent (OK), `send` returns false or
  // `client_gone` returns true (kCancelled), or the service shuts down.
  Status watch(const v1::WatchJobRequest& request, const std::function<bool(const v1::JobEvent&)>& send,
               const std::function<bool()>& client_gone, const Identity& caller = Identity::local());
  // Sends `part` of the job's result: the HDF5 file or its XDMF sidecar.
  Status download(const std::string& job_id, const std::function<bool(const v1::ResultChunk&)>& send,
                  const Identity& caller = Identity::local(), v1::ResultPart part = v1::RESULT_PART_HDF5);
  // A whole mesh upload (the handler collects the chunks up to max_mesh_bytes).
  StatusOr<v1::MeshRef> upload_mesh(const std::string& bytes, const std::string& name);
  Status delete_job(const std::string& job_id, const Identity& caller = Identity::local());

  // --- worker API ---
  StatusOr<v1::LeaseJobResponse> lease(const v1::LeaseJobRequest& request,
                                       const std::function<bool()>& client_gone);
  StatusOr<v1::ReportAck> report(const v1::WorkerReport& report);
  // An upload of `part` of the attempt's result; the XDMF sidecar is at most
  // kMaxXdmfBytes and becomes the job's with the HDF5 file (finish, fail).
  StatusOr<std::unique_ptr<ResultUpload>> begin_upload(const v1::Lease& lease,
                                                       v1::ResultPart part = v1::RESULT_PART_HDF5);
  static constexpr std::int64_t kMaxXdmfBytes = 16LL << 20;
  StatusOr<v1::FinishJobResponse> finish(const v1::FinishJobRequest& request);
  StatusOr<v1::FinishJobResponse> fail(const v1::FailJobRequest& request);
  StatusOr<v1::FinishJobResponse> release(const v1::ReleaseJobRequest& request);
  // The bytes of a mesh the leased job's spec names, in chunks.
  Status fetch_mesh(const v1::FetchMeshRequest& request,
                    const std::function<bool(const v1::MeshChunk&)>& send);
  // Checkpoints of running flow jobs (server/job_service_checkpoints.cc):
  // an upload under a per-attempt temporary name, bounded; committed (fenced)
  // it replaces checkpoints/job-N.ckpt atomically.
  StatusOr<std::unique_ptr<ResultUpload>> begin_checkpoint_upload(const v1::Lease& lease);
  StatusOr<std::int64_t> commit_checkpoint(const v1::Lease& lease, const v1::CheckpointInfo& info,
                                           ResultUpload& upload);
  Status fetch_checkpoint(const v1::FetchCheckpointRequest& request,
                          const std::function<bool(const v1::CheckpointChunk&)>& send);
  std::filesystem::path checkpoint_path(std::int64_t job_id) const;

  // --- housekeeping (the server's Asio timers and shutdown) ---
  // Requeues or fails jobs whose lease expired; returns how many changed.
  int reap_expired_leases();
  // Draining: SubmitJob and LeaseJob refuse new work; running jobs go on.
  void set_draining(bool draining);
  bool draining() const { return draining_.load(); }
  // Every RUNNING job back to QUEUED (shutdown after the grace period).
  int release_all_running(const std::string& reason);
  std::int64_t running_jobs() { return store_.count(v1::Job::RUNNING); }
  std::int64_t queued_jobs() { return store_.count(v1::Job::QUEUED); }
  // Workers waiting in LeaseJob right now: free workers (the Slurm executor
  // submits more only when there are none; server/slurm_executor.h).
  int waiting_workers() const { return waiting_workers_.load(); }
  // Removes every result upload (results/*.part) that no attempt can still
  // finish: at server start and at shutdown.
  int remove_all_uploads();
  const MeshStore& meshes() const { return meshes_; }

  std::filesystem::path result_path(std::int64_t job_id, v1::ResultPart part = v1::RESULT_PART_HDF5) const;
  const JobServiceOptions& options() const { return options_; }
  // Spec conversions made at submit so far (one per submitted spec).
  std::int64_t spec_conversions() const { return registry_.conversions(); }

 private:
  std::int64_t now() const { return options_.now_ms(); }
  // SubmitJob of a study: expands it, validates and memory-checks every
  // child, then queues the study and its children in one transaction.
  StatusOr<v1::SubmitJobResponse> submit_study(const v1::SubmitJobRequest& request, const Identity& caller);
  // A fit's library curves as child-job candidates (jobs/fit/fit_library.h),
  // each prepared like a submitted job (its memory estimate); none for Hertz.
  StatusOr<std::vector<Store::LibraryChild>> library_children(const v1::JobSpec& spec);
  // The stored curves of a leased fit's keys into its spec (FitSpec.server_library).
  void attach_library(const v1::Job& job, v1::FitSpec& fit);
  std::int64_t ttl_ms() const { return static_cast<std::int64_t>(options_.lease_ttl_s * 1000.0); }
  std::filesystem::path upload_path(const v1::Lease& lease, v1::ResultPart part = v1::RESULT_PART_HDF5) const;
  // Moves the attempt's upload (if any) into place as the job's result.
  StatusOr<std::int64_t> adopt_upload(const v1::Lease& lease, std::int64_t job_id);
  void published(const v1::Job& job);
  // kNotFound unless `caller` may see job `id`.
  Status check_visible(std::int64_t id, const Identity& caller);
  // Refuses what a server job may not carry (a mesh_file path, inline mesh
  // bytes, an oversized name), then fills in the bytes of mesh_sha256 from
  // the mesh store and prepares the spec.
  StatusOr<std::unique_ptr<jobs::PreparedJob>> prepare_submitted(const v1::JobSpec& spec);
  // The highest sample index the job can report (cached per job); < 0: unknown.
  std::int64_t max_sample_index(std::int64_t job_id);
  // Removes the uploads of every attempt of the job (after its lease is gone).
  void remove_uploads(std::int64_t job_id);
  std::filesystem::path checkpoint_upload_path(const v1::Lease& lease) const;
  // LeaseJobResponse.checkpoint from the job's record, if its file is there.
  void describe_checkpoint(std::int64_t job_id, v1::LeaseJobResponse& response);
  // The job's checkpoint file, its record and any checkpoint upload (a terminal or deleted job).
  void remove_checkpoint(std::int64_t job_id);

  Store& store_;
  Notifier& notifier_;
  JobServiceOptions options_;
  jobs::SceneRegistry registry_;  // converts and validates each submitted spec once
  std::atomic<bool> draining_{false};
  std::atomic<int> waiting_workers_{0};
  MeshStore meshes_;
  std::mutex sample_bounds_mutex_;
  std::map<std::int64_t, std::int64_t> sample_bounds_;  // job id -> max_sample_index
};

// Opaque page tokens: the last id of the page and the filters, base64url.
std::string encode_page_token(std::int64_t after_id, v1::Job::State state, std::int64_t parent_id = 0);
StatusOr<std::int64_t> decode_page_token(const std::string& token, v1::Job::State state,
                                         std::int64_t parent_id = 0);

}  // namespace cellflow::server
