// RPC plumbing shared by the client (client/rpc_client.h) and the worker
// (worker/worker.h): one way to open a channel to the server, a deadline on
// every call, and one retry loop for calls answered UNAVAILABLE (the only
// status that says the call did not reach the service, so it is safe to try
// again), with an exponential backoff between the tries.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "physics/core/status.h"

namespace cellflow::rpc {

// Channel arguments of every channel to the server, and its credentials.
struct ChannelOptions {
  // gRPC's reconnect backoff after a broken connection: starts at the initial
  // value and is capped at the max (gRPC's own defaults are 1 s and 120 s);
  // small values let the client and the worker reconnect quickly after a
  // server restart.
  int initial_reconnect_backoff_ms = 100;
  int max_reconnect_backoff_ms = 1000;

  // Sent as `authorization: Bearer <token>` on every call (a client
  // interceptor, so it works over TLS and over plaintext loopback); empty:
  // no token.
  std::string bearer_token;
  // TLS: on when `tls` is set. The server's certificate is checked against
  // tls_ca_pem (empty: the system's roots); tls_cert_pem and tls_key_pem are
  // the client certificate for mTLS (both or neither); tls_server_name
  // overrides the name checked against the certificate (default: the host
  // of the address).
  bool tls = false;
  std::string tls_ca_pem;
  std::string tls_cert_pem;
  std::string tls_key_pem;
  std::string tls_server_name;
};

grpc::ChannelArguments channel_arguments(const ChannelOptions& options = {});
// A channel to `address` (host:port, unix:PATH) with the arguments and
// credentials above: TLS when options.tls, plaintext otherwise.
std::shared_ptr<grpc::Channel> make_channel(const std::string& address, const ChannelOptions& options = {});

// Reads a whole file (a PEM certificate, say) into *out.
cellflow::Status read_file(const std::string& path, std::string* out);
// Reads a secret (a token) from `path`, trimmed of surrounding whitespace.
// Refuses a file that its group or others may read or write (mode must be
// 0600 or stricter) and an empty one.
cellflow::Status read_secret_file(const std::string& path, std::string* out);
// Fills the TLS fields from files: a CA file turns TLS on; cert and key
// (both or neither) add a client certificate. Empty paths are skipped.
cellflow::Status load_tls_files(const std::string& ca_file, const std::string& cert_file,
                                const std::string& key_file, ChannelOptions* options);

// Seconds (as in the options and the protos) to milliseconds; `fallback` for s <= 0.
std::chrono::milliseconds seconds_to_ms(double s, std::chrono::milliseconds fallback);
// Sets the deadline of a call `timeout` from now; timeout <= 0 sets none.
void set_deadline(grpc::ClientContext& context, std::chrono::milliseconds timeout);

// True only for UNAVAILABLE.
bool retryable(const grpc::Status& status);

// Waits between tries: `initial`, then multiplied by `multiplier` after each
// wait, capped at `max` (max <= 0: no cap).
class Backoff {
 public:
  Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max, double multiplier = 2.0);
  // The wait to use now; the following one grows.
  std::chrono::milliseconds next();
  // Back to the initial wait (after a success).
  void reset() { current_ = initial_; }

 private:
  std::chrono::milliseconds initial_;
  std::chrono::milliseconds max_;
  double multiplier_;
  std::chrono::milliseconds current_;
};

// How call_with_retry tries a call. The defaults are the client's
// (ClientOptions: 10 s per call, 4 tries, waits of 0.25, 0.5, 1 s).
struct RetryOptions {
  std::chrono::milliseconds deadline{10000};       // of each try; <= 0: none
  int max_attempts = 4;                            // tries in all; <= 0: no limit
  std::chrono::milliseconds give_up_after{0};      // no new try once this long has passed since
                                                   // the first began; <= 0: no limit
  std::chrono::milliseconds initial_backoff{250};  // wait after the first UNAVAILABLE
  std::chrono::milliseconds max_backoff{0};        // cap of the wait; <= 0: no cap
  double backoff_multiplier = 2.0;                 // growth of the wait per try
};

using Call = std::function<grpc::Status(grpc::ClientContext&)>;

// Calls `call` with a fresh context (deadline set) until it succeeds, fails
// with a status other than UNAVAILABLE, or the tries (max_attempts) or the
// time (give_up_after) are used up; returns the last status. Sleeps between
// the tries per the backoff.
grpc::Status call_with_retry(const RetryOptions& options, const Call& call);

}  // namespace cellflow::rpc
