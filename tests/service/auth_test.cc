// Authentication and isolation on loopback with the real server, workers and
// SQLite (server/README.md, "Authentication"): per-user tokens from
// `cellflow-server token create`, jobs visible only to their owner (and to
// admins), UNAUTHENTICATED without a valid token, the worker API only on its
// own listener with a worker credential, and TLS from certificate files made
// here with Debian's openssl.
#include <sys/stat.h>

#include "cellflow/v1/worker.grpc.pb.h"
#include "rpc/rpc.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

class AuthTest : public ServiceTest {
 protected:
  std::unique_ptr<client::Client> client_with(const std::string& token, int max_attempts = 1) {
    client::ClientOptions options = client_options(token);
    options.max_attempts = max_attempts;
    options.timeout_s = 5;
    options.reconnect_s = 0;
    return std::make_unique<client::Client>(options);
  }

  std::unique_ptr<v1::WorkerService::Stub> worker_stub(const std::string& address, const std::string& token) {
    rpc::ChannelOptions channel;
    channel.bearer_token = token;
    return v1::WorkerService::NewStub(rpc::make_channel(address, channel));
  }

  grpc::Status lease(v1::WorkerService::Stub& stub, v1::LeaseJobResponse* response) {
    v1::LeaseJobRequest request;
    request.set_worker_id("auth-test");
    request.set_wait_s(0);
    grpc::ClientContext context;
    rpc::set_deadline(context, 5s);
    return stub.LeaseJob(&context, request, response);
  }

  grpc::Status watch_status(client::Client& client, const std::string& id) {
    return client.watch(id, 0, [](const v1::JobEvent&) { return true; });
  }

  std::string server_command() const { return std::string(CELLFLOW_SERVER_EXE) + " "; }
  std::string data_dir() const { return (dir_ / "data").string(); }
};

