#include "worker/reporter.h"

#include <spdlog/spdlog.h>

#include <vector>

#include "rpc/rpc.h"

namespace cellflow::worker {

using Clock = std::chrono::steady_clock;

Reporter::Reporter(v1::WorkerService::StubInterface& stub, v1::Lease lease,
                   std::chrono::milliseconds heartbeat_interval, std::chrono::milliseconds lease_ttl)
    : stub_(stub), lease_(std::move(lease)), heartbeat_interval_(heartbeat_interval), lease_ttl_(lease_ttl) {}

Reporter::~Reporter() {
  close(std::chrono::milliseconds(0));
}

void Reporter::start() {
  last_contact_ = Clock::now();
  thread_ = std::thread([this] { run(); });
}

void Reporter::send(v1::WorkerReport report) {
  std::lock_guard lock(mutex_);
  *report.mutable_lease() = lease_;
  report.set_report_id(next_report_id_++);
  unacked_.push_back(std::move(report));
  changed_.notify_all();
}

bool Reporter::finished_locked() const {
  return (closing_ && unacked_.empty()) || cancelled_.load() || lease_lost_.load();
}

bool Reporter::close(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  closing_ = true;
  changed_.notify_all();
  if (!changed_.wait_for(lock, timeout, [&] { return thread_done_ || !thread_.joinable(); })) {
    // Out of time: abandon what is unacknowledged.
    if (context_ != nullptr) context_->TryCancel();
    lease_lost_ = true;
    changed_.notify_all();
  }
  const bool all_acked = unacked_.empty();
  lock.unlock();
  if (thread_.joinable()) thread_.join();
  return all_acked;
}

void Reporter::run() {
  rpc::Backoff backoff(std::chrono::milliseconds(100), std::chrono::milliseconds(2000));
  while (true) {
    {
      std::lock_guard lock(mutex_);
      if (finished_locked()) break;
      written_up_to_ = 0;  // a new stream: everything unacknowledged goes again
      stream_broken_ = false;
    }
    grpc::ClientContext context;
    {
      std::lock_guard lock(mutex_);
      context_ = &context;
    }
    auto stream = stub_.ReportJob(&context);

    std::thread reader([&] {
      v1::ReportAck ack;
      while (stream->Read(&ack)) {
        std::lock_guard lock(mutex_);
        last_contact_ = Clock::now();
        if (!ack.lease_valid()) (ack.cancelled() ? cancelled_ : lease_lost_) = true;
        if (!ack.error().empty())
          spdlog::warn("{}: the server refused report {}: {}", lease_.job_id(), ack.report_id(), ack.error());
        if (ack.report_id() > 0) {
          while (!unacked_.empty() && unacked_.front().report_id() <= ack.report_id()) unacked_.pop_front();
        }
        changed_.notify_all();
      }
      std::lock_guard lock(mutex_);
      stream_broken_ = true;
      changed_.notify_all();
    });

    auto next_heartbeat = Clock::now();
    bool writes_done = false;
    while (true) {
      std::vector<v1::WorkerReport> batch;
      bool heartbeat = false;
      {
        std::unique_lock lock(mutex_);
        auto has_unwritten = [&] {
          return !unacked_.empty() && unacked_.back().report_id() > written_up_to_;
        };
        changed_.wait_until(lock, next_heartbeat,
                            [&] { return stream_broken_ || finished_locked() || has_unwritten(); });
        if (stream_broken_ || finished_locked()) break;
        for (const auto& report : unacked_) {
          if (report.report_id() > written_up_to_) batch.push_back(report);
        }
        if (!batch.empty()) written_up_to_ = batch.back().report_id();
        if (Clock::now() >= next_heartbeat) {
          heartbeat = true;
          next_heartbeat = Clock::now() + heartbeat_interval_;
        }
      }
      bool ok = true;
      for (const auto& report : batch) {
        if (!(ok = stream->Write(report))) break;
      }
      if (ok && heartbeat) {
        v1::WorkerReport beat;
        *beat.mutable_lease() = lease_;
        beat.mutable_heartbeat();
        ok = stream->Write(beat);
      }
      if (!ok) break;
    }
    {
      std::lock_guard lock(mutex_);
      // Closing with everything acknowledged: end the stream politely; the
      // server's handler returns and the reader sees the end.
      writes_done = closing_ && unacked_.empty() && !stream_broken_;
    }
    if (writes_done) {
      stream->WritesDone();
    } else {
      context.TryCancel();
    }
    reader.join();
    const grpc::Status status = stream->Finish();
    {
      std::lock_guard lock(mutex_);
      context_ = nullptr;
      if (finished_locked()) break;
      if (Clock::now() - last_contact_ > lease_ttl_) {
        spdlog::warn("{}: no contact with the server for longer than the lease; giving the attempt up",
                     lease_.job_id());
        lease_lost_ = true;
        break;
      }
    }
    spdlog::warn("{}: report stream broke ({}); reconnecting", lease_.job_id(), status.error_message());
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, backoff.next(), [&] { return finished_locked(); });
  }
  std::lock_guard lock(mutex_);
  thread_done_ = true;
  changed_.notify_all();
}

}  // namespace cellflow::worker
