// Wakes watchers when a job's event log grows and lease pollers when the
// queue changes: condition variables, no polling. Publishers call after the
// transaction committed; a waiter subscribes before it reads the database,
// so no commit between its read and its wait goes unnoticed.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>

namespace cellflow::server {

class Notifier {
 public:
  struct Entry {
    std::int64_t last_sequence = 0;  // highest sequence published since subscription
    int subscribers = 0;
    std::condition_variable changed;
  };

  // Keeps the job's entry alive while held.
  class Subscription {
   public:
    Subscription(Notifier* notifier, std::int64_t job_id, std::shared_ptr<Entry> entry)
        : notifier_(notifier), job_id_(job_id), entry_(std::move(entry)) {}
    ~Subscription();
    Subscription(const Subscription&) = delete;
    Subscription& operator=(const Subscription&) = delete;

    // Blocks until an event with sequence > after_sequence was published, the
    // timeout passes or the notifier shuts down. True if such an event exists.
    bool wait(std::int64_t after_sequence, std::chrono::milliseconds timeout);

   private:
    Notifier* notifier_;
    std::int64_t job_id_;
    std::shared_ptr<Entry> entry_;
  };

  std::unique_ptr<Subscription> subscribe(std::int64_t job_id);
  void publish(std::int64_t job_id, std::int64_t sequence);

  // Queue changes (a job became QUEUED): a generation counter.
  std::uint64_t queue_generation();
  void queue_changed();
  // Waits until the generation differs from `seen`, the deadline or shutdown.
  void wait_queue(std::uint64_t seen, std::chrono::steady_clock::time_point deadline);

  void shutdown();
  bool shutting_down();

 private:
  std::mutex mutex_;
  std::map<std::int64_t, std::shared_ptr<Entry>> entries_;
  std::uint64_t queue_generation_ = 0;
  std::condition_variable queue_changed_;
  bool shutdown_ = false;
};

}  // namespace cellflow::server
