#include "client/rpc_client.h"

#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "rpc/rpc.h"

namespace cellflow::client {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

rpc::ChannelOptions channel_options(const ClientOptions& options) {
  rpc::ChannelOptions channel;
  channel.bearer_token = options.token;
  channel.tls = options.tls;
  channel.tls_ca_pem = options.tls_ca_pem;
  channel.tls_cert_pem = options.tls_cert_pem;
  channel.tls_key_pem = options.tls_key_pem;
  channel.tls_server_name = options.tls_server_name;
  return channel;
}

std::string env(const char* name) {
  const char* value = std::getenv(name);
  return value ? value : "";
}

}  // namespace

std::string load_credentials(const CredentialSources& sources, ClientOptions* options) {
  std::string token_file = sources.token_file;
  if (token_file.empty() && !env("CELLFLOW_TOKEN").empty()) {
    options->token = env("CELLFLOW_TOKEN");
  } else {
    if (token_file.empty() && !env("HOME").empty()) {
      const std::string fallback = env("HOME") + "/.config/cellflow/token";
      std::error_code error;
      if (std::filesystem::exists(fallback, error)) token_file = fallback;
    }
    if (!token_file.empty()) {
      if (Status s = rpc::read_secret_file(token_file, &options->token); !s.ok()) return s.message();
    }
  }
  const bool from_flags = !sources.tls_ca_file.empty() || !sources.tls_cert_file.empty();
  rpc::ChannelOptions channel;
  const Status s = from_flags ? rpc::load_tls_files(sources.tls_ca_file, sources.tls_cert_file,
                                                    sources.tls_key_file, &channel)
                              : rpc::load_tls_files(env("CELLFLOW_TLS_CA"), env("CELLFLOW_TLS_CERT"),
                                                    env("CELLFLOW_TLS_KEY"), &channel);
  if (!s.ok()) return s.message();
  if (channel.tls) {
    options->tls = true;
    options->tls_ca_pem = channel.tls_ca_pem;
    options->tls_cert_pem = channel.tls_cert_pem;
    options->tls_key_pem = channel.tls_key_pem;
  }
  return "";
}

Client::Client(ClientOptions options)
    : Client(options, rpc::make_channel(options.server, channel_options(options))) {}

Client::Client(ClientOptions options, std::shared_ptr<grpc::Channel> channel)
    : options_(std::move(options)),
      channel_(std::move(channel)),
      stub_(v1::CellflowService::NewStub(channel_)) {}

namespace {

// The deadline of each unary call; a timeout_s <= 0 expires at once (as it
// always did), it does not mean "no deadline".
std::chrono::milliseconds call_timeout(const ClientOptions& options) {
  return std::max(std::chrono::milliseconds(1),
                  std::chrono::milliseconds(static_cast<std::int64_t>(options.timeout_s * 1000)));
}

}  // namespace

void Client::set_deadline(grpc::ClientContext& context) const {
  rpc::set_deadline(context, call_timeout(options_));
}

grpc::Status Client::with_retry(const std::function<grpc::Status(grpc::ClientContext&)>& call) const {
  // Only UNAVAILABLE is retried: the call did not reach the service.
  // (SubmitJob is idempotent anyway when it carries a request_id.)
  rpc::RetryOptions retry;
  retry.deadline = call_timeout(options_);
  retry.max_attempts = std::max(1, options_.max_attempts);
  retry.initial_backoff = 250ms;
  retry.max_backoff = 0ms;  // 0.25, 0.5, 1, 2 s, ...
  return rpc::call_with_retry(retry, call);
}

grpc::Status Client::submit(const v1::SubmitJobRequest& request, v1::SubmitJobResponse* response) {
  // The result's author: the spec's, else this user's name ($USER; the server
  // falls back to the token's user when neither is set).
  v1::SubmitJobRequest named = request;
  const char* user = std::getenv("USER");
  if (user == nullptr || *user == '\0') {
    const passwd* entry = ::getpwuid(::getuid());  // a shell without USER: the account's name
    user = entry != nullptr ? entry->pw_name : nullptr;
  }
  if (named.spec().author().empty() && user != nullptr && *user != '\0' && std::strlen(user) <= 256)
    named.mutable_spec()->set_author(user);
  return with_retry([&](grpc::ClientContext& c) { return stub_->SubmitJob(&c, named, response); });
}

