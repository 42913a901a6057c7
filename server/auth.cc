#include "server/auth.h"

#include <cctype>
#include <cstdio>
#include <fstream>

#include "server/encoding.h"

namespace cellflow::server {

namespace {

bool starts_with(std::string_view s, std::string_view prefix) {
  return s.substr(0, prefix.size()) == prefix;
}

// Methods that need no token: health checks and reflection.
bool open_method(const char* method) {
  const std::string_view m = method ? method : "";
  return starts_with(m, "/grpc.health.v1.Health/") || starts_with(m, "/grpc.reflection.");
}

class AuthInterceptor final : public grpc::experimental::Interceptor {
 public:
  AuthInterceptor(grpc::experimental::ServerRpcInfo* info, const Authenticator& authenticator,
                  Authenticator::Api api, CallAuth& calls)
      : info_(info), authenticator_(authenticator), api_(api), calls_(calls) {}
  ~AuthInterceptor() override {
    if (recorded_) calls_.erase(info_->server_context());
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    using grpc::experimental::InterceptionHookPoints;
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      Verdict verdict;
      if (open_method(info_->method())) {
        verdict.identity = Identity{"", false, false};
      } else {
        std::string_view authorization;
        if (auto* metadata = methods->GetRecvInitialMetadata()) {
          auto it = metadata->find("authorization");
          if (it != metadata->end()) authorization = std::string_view(it->second.data(), it->second.size());
        }
        verdict = authenticator_.check(api_, authorization);
      }
      refusal_ = verdict.status;
      calls_.record(info_->server_context(), std::move(verdict));
      recorded_ = true;
    }
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS) && !refusal_.ok()) {
      methods->ModifySendStatus(refusal_);
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  const Authenticator& authenticator_;
  Authenticator::Api api_;
  CallAuth& calls_;
  grpc::Status refusal_;
  bool recorded_ = false;
};

}  // namespace

StatusOr<std::string> generate_token() {
  unsigned char bytes[32];
  std::ifstream in("/dev/urandom", std::ios::binary);
  if (!in.read(reinterpret_cast<char*>(bytes), sizeof bytes)) {
    return Status(StatusCode::kInternal, "cannot read 32 bytes from /dev/urandom");
  }
  return base64url(std::string_view(reinterpret_cast<const char*>(bytes), sizeof bytes));
}

std::string hash_token(std::string_view token) {
  return sha256_hex(token);
}

bool valid_user_name(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-' && c != '@')
      return false;
  }
  return true;
}

Verdict Authenticator::check(Api api, std::string_view authorization) const {
  Verdict verdict;
  if (mode_ == AuthMode::kNone) {
    verdict.identity = api == Api::kWorker ? Identity{"local-worker", false, true} : Identity::local();
    return verdict;
  }
  const char* hint =
      api == Api::kPublic
          ? " (the client reads it from CELLFLOW_TOKEN, --token-file or ~/.config/cellflow/token)"
          : " (the worker reads it from CELLFLOW_WORKER_TOKEN or --token-file)";
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.empty()) {
    verdict.status = {grpc::StatusCode::UNAUTHENTICATED,
                      std::string("no credentials: send authorization: Bearer <token>") + hint};
    return verdict;
  }
  if (!starts_with(authorization, kBearer) || authorization.size() == kBearer.size()) {
    verdict.status = {grpc::StatusCode::UNAUTHENTICATED, "authorization metadata is not \"Bearer <token>\""};
    return verdict;
  }
  const std::string hash = hash_token(authorization.substr(kBearer.size()));
  if (api == Api::kWorker && !local_worker_hash_.empty() && hash == local_worker_hash_) {
    verdict.identity = Identity{"local-worker", false, true};
    return verdict;
  }
  auto token = store_->find_token(hash);
  if (!token.ok()) {
    verdict.status = {grpc::StatusCode::INTERNAL, token.status().to_string()};
    return verdict;
  }
  if (!token->has_value()) {
    verdict.status = {grpc::StatusCode::UNAUTHENTICATED, "unknown token"};
    return verdict;
  }
  const TokenRecord& record = **token;
  if (record.revoked()) {
    verdict.status = {grpc::StatusCode::UNAUTHENTICATED, "token revoked"};
    return verdict;
  }
  const bool is_worker = record.role == "worker";
  if (api == Api::kPublic && is_worker) {
    verdict.status = {grpc::StatusCode::PERMISSION_DENIED, "a worker token cannot call the public API"};
    return verdict;
  }
  if (api == Api::kWorker && !is_worker) {
    verdict.status = {grpc::StatusCode::PERMISSION_DENIED,
                      "a user token cannot call the worker API (create one with token create --worker)"};
    return verdict;
  }
  verdict.identity = Identity{record.user, record.role == "admin", is_worker};
  return verdict;
}

void CallAuth::record(const grpc::ServerContextBase* context, Verdict verdict) {
  std::lock_guard lock(mutex_);
  calls_[context] = std::move(verdict);
}

void CallAuth::erase(const grpc::ServerContextBase* context) {
  std::lock_guard lock(mutex_);
  calls_.erase(context);
}

grpc::Status CallAuth::caller(const grpc::ServerContextBase* context, Identity* identity) const {
  std::lock_guard lock(mutex_);
  auto it = calls_.find(context);
  if (it == calls_.end()) return {grpc::StatusCode::UNAUTHENTICATED, "the call was not authenticated"};
  if (!it->second.status.ok()) return it->second.status;
  *identity = it->second.identity;
  return grpc::Status::OK;
}

grpc::experimental::Interceptor* AuthInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  return new AuthInterceptor(info, authenticator_, api_, calls_);
}

bool is_loopback_address(const std::string& address) {
  if (starts_with(address, "unix:") || starts_with(address, "unix-abstract:")) return true;
  std::string host = address;
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    host = close == std::string::npos ? host : host.substr(1, close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos && host.find(':') == colon) {
    host = host.substr(0, colon);  // host:port (a bare IPv6 address keeps its colons)
  }
  if (host == "localhost" || host == "::1") return true;
  if (starts_with(host, "127.")) {
    int a = 0, b = 0, c = 0, d = 0;
    char tail = 0;
    return std::sscanf(host.c_str(), "%d.%d.%d.%d%c", &a, &b, &c, &d, &tail) == 4 && b >= 0 && b < 256 &&
           c >= 0 && c < 256 && d >= 0 && d < 256;
  }
  return false;
}

}  // namespace cellflow::server
