// The report stream of one attempt: samples and progress as they are
// computed, heartbeats from a timer, acknowledgements back. A report stays
// queued until the server acknowledged it; when the stream breaks (server
// restart, network) the reporter reconnects with the same lease token and
// sends the unacknowledged reports again (the server drops samples it already
// has), for as long as the lease may still be alive. An ack that says the
// lease is gone or the job was cancelled sets the flag the physics polls
// through should_stop.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>

#include "cellflow/v1/worker.grpc.pb.h"

namespace cellflow::worker {

class Reporter {
 public:
  Reporter(v1::WorkerService::StubInterface& stub, v1::Lease lease,
           std::chrono::milliseconds heartbeat_interval, std::chrono::milliseconds lease_ttl);
  ~Reporter();
  Reporter(const Reporter&) = delete;
  Reporter& operator=(const Reporter&) = delete;

  void start();
  // Queues a report (its lease and report_id are set here). Thread-safe.
  void send(v1::WorkerReport report);
  bool cancelled() const { return cancelled_.load(); }
  bool lease_lost() const { return lease_lost_.load(); }
  bool should_stop() const { return cancelled() || lease_lost(); }
  // Waits until every report was acknowledged (or the attempt is over), at
  // most `timeout`, then ends the stream. True if nothing is left unacked.
  bool close(std::chrono::milliseconds timeout);

 private:
  void run();
  bool finished_locked() const;

  v1::WorkerService::StubInterface& stub_;
  v1::Lease lease_;
  std::chrono::milliseconds heartbeat_interval_;
  std::chrono::milliseconds lease_ttl_;

  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<v1::WorkerReport> unacked_;
  std::int64_t next_report_id_ = 1;
  std::int64_t written_up_to_ = 0;  // highest report_id written on the current stream
  bool closing_ = false;
  bool stream_broken_ = false;
  bool thread_done_ = false;
  grpc::ClientContext* context_ = nullptr;  // of the current stream, for cancelling it
  std::chrono::steady_clock::time_point last_contact_;
  std::atomic<bool> cancelled_{false};
  std::atomic<bool> lease_lost_{false};
  std::thread thread_;
};

}  // namespace cellflow::worker
