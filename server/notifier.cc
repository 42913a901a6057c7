#include "server/notifier.h"

namespace cellflow::server {

Notifier::Subscription::~Subscription() {
  std::lock_guard lock(notifier_->mutex_);
  if (--entry_->subscribers == 0) notifier_->entries_.erase(job_id_);
}

bool Notifier::Subscription::wait(std::int64_t after_sequence, std::chrono::milliseconds timeout) {
  std::unique_lock lock(notifier_->mutex_);
  entry_->changed.wait_for(lock, timeout,
                           [&] { return entry_->last_sequence > after_sequence || notifier_->shutdown_; });
  return entry_->last_sequence > after_sequence;
}

std::unique_ptr<Notifier::Subscription> Notifier::subscribe(std::int64_t job_id) {
  std::lock_guard lock(mutex_);
  std::shared_ptr<Entry>& entry = entries_[job_id];
  if (!entry) entry = std::make_shared<Entry>();
  ++entry->subscribers;
  return std::make_unique<Subscription>(this, job_id, entry);
}

void Notifier::publish(std::int64_t job_id, std::int64_t sequence) {
  std::lock_guard lock(mutex_);
  auto found = entries_.find(job_id);
  if (found == entries_.end()) return;
  if (sequence > found->second->last_sequence) found->second->last_sequence = sequence;
  found->second->changed.notify_all();
}

std::uint64_t Notifier::queue_generation() {
  std::lock_guard lock(mutex_);
  return queue_generation_;
}

void Notifier::queue_changed() {
  std::lock_guard lock(mutex_);
  ++queue_generation_;
  queue_changed_.notify_all();
}

void Notifier::wait_queue(std::uint64_t seen, std::chrono::steady_clock::time_point deadline) {
  std::unique_lock lock(mutex_);
  queue_changed_.wait_until(lock, deadline, [&] { return queue_generation_ != seen || shutdown_; });
}

void Notifier::shutdown() {
  std::lock_guard lock(mutex_);
  shutdown_ = true;
  queue_changed_.notify_all();
  for (auto& [id, entry] : entries_) entry->changed.notify_all();
}

bool Notifier::shutting_down() {
  std::lock_guard lock(mutex_);
  return shutdown_;
}

}  // namespace cellflow::server