TEST_F(AuthTest, UsersSeeOnlyTheirOwnJobsAndAnAdminSeesAll) {
  start_server(1);
  const std::string bob_token = create_token("bob");
  const std::string admin_token = create_token("root", "--admin");
  auto bob = client_with(bob_token);
  auto admin = client_with(admin_token);

  // test-user (client_) runs a job to the end; bob queues one of his own.
  const std::string mine = submit(small_compression(3), "same-request");
  ASSERT_TRUE(wait_state(mine, v1::Job::SUCCEEDED, 60s));
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression(3);
  request.set_request_id("same-request");  // request ids are per user: a new job for bob
  v1::SubmitJobResponse bobs;
  ASSERT_TRUE(bob->submit(request, &bobs).ok());
  EXPECT_FALSE(bobs.already_existed());
  EXPECT_NE(bobs.job().id(), mine);
  v1::SubmitJobResponse again;
  ASSERT_TRUE(client_->submit(request, &again).ok());
  EXPECT_TRUE(again.already_existed());
  EXPECT_EQ(again.job().id(), mine);

  // Bob cannot see, watch, cancel or download test-user's job: NOT_FOUND,
  // exactly as for an id that does not exist.
  v1::Job job;
  const grpc::Status get = bob->get(mine, &job);
  EXPECT_EQ(get.error_code(), grpc::StatusCode::NOT_FOUND) << get.error_message();
  v1::Job missing;
  const grpc::Status get_missing = bob->get("job-999", &missing);
  EXPECT_EQ(get_missing.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(get.error_message().find("permission"), std::string::npos);
  EXPECT_EQ(watch_status(*bob, mine).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(bob->cancel(mine, &job).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(bob->download(mine, (dir_ / "stolen.h5").string()).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_FALSE(fs::exists(dir_ / "stolen.h5"));
  v1::ListJobsResponse listed;
  ASSERT_TRUE(bob->list(v1::ListJobsRequest(), &listed).ok());
  ASSERT_EQ(listed.jobs_size(), 1);
  EXPECT_EQ(listed.jobs(0).id(), bobs.job().id());

  // Nor test-user bob's.
  EXPECT_EQ(client_->get(bobs.job().id(), &job).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(client_->cancel(bobs.job().id(), &job).error_code(), grpc::StatusCode::NOT_FOUND);
  ASSERT_TRUE(client_->list(v1::ListJobsRequest(), &listed).ok());
  ASSERT_EQ(listed.jobs_size(), 1);
  EXPECT_EQ(listed.jobs(0).id(), mine);
  ASSERT_TRUE(client_->download(mine, (dir_ / "mine.h5").string()).ok());

  // The admin sees and manages both.
  ASSERT_TRUE(admin->list(v1::ListJobsRequest(), &listed).ok());
  EXPECT_EQ(listed.jobs_size(), 2);
  ASSERT_TRUE(admin->get(mine, &job).ok());
  EXPECT_EQ(job.state(), v1::Job::SUCCEEDED);
  EXPECT_TRUE(watch_status(*admin, mine).ok());
  ASSERT_TRUE(admin->download(mine, (dir_ / "admin.h5").string()).ok());
  // Bob's own job: his to cancel (unless the worker was faster).
  const grpc::Status cancelled = bob->cancel(bobs.job().id(), &job);
  EXPECT_TRUE(cancelled.ok() || cancelled.error_code() == grpc::StatusCode::FAILED_PRECONDITION)
      << cancelled.error_message();
}

TEST_F(AuthTest, UnauthenticatedAndRevokedCallsAreRefused) {
  start_server(0);
  v1::Job job;
  v1::ListJobsResponse listed;
  auto anonymous = client_with("");
  const grpc::Status none = anonymous->list(v1::ListJobsRequest(), &listed);
  EXPECT_EQ(none.error_code(), grpc::StatusCode::UNAUTHENTICATED) << none.error_message();
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression(3);
  v1::SubmitJobResponse response;
  EXPECT_EQ(anonymous->submit(request, &response).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(watch_status(*anonymous, "job-1").error_code(), grpc::StatusCode::UNAUTHENTICATED);
  auto forged = client_with("not-a-token-this-server-issued");
  EXPECT_EQ(forged->list(v1::ListJobsRequest(), &listed).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  // A worker token is no user token.
  EXPECT_EQ(client_with(worker_token_)->list(v1::ListJobsRequest(), &listed).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  ASSERT_TRUE(client_->list(v1::ListJobsRequest(), &listed).ok());
  EXPECT_EQ(listed.jobs_size(), 0) << "a refused submit queues nothing";

  // Revocation takes effect on the next call, the server running.
  const std::string carol_token = create_token("carol");
  auto carol = client_with(carol_token);
  ASSERT_TRUE(carol->list(v1::ListJobsRequest(), &listed).ok());
  int code = 0;
  const std::string revoked =
      run_command(server_command() + "token revoke --user carol --data-dir " + data_dir(), &code);
  EXPECT_EQ(code, 0) << revoked;
  const grpc::Status after = carol->list(v1::ListJobsRequest(), &listed);
  EXPECT_EQ(after.error_code(), grpc::StatusCode::UNAUTHENTICATED) << after.error_message();
  EXPECT_NE(after.error_message().find("revoked"), std::string::npos) << after.error_message();
  const std::string tokens = run_command(server_command() + "token list --data-dir " + data_dir(), &code);
  EXPECT_EQ(code, 0);
  EXPECT_NE(tokens.find("carol"), std::string::npos) << tokens;
  EXPECT_NE(tokens.find("test-worker"), std::string::npos) << tokens;
  EXPECT_EQ(tokens.find(carol_token), std::string::npos) << "token list never shows a token";
  EXPECT_EQ(tokens.find(token_), std::string::npos);

  // The CLI: a token file must be 0600 or stricter; no token is exit code 7.
  const std::string cli = "env -u CELLFLOW_TOKEN HOME=" + dir_.string() + " " + CELLFLOW_CLI_EXE +
                          " --timeout-s 5 --server " + address_;
  const std::string no_token = run_command(cli + " list", &code);
  EXPECT_EQ(code, 7) << no_token;
  const fs::path token_file = dir_ / "token";
  std::ofstream(token_file) << token_ << "\n";
  ::chmod(token_file.c_str(), 0644);
  const std::string loose = run_command(cli + " --token-file " + token_file.string() + " list", &code);
  EXPECT_EQ(code, 1) << loose;
  EXPECT_NE(loose.find("chmod 600"), std::string::npos) << loose;
  ::chmod(token_file.c_str(), 0600);
  const std::string ok = run_command(cli + " --token-file " + token_file.string() + " list", &code);
  EXPECT_EQ(code, 0) << ok;
  // The default file, ~/.config/cellflow/token.
  fs::create_directories(dir_ / ".config" / "cellflow");
  fs::copy_file(token_file, dir_ / ".config" / "cellflow" / "token");
  ::chmod((dir_ / ".config" / "cellflow" / "token").c_str(), 0600);
  const std::string from_home = run_command(cli + " list", &code);
  EXPECT_EQ(code, 0) << from_home;
}

TEST_F(AuthTest, WorkerApiOnlyOnItsListenerWithAWorkerCredential) {
  start_server(0);
  v1::LeaseJobResponse leased;
  // The public listener has no worker API, whatever the token.
  auto on_public = worker_stub(address_, worker_token_);
  const grpc::Status public_lease = lease(*on_public, &leased);
  EXPECT_TRUE(public_lease.error_code() == grpc::StatusCode::UNIMPLEMENTED ||
              public_lease.error_code() == grpc::StatusCode::PERMISSION_DENIED)
      << public_lease.error_code() << " " << public_lease.error_message();
  EXPECT_EQ(lease(*worker_stub(address_, token_), &leased).error_code(), grpc::StatusCode::UNIMPLEMENTED);
  // Nor has the worker listener the public API.
  client::ClientOptions options = client_options(token_);
  options.server = worker_address_;
  options.max_attempts = 1;
  client::Client misdirected(options);
  v1::ListJobsResponse listed;
  // (the worker listener's interceptor refuses the user token before the router finds no such method)
  const grpc::Status misdirected_list = misdirected.list(v1::ListJobsRequest(), &listed);
  EXPECT_TRUE(misdirected_list.error_code() == grpc::StatusCode::UNIMPLEMENTED ||
              misdirected_list.error_code() == grpc::StatusCode::PERMISSION_DENIED)
      << misdirected_list.error_code() << " " << misdirected_list.error_message();

  const std::string id = submit(small_compression(3));
  // No credential, a user token, a forged one: no lease.
  const grpc::Status anonymous = lease(*worker_stub(worker_address_, ""), &leased);
  EXPECT_EQ(anonymous.error_code(), grpc::StatusCode::UNAUTHENTICATED) << anonymous.error_message();
  const grpc::Status user = lease(*worker_stub(worker_address_, token_), &leased);
  EXPECT_EQ(user.error_code(), grpc::StatusCode::PERMISSION_DENIED) << user.error_message();
  EXPECT_EQ(lease(*worker_stub(worker_address_, "forged"), &leased).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  // Worker processes without their credential give up (exit 2) and lease nothing.
  Process* bare = start_worker({}, {"CELLFLOW_WORKER_TOKEN="});
  Process* with_user_token = start_worker({}, {"CELLFLOW_WORKER_TOKEN=" + token_});
  ASSERT_TRUE(bare->wait_for(20s));
  ASSERT_TRUE(with_user_token->wait_for(20s));
  EXPECT_EQ(WEXITSTATUS(bare->wait()), 2) << bare->log();
  EXPECT_EQ(WEXITSTATUS(with_user_token->wait()), 2) << with_user_token->log();
  EXPECT_EQ(get(id).state(), v1::Job::QUEUED);
  // A worker token file must be private.
  const fs::path token_file = dir_ / "worker-token";
  std::ofstream(token_file) << worker_token_ << "\n";
  ::chmod(token_file.c_str(), 0640);
  Process* loose = start_worker({"--token-file", token_file.string()}, {"CELLFLOW_WORKER_TOKEN="});
  ASSERT_TRUE(loose->wait_for(20s));
  EXPECT_NE(WEXITSTATUS(loose->wait()), 0);
  EXPECT_NE(loose->log().find("chmod 600"), std::string::npos) << loose->log();
  // With its worker token (here from a 0600 file) a worker runs the job.
  ::chmod(token_file.c_str(), 0600);
  start_worker({"--token-file", token_file.string()}, {"CELLFLOW_WORKER_TOKEN="});
  EXPECT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << v1::Job::State_Name(get(id).state());
  // A revoked worker token leases nothing.
  int code = 0;
  run_command(server_command() + "token revoke --user test-worker --data-dir " + data_dir(), &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(lease(*worker_stub(worker_address_, worker_token_), &leased).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
}

TEST_F(AuthTest, NoAuthOnlyOnLoopbackAndPlaintextOnlyOnLoopbackUnlessInsecureListen) {
  auto refuses = [&](std::vector<std::string> args, const std::string& expected) {
    std::vector<std::string> argv = {CELLFLOW_SERVER_EXE, "--data-dir", data_dir(), "--worker-listen",
                                     "127.0.0.1:0"};
    argv.insert(argv.end(), args.begin(), args.end());
    Process server(argv, (dir_ / "refused.log").string());
    ASSERT_TRUE(server.wait_for(20s));
    EXPECT_EQ(WEXITSTATUS(server.wait()), 1);
    EXPECT_NE(server.log().find(expected), std::string::npos) << server.log();
  };
  refuses({"--listen", "0.0.0.0:0", "--auth", "none"}, "only on loopback");
  refuses({"--listen", "0.0.0.0:0"}, "--tls-cert");
  // --insecure-listen: starts, with a warning.
  {
    std::vector<std::string> argv = {CELLFLOW_SERVER_EXE, "--data-dir",  data_dir(),
                                     "--listen",          "0.0.0.0:0",   "--worker-listen",
                                     "127.0.0.1:0",       "--port-file", (dir_ / "insecure-port").string(),
                                     "--insecure-listen"};
    Process server(argv, (dir_ / "insecure.log").string());
    ASSERT_TRUE(eventually([&] { return fs::exists(dir_ / "insecure-port"); }, 20s)) << server.log();
    EXPECT_NE(server.log().find("plaintext"), std::string::npos) << server.log();
    server.signal(SIGTERM);
    EXPECT_TRUE(server.wait_for(20s));
  }
  // --auth none on loopback: no token needed, the caller is the local admin.
  auth_ = false;
  start_server(0);
  auto anonymous = client_with("");
  const std::string id = submit(small_compression(3));
  v1::Job job;
  EXPECT_TRUE(anonymous->get(id, &job).ok());
  v1::LeaseJobResponse leased;
  EXPECT_TRUE(lease(*worker_stub(worker_address_, ""), &leased).ok());
}

// TLS from files made here: a CA, a server certificate for localhost and
// 127.0.0.1 signed by it, and a second CA that signed nothing of this server.
class TlsTest : public AuthTest {
 protected:
  const std::string openssl = CELLFLOW_OPENSSL;
  void make_certificates() {
    const std::string d = dir_.string();
    const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
    std::ofstream(dir_ / "san.ext") << "subjectAltName=DNS:localhost,IP:127.0.0.1\n"
                                       "basicConstraints=CA:FALSE\n";
    for (const std::string& command : {
             openssl + " req -x509" + ec + " -days 2 -subj /CN=cellflow-test-ca -keyout " + d +
                 "/ca.key -out " + d + "/ca.pem",
             openssl + " req -x509" + ec + " -days 2 -subj /CN=other-ca -keyout " + d + "/other.key -out " +
                 d + "/other.pem",
             openssl + " req" + ec + " -subj /CN=localhost -keyout " + d + "/server.key -out " + d +
                 "/server.csr",
             openssl + " x509 -req -in " + d + "/server.csr -CA " + d + "/ca.pem -CAkey " + d +
                 "/ca.key -CAcreateserial -days 2 -extfile " + d + "/san.ext -out " + d + "/server.pem",
         }) {
      int code = 0;
      const std::string out = run_command(command, &code);
      ASSERT_EQ(code, 0) << command << "\n" << out;
    }
  }
  client::ClientOptions tls_options(const std::string& ca_file) {
    client::ClientOptions options = client_options(token_);
    options.tls = true;
    EXPECT_TRUE(rpc::read_file(ca_file, &options.tls_ca_pem).ok());
    options.max_attempts = 1;
    options.timeout_s = 5;
    return options;
  }
};

TEST_F(TlsTest, ClientWithTheCaConnectsPlaintextAndWrongCaAreRefused) {
  make_certificates();
  ASSERT_FALSE(HasFatalFailure());
  const std::string d = dir_.string();
  client_base_.tls = true;
  ASSERT_TRUE(rpc::read_file(d + "/ca.pem", &client_base_.tls_ca_pem).ok());
  start_server(0, {"--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key"});
  // A worker over TLS on the worker listener runs the job of a TLS client.
  start_worker({"--tls-ca", d + "/ca.pem"});
  const std::string id = submit(small_compression(3));
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << v1::Job::State_Name(get(id).state());
  ASSERT_TRUE(client_->download(id, d + "/tls.h5").ok());

  v1::ListJobsResponse listed;
  client::ClientOptions plaintext = client_options(token_);
  plaintext.tls = false;
  plaintext.max_attempts = 1;
  plaintext.timeout_s = 5;
  const grpc::Status plain = client::Client(plaintext).list(v1::ListJobsRequest(), &listed);
  EXPECT_FALSE(plain.ok());
  EXPECT_EQ(plain.error_code(), grpc::StatusCode::UNAVAILABLE) << plain.error_message();
  const grpc::Status wrong =
      client::Client(tls_options(d + "/other.pem")).list(v1::ListJobsRequest(), &listed);
  EXPECT_FALSE(wrong.ok());
  EXPECT_EQ(wrong.error_code(), grpc::StatusCode::UNAVAILABLE) << wrong.error_message();
  EXPECT_TRUE(client::Client(tls_options(d + "/ca.pem")).list(v1::ListJobsRequest(), &listed).ok());
  // A worker without the CA cannot reach the worker listener.
  v1::LeaseJobResponse leased;
  EXPECT_EQ(lease(*worker_stub(worker_address_, worker_token_), &leased).error_code(),
            grpc::StatusCode::UNAVAILABLE);

  // The CLI: --tls-ca or CELLFLOW_TLS_CA.
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --timeout-s 5 --server " + address_;
  int code = 0;
  std::string out = run_command(cli + " --tls-ca " + d + "/ca.pem get " + id, &code);
  EXPECT_EQ(code, 0) << out;
  out = run_command("CELLFLOW_TLS_CA=" + d + "/ca.pem " + cli + " get " + id, &code);
  EXPECT_EQ(code, 0) << out;
  out = run_command(cli + " get " + id, &code);
  EXPECT_EQ(code, 6) << out;  // plaintext against TLS: unreachable
}

TEST_F(TlsTest, MutualTlsNeedsAClientCertificate) {
  make_certificates();
  ASSERT_FALSE(HasFatalFailure());
  const std::string d = dir_.string();
  // A client certificate signed by the CA.
  for (const std::string& command : {
           openssl +
               " req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj /CN=client -keyout " + d +
               "/client.key -out " + d + "/client.csr",
           openssl + " x509 -req -in " + d + "/client.csr -CA " + d + "/ca.pem -CAkey " + d +
               "/ca.key -CAcreateserial -days 2 -out " + d + "/client.pem",
       }) {
    int code = 0;
    const std::string out = run_command(command, &code);
    ASSERT_EQ(code, 0) << command << "\n" << out;
  }
  client_base_.tls = true;
  ASSERT_TRUE(rpc::read_file(d + "/ca.pem", &client_base_.tls_ca_pem).ok());
  ASSERT_TRUE(rpc::read_file(d + "/client.pem", &client_base_.tls_cert_pem).ok());
  ASSERT_TRUE(rpc::read_file(d + "/client.key", &client_base_.tls_key_pem).ok());
  start_server(
      1, {"--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key", "--tls-client-ca", d + "/ca.pem"});
  // The local worker (private socket) runs the job; the client presents its certificate.
  const std::string id = submit(small_compression(3));
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << v1::Job::State_Name(get(id).state());
  v1::ListJobsResponse listed;
  client::ClientOptions no_certificate = tls_options(d + "/ca.pem");
  no_certificate.tls_cert_pem.clear();
  no_certificate.tls_key_pem.clear();
  const grpc::Status without = client::Client(no_certificate).list(v1::ListJobsRequest(), &listed);
  EXPECT_EQ(without.error_code(), grpc::StatusCode::UNAVAILABLE) << without.error_message();
}

}  // namespace
}  // namespace cellflow::testing
