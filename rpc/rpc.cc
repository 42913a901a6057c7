#include "rpc/rpc.h"

#include <algorithm>
#include <thread>

namespace cellflow::rpc {

using Clock = std::chrono::steady_clock;

grpc::ChannelArguments channel_arguments(const ChannelOptions& options) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, options.max_reconnect_backoff_ms);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, options.initial_reconnect_backoff_ms);
  return args;
}

std::shared_ptr<grpc::Channel> make_channel(const std::string& address, const ChannelOptions& options) {
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), channel_arguments(options));
}

std::chrono::milliseconds seconds_to_ms(double s, std::chrono::milliseconds fallback) {
  return s > 0 ? std::chrono::milliseconds(static_cast<std::int64_t>(s * 1000)) : fallback;
}

void set_deadline(grpc::ClientContext& context, std::chrono::milliseconds timeout) {
  if (timeout.count() > 0) context.set_deadline(std::chrono::system_clock::now() + timeout);
}

bool retryable(const grpc::Status& status) {
  return status.error_code() == grpc::StatusCode::UNAVAILABLE;
}

Backoff::Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max, double multiplier)
    : initial_(initial), max_(max), multiplier_(multiplier), current_(initial) {}

std::chrono::milliseconds Backoff::next() {
  const auto wait = current_;
  current_ = std::chrono::milliseconds(
      static_cast<std::int64_t>(static_cast<double>(current_.count()) * multiplier_));
  if (max_.count() > 0) current_ = std::min(current_, max_);
  return wait;
}

grpc::Status call_with_retry(const RetryOptions& options, const Call& call) {
  const auto first = Clock::now();
  Backoff backoff(options.initial_backoff, options.max_backoff, options.backoff_multiplier);
  grpc::Status status;
  for (int attempt = 1;; ++attempt) {
    grpc::ClientContext context;
    set_deadline(context, options.deadline);
    status = call(context);
    if (status.ok() || !retryable(status)) return status;
    if (options.max_attempts > 0 && attempt >= options.max_attempts) return status;
    if (options.give_up_after.count() > 0 && Clock::now() - first > options.give_up_after) return status;
    std::this_thread::sleep_for(backoff.next());
  }
}

}  // namespace cellflow::rpc
