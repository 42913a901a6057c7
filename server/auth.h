// Authentication of both listeners (see server/README.md, "Authentication").
//
// Tokens: 32 random bytes from /dev/urandom, base64url (43 characters),
// shown once by `cellflow-server token create`; the store keeps only their
// SHA-256 (OpenSSL libcrypto) in the `tokens` table. A call carries
// `authorization: Bearer <token>` metadata.
//
// gRPC 1.51 offers AuthMetadataProcessor only with TLS credentials, so the
// check is a server interceptor that works with and without TLS: on
// POST_RECV_INITIAL_METADATA it looks the token up and records the verdict
// for the call (CallAuth); the handlers (server/grpc_services.cc) read the
// verdict before doing anything, and the interceptor also overrides the
// final status of a refused call (PRE_SEND_STATUS), so a refused call never
// ends with anything but UNAUTHENTICATED or PERMISSION_DENIED.
//
// grpc.health.v1.Health and server reflection stay open (what orchestrators
// probe; reflection describes only the services of its listener).
#pragma once

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/server_interceptor.h>

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

#include "physics/core/status.h"
#include "server/identity.h"
#include "server/store.h"

namespace cellflow::server {

// A fresh token: 32 bytes from /dev/urandom, base64url without padding.
StatusOr<std::string> generate_token();
// Lowercase hex SHA-256 of the token (what the store keeps).
std::string hash_token(std::string_view token);
// User names: 1..64 of [A-Za-z0-9._@-].
bool valid_user_name(const std::string& name);

enum class AuthMode { kToken, kNone };

// What a call may do, decided once per call.
struct Verdict {
  grpc::Status status;  // OK, UNAUTHENTICATED or PERMISSION_DENIED
  Identity identity;    // valid when status is OK
};

// Token checks against the store (and the in-memory secret of the local
// worker pool). Thread-safe; every check reads the store, so a revocation
// takes effect on the next call.
class Authenticator {
 public:
  enum class Api { kPublic, kWorker };
  Authenticator(Store* store, AuthMode mode) : store_(store), mode_(mode) {}
  // The credential of the local worker pool: never stored, only its hash kept.
  void set_local_worker_secret(const std::string& secret) { local_worker_hash_ = hash_token(secret); }
  AuthMode mode() const { return mode_; }
  // `authorization` is the metadata value ("Bearer <token>"), empty if absent.
  Verdict check(Api api, std::string_view authorization) const;

 private:
  Store* store_;
  AuthMode mode_;
  std::string local_worker_hash_;
};

// The verdict of every call in flight on a listener, keyed by its context.
class CallAuth {
 public:
  void record(const grpc::ServerContextBase* context, Verdict verdict);
  void erase(const grpc::ServerContextBase* context);
  // The caller's identity, or the refusal (fails closed: a call without a
  // recorded verdict is UNAUTHENTICATED).
  grpc::Status caller(const grpc::ServerContextBase* context, Identity* identity) const;

 private:
  mutable std::mutex mutex_;
  std::unordered_map<const grpc::ServerContextBase*, Verdict> calls_;
};

// The interceptor factory of one listener.
class AuthInterceptorFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  AuthInterceptorFactory(const Authenticator& authenticator, Authenticator::Api api, CallAuth& calls)
      : authenticator_(authenticator), api_(api), calls_(calls) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(grpc::experimental::ServerRpcInfo* info) override;

 private:
  const Authenticator& authenticator_;
  Authenticator::Api api_;
  CallAuth& calls_;
};

// True for addresses only this host can reach: 127.0.0.0/8, ::1, localhost,
// unix: and unix-abstract: sockets.
bool is_loopback_address(const std::string& address);

}  // namespace cellflow::server
