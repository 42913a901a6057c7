#include "rpc/rpc.h"

#include <grpcpp/support/client_interceptor.h>
#include <sys/stat.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <thread>

namespace cellflow::rpc {

using Clock = std::chrono::steady_clock;

grpc::ChannelArguments channel_arguments(const ChannelOptions& options) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, options.max_reconnect_backoff_ms);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, options.initial_reconnect_backoff_ms);
  return args;
}

namespace {

// Adds the bearer token to the initial metadata of every call.
class BearerInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit BearerInterceptor(const std::string* header) : header_(header) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      methods->GetSendInitialMetadata()->emplace("authorization", *header_);
    }
    methods->Proceed();
  }

 private:
  const std::string* header_;
};

class BearerInterceptorFactory final : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit BearerInterceptorFactory(const std::string& token) : header_("Bearer " + token) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(grpc::experimental::ClientRpcInfo*) override {
    return new BearerInterceptor(&header_);
  }

 private:
  std::string header_;
};

}  // namespace

std::shared_ptr<grpc::Channel> make_channel(const std::string& address, const ChannelOptions& options) {
  grpc::ChannelArguments args = channel_arguments(options);
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.tls) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = options.tls_ca_pem;
    ssl.pem_cert_chain = options.tls_cert_pem;
    ssl.pem_private_key = options.tls_key_pem;
    credentials = grpc::SslCredentials(ssl);
    if (!options.tls_server_name.empty()) args.SetSslTargetNameOverride(options.tls_server_name);
  } else {
    credentials = grpc::InsecureChannelCredentials();
  }
  if (options.bearer_token.empty()) return grpc::CreateCustomChannel(address, credentials, args);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(std::make_unique<BearerInterceptorFactory>(options.bearer_token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(address, credentials, args,
                                                                 std::move(interceptors));
}

cellflow::Status read_file(const std::string& path, std::string* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {cellflow::StatusCode::kInvalidArgument, "cannot read " + path};
  std::stringstream text;
  text << in.rdbuf();
  *out = text.str();
  return {};
}

cellflow::Status read_secret_file(const std::string& path, std::string* out) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {cellflow::StatusCode::kInvalidArgument, "cannot read " + path};
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return {cellflow::StatusCode::kInvalidArgument,
            "refusing token file " + path + ": mode " + mode + " lets others read it; run chmod 600 " + path};
  }
  std::string text;
  if (cellflow::Status s = read_file(path, &text); !s.ok()) return s;
  const auto begin = text.find_first_not_of(" \t\r\n");
  const auto end = text.find_last_not_of(" \t\r\n");
  if (begin == std::string::npos) return {cellflow::StatusCode::kInvalidArgument, path + " is empty"};
  *out = text.substr(begin, end - begin + 1);
  return {};
}

cellflow::Status load_tls_files(const std::string& ca_file, const std::string& cert_file,
                                const std::string& key_file, ChannelOptions* options) {
  if (cert_file.empty() != key_file.empty()) {
    return {cellflow::StatusCode::kInvalidArgument,
            "a client certificate needs both --tls-cert and --tls-key"};
  }
  if (!ca_file.empty()) {
    if (cellflow::Status s = read_file(ca_file, &options->tls_ca_pem); !s.ok()) return s;
    options->tls = true;
  }
  if (!cert_file.empty()) {
    if (cellflow::Status s = read_file(cert_file, &options->tls_cert_pem); !s.ok()) return s;
    if (cellflow::Status s = read_file(key_file, &options->tls_key_pem); !s.ok()) return s;
    options->tls = true;
  }
  return {};
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
