// A thin client of cellflow.v1.CellflowService for the CLI, the integration
// tests and the benchmark: a deadline on every unary call, retries of
// UNAVAILABLE only (with backoff), and a watch that resumes from the last
// sequence it saw after a broken stream.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "cellflow/v1/service.grpc.pb.h"

namespace cellflow::client {

struct ClientOptions {
  std::string server = "127.0.0.1:50051";
  double timeout_s = 10.0;    // deadline of each unary call
  int max_attempts = 4;       // tries of a call answered UNAVAILABLE
  double reconnect_s = 60.0;  // how long watch/download keep reconnecting
  // Credentials (see load_credentials): the bearer token sent on every call
  // (empty: none), and TLS (on when tls is set; tls_ca_pem empty: the
  // system's roots; cert and key: a client certificate for mTLS).
  std::string token;
  bool tls = false;
  std::string tls_ca_pem, tls_cert_pem, tls_key_pem;
  std::string tls_server_name;  // overrides the name checked against the server's certificate
};

// Where the client finds its credentials: the token from `token_file` if
// given, else CELLFLOW_TOKEN, else ~/.config/cellflow/token if it exists (a
// token file must have mode 0600 or stricter, or it is refused); TLS from
// `tls_ca_file` if given, else CELLFLOW_TLS_CA (and CELLFLOW_TLS_CERT /
// CELLFLOW_TLS_KEY for mTLS). Returns the reason on failure.
struct CredentialSources {
  std::string token_file;
  std::string tls_ca_file, tls_cert_file, tls_key_file;
};
std::string load_credentials(const CredentialSources& sources, ClientOptions* options);

class Client {
 public:
  explicit Client(ClientOptions options);
  Client(ClientOptions options, std::shared_ptr<grpc::Channel> channel);

  // Sets spec.author to $USER when the spec names no author.
  grpc::Status submit(const v1::SubmitJobRequest& request, v1::SubmitJobResponse* response);
  grpc::Status get(const std::string& job_id, v1::Job* job);
  grpc::Status list(const v1::ListJobsRequest& request, v1::ListJobsResponse* response);
  grpc::Status cancel(const std::string& job_id, v1::Job* job);
  // Removes a terminal job (its rows and result file).
  grpc::Status delete_job(const std::string& job_id);
  // Uploads mesh bytes in 1 MiB chunks; *ref gets the hash to put in
  // CellSpec.mesh_sha256. `name` is only named in the server's messages.
  grpc::Status upload_mesh(const std::string& bytes, const std::string& name, v1::MeshRef* ref);
  // Calls on_event for every event after `after_sequence`, in order, until the
  // terminal state event (OK), on_event returns false (CANCELLED) or the
  // server stays unreachable for reconnect_s. Reconnects resume after the
  // last sequence seen, so no event is seen twice.
  grpc::Status watch(const std::string& job_id, std::int64_t after_sequence,
                     const std::function<bool(const v1::JobEvent&)>& on_event);
  // Writes the job's result file (or its XDMF sidecar, which names the file
  // "./job-<n>.h5") to `path` (via path.part, renamed when complete).
  grpc::Status download(const std::string& job_id, const std::string& path,
                        v1::ResultPart part = v1::RESULT_PART_HDF5);

  v1::CellflowService::Stub& stub() { return *stub_; }
  const ClientOptions& options() const { return options_; }

 private:
  void set_deadline(grpc::ClientContext& context) const;
  grpc::Status with_retry(const std::function<grpc::Status(grpc::ClientContext&)>& call) const;

  ClientOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::CellflowService::Stub> stub_;
};

}  // namespace cellflow::client
