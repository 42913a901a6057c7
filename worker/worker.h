// cellflow-worker: leases one job at a time from the server, runs it
// (worker/job_runner.h), streams its samples, progress and heartbeats
// (worker/reporter.h), uploads the HDF5 result and finishes the attempt with
// its lease token. It shares nothing with the server but the address. Every
// call to the server goes through one v1::WorkerService::StubInterface: the
// real stub over a channel (rpc/rpc.h) in production, a fake in tests.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "cellflow/v1/worker.grpc.pb.h"
#include "jobs/registry.h"
#include "rpc/rpc.h"

namespace cellflow::worker {

struct WorkerOptions {
  std::string server_address = "127.0.0.1:50051";
  std::string name = "worker";       // worker id = name@host:pid
  std::string scratch_dir;           // where results are written; default: $TMPDIR/cellflow-worker-<pid>
                                     // (removed on exit; those of dead pids are removed at start)
  double lease_wait_s = 10.0;        // long-poll time of one LeaseJob call
  int max_jobs = 0;                  // exit after this many attempts; 0: no limit
  double idle_exit_s = 0.0;          // exit after this long without a job; 0: never
  int threads = 0;                   // OpenMP threads for the physics; 0: default
  int debug_delay_per_point_ms = 0;  // testing aid, see RunOptions
  bool keep_results = false;         // keep the local copy of uploaded results
  // The worker credential (bearer_token) and TLS of the channel to the
  // server's worker listener; see worker/main.cc for where they come from.
  rpc::ChannelOptions channel;
  std::string library_dir;  // fit jobs' curve library; empty: jobs::default_library_dir()
  // Flow jobs: a checkpoint at the first sample step after each interval of
  // wall time, uploaded to the server (UploadCheckpoint); a re-leased attempt
  // resumes from the last one. 0: no checkpoints.
  double checkpoint_interval_s = 300.0;
};

class Worker {
 public:
  // Connects to options.server_address with options.channel:
  // Worker(options, connect(options.server_address, options.channel)).
  explicit Worker(WorkerOptions options);
  // Makes every call through `stub` (which must not be null); options.server_address is
  // then only named in the logs.
  Worker(WorkerOptions options, std::unique_ptr<v1::WorkerService::StubInterface> stub);
  // The production stub: v1::WorkerService::NewStub over rpc::make_channel(address).
  static std::unique_ptr<v1::WorkerService::StubInterface> connect(const std::string& address,
                                                                   const rpc::ChannelOptions& channel = {});

  // Runs until stop() or the max_jobs / idle_exit_s limits; returns the exit code.
  int run();
  // Asks the worker to stop: a running job is handed back to the queue, and
  // no new lease is taken (a LeaseJob poll in flight is cancelled; a lease
  // that still arrives is handed back unrun). Thread-safe.
  void stop();
  const std::string& id() const { return id_; }
  // Spec conversions of this worker so far (one per attempt it ran).
  std::int64_t conversions() const { return registry_.conversions(); }

 private:
  void run_attempt(const v1::LeaseJobResponse& lease);
  // Fills in the bytes of the uploaded mesh the spec names (FetchMesh);
  // refuses a spec that names a file of this machine.
  Status fetch_mesh(v1::JobSpec& spec, const v1::Lease& lease);
  // One cell's uploaded mesh (field: its path in the spec, "suspension.cells[1].cell.").
  Status fetch_cell_mesh(v1::CellSpec* cell, const std::string& field, const v1::Lease& lease);
  // Removes the scratch directories of workers that are gone (default location only).
  void remove_stale_scratch();
  bool sleep_unless_stopped(std::chrono::milliseconds duration);
  // ReleaseJob for a lease this worker will not finish; true if the server took it.
  bool hand_back(const v1::Lease& lease);

  WorkerOptions options_;
  std::string id_;
  std::unique_ptr<v1::WorkerService::StubInterface> stub_;
  jobs::SceneRegistry registry_;
  std::atomic<bool> stop_{false};
  std::mutex lease_call_mutex_;
  grpc::ClientContext* lease_call_ = nullptr;  // the LeaseJob poll in flight, for stop()
  bool own_scratch_ = false;                   // the default per-pid scratch directory: removed on exit
};

}  // namespace cellflow::worker