grpc::Status Client::get(const std::string& job_id, v1::Job* job) {
  v1::GetJobRequest request;
  request.set_job_id(job_id);
  return with_retry([&](grpc::ClientContext& c) { return stub_->GetJob(&c, request, job); });
}

grpc::Status Client::list(const v1::ListJobsRequest& request, v1::ListJobsResponse* response) {
  return with_retry([&](grpc::ClientContext& c) { return stub_->ListJobs(&c, request, response); });
}

grpc::Status Client::cancel(const std::string& job_id, v1::Job* job) {
  v1::CancelJobRequest request;
  request.set_job_id(job_id);
  return with_retry([&](grpc::ClientContext& c) { return stub_->CancelJob(&c, request, job); });
}

grpc::Status Client::delete_job(const std::string& job_id) {
  v1::DeleteJobRequest request;
  request.set_job_id(job_id);
  v1::DeleteJobResponse response;
  return with_retry([&](grpc::ClientContext& c) { return stub_->DeleteJob(&c, request, &response); });
}

grpc::Status Client::upload_mesh(const std::string& bytes, const std::string& name, v1::MeshRef* ref) {
  // Retried whole while UNAVAILABLE; the server stores a mesh once by its hash.
  return with_retry([&](grpc::ClientContext& c) {
    auto writer = stub_->UploadMesh(&c, ref);
    constexpr std::size_t kChunk = 1 << 20;
    std::size_t offset = 0;
    do {
      v1::MeshChunk chunk;
      if (offset == 0) chunk.set_file_name(name);
      chunk.set_data(bytes.substr(offset, kChunk));
      if (!writer->Write(chunk)) break;
      offset += kChunk;
    } while (offset < bytes.size());
    writer->WritesDone();
    return writer->Finish();
  });
}

grpc::Status Client::watch(const std::string& job_id, std::int64_t after_sequence,
                           const std::function<bool(const v1::JobEvent&)>& on_event) {
  rpc::Backoff backoff(100ms, 2000ms);
  auto unreachable_since = Clock::now();
  while (true) {
    grpc::ClientContext context;
    v1::WatchJobRequest request;
    request.set_job_id(job_id);
    request.set_after_sequence(after_sequence);
    auto reader = stub_->WatchJob(&context, request);
    v1::JobEvent event;
    bool stopped = false;
    while (reader->Read(&event)) {
      unreachable_since = Clock::now();
      backoff.reset();
      after_sequence = event.sequence();
      if (!on_event(event)) {
        stopped = true;
        context.TryCancel();
        break;
      }
    }
    const grpc::Status status = reader->Finish();
    if (stopped) return {grpc::StatusCode::CANCELLED, "stopped by the caller"};
    if (!rpc::retryable(status)) return status;
    if (Clock::now() - unreachable_since >
        std::chrono::milliseconds(static_cast<std::int64_t>(options_.reconnect_s * 1000))) {
      return status;
    }
    std::this_thread::sleep_for(backoff.next());
  }
}

grpc::Status Client::download(const std::string& job_id, const std::string& path, v1::ResultPart part) {
  const std::string partial = path + ".part";
  rpc::Backoff backoff(250ms, 0ms);  // uncapped: 0.25, 0.5, 1 s, ...
  for (int attempt = 1;; ++attempt) {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) return {grpc::StatusCode::INVALID_ARGUMENT, "cannot write " + partial};
    grpc::ClientContext context;
    v1::DownloadResultRequest request;
    request.set_job_id(job_id);
    request.set_part(part);
    auto reader = stub_->DownloadResult(&context, request);
    v1::ResultChunk chunk;
    std::int64_t received = 0;
    std::int64_t total = -1;
    while (reader->Read(&chunk)) {
      if (chunk.offset() != received) {
        context.TryCancel();
        break;
      }
      out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
      received += static_cast<std::int64_t>(chunk.data().size());
      total = chunk.total_size_bytes();
    }
    grpc::Status status = reader->Finish();
    out.close();
    if (status.ok() && total >= 0 && received != total) {
      status = {grpc::StatusCode::DATA_LOSS,
                "received " + std::to_string(received) + " of " + std::to_string(total)};
    }
    if (status.ok()) {
      if (std::rename(partial.c_str(), path.c_str()) != 0)
        return {grpc::StatusCode::INTERNAL, "cannot write " + path};
      return status;
    }
    std::remove(partial.c_str());
    if (!rpc::retryable(status) || attempt >= options_.max_attempts) return status;
    std::this_thread::sleep_for(backoff.next());
  }
}

}  // namespace cellflow::client
