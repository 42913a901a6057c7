#include "server/server.h"

#include <fcntl.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "rpc/rpc.h"
#include "server/auth.h"
#include "server/grpc_services.h"
#include "server/job_service.h"
#include "server/notifier.h"
#include "server/store.h"
#include "server/worker_pool.h"

namespace cellflow::server {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

std::string default_worker_path() {
  std::error_code error;
  const fs::path self = fs::read_symlink("/proc/self/exe", error);
  return error ? "cellflow-worker" : (self.parent_path() / "cellflow-worker").string();
}

std::int64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page_size > 0 ? static_cast<std::int64_t>(pages) * page_size : 0;
}

// host:port -> the host part; "[::]:0" -> "[::]".
std::string host_of(const std::string& address) {
  const auto colon = address.rfind(':');
  return colon == std::string::npos ? address : address.substr(0, colon);
}

bool write_port_file(const std::string& path, int port) {
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << port << "\n";
    if (!out) return false;
  }
  return std::rename(temporary.c_str(), path.c_str()) == 0;
}

// TLS credentials of both listeners when a certificate is given, else plaintext.
StatusOr<std::shared_ptr<grpc::ServerCredentials>> server_credentials(const ServerOptions& options) {
  if (options.tls_cert.empty() && options.tls_key.empty()) {
    if (!options.tls_client_ca.empty())
      return Status(StatusCode::kInvalidArgument, "--tls-client-ca needs --tls-cert and --tls-key");
    return grpc::InsecureServerCredentials();
  }
  if (options.tls_cert.empty() || options.tls_key.empty())
    return Status(StatusCode::kInvalidArgument, "TLS needs both --tls-cert and --tls-key");
  grpc::SslServerCredentialsOptions ssl;
  grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
  if (Status s = rpc::read_file(options.tls_key, &pair.private_key); !s.ok()) return s;
  if (Status s = rpc::read_file(options.tls_cert, &pair.cert_chain); !s.ok()) return s;
  ssl.pem_key_cert_pairs.push_back(std::move(pair));
  if (!options.tls_client_ca.empty()) {
    if (Status s = rpc::read_file(options.tls_client_ca, &ssl.pem_root_certs); !s.ok()) return s;
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(ssl);
}

// The rules of server/README.md ("Authentication"): --auth none only with
// every listener on loopback; a listener reachable from other hosts needs
// TLS, unless --insecure-listen (tokens then travel in plaintext).
Status check_listeners(const ServerOptions& options) {
  if (options.auth != "token" && options.auth != "none")
    return {StatusCode::kInvalidArgument, "--auth must be token or none"};
  const bool tls = !options.tls_cert.empty();
  for (const std::string* address : {&options.listen, &options.worker_listen}) {
    if (is_loopback_address(*address)) continue;
    if (options.auth == "none") {
      return {StatusCode::kInvalidArgument,
              "--auth none serves anyone who can connect: it is allowed only on loopback addresses "
              "(127.0.0.0/8, ::1, localhost, unix:), not on " +
                  *address};
    }
    if (!tls && !options.insecure_listen) {
      return {StatusCode::kInvalidArgument,
              *address +
                  " is reachable from other hosts: give --tls-cert and --tls-key (tokens would "
                  "travel in plaintext), or --insecure-listen on a network you trust"};
    }
    if (!tls) spdlog::warn("--insecure-listen: {} serves plaintext gRPC; tokens can be sniffed", *address);
  }
  return {};
}

// The chosen port of a listener ("host:port" with port 0 replaced).
std::string bound_address(const std::string& address, int port) {
  if (address.rfind("unix", 0) == 0) return address;
  return host_of(address) + ":" + std::to_string(port);
}

// The shutdown sequence: drain (no new work; running jobs may finish for
// grace_s), stop the local workers (they hand their jobs back), requeue what
// still runs elsewhere, stop the gRPC server.
class Shutdown {
 public:
  Shutdown(boost::asio::io_context& io, JobService& jobs, Notifier& notifier, WorkerPool& pool,
           grpc::Server& server, grpc::Server& worker_server, double grace_s)
      : io_(io),
        jobs_(jobs),
        notifier_(notifier),
        pool_(pool),
        server_(server),
        worker_server_(worker_server),
        grace_s_(grace_s),
        poll_(io) {}

  void begin(int signal_number) {
    if (phase_ == Phase::kDraining) {
      spdlog::warn("second signal: not waiting for running jobs");
      stop_workers();
      return;
    }
    if (phase_ != Phase::kRunning) return;
    phase_ = Phase::kDraining;
    spdlog::info("signal {}: draining; running jobs may finish within {} s", signal_number, grace_s_);
    jobs_.set_draining(true);
    if (auto* health = server_.GetHealthCheckService()) health->SetServingStatus(false);
    if (auto* health = worker_server_.GetHealthCheckService()) health->SetServingStatus(false);
    deadline_ =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(static_cast<int>(grace_s_ * 1000));
    poll();
  }

 private:
  enum class Phase { kRunning, kDraining, kStoppingWorkers, kDone };

  void poll() {
    if (phase_ != Phase::kDraining) return;
    const std::int64_t running = jobs_.running_jobs();
    if (running <= 0 || std::chrono::steady_clock::now() >= deadline_) {
      if (running > 0) spdlog::info("grace period over; {} job(s) still running", running);
      stop_workers();
      return;
    }
    // Polled at 10 Hz only while draining: completions are rare and this
    // keeps the shutdown path independent of the notifier.
    poll_.expires_after(100ms);
    poll_.async_wait([this](const boost::system::error_code& error) {
      if (!error) poll();
    });
  }

  void stop_workers() {
    phase_ = Phase::kStoppingWorkers;
    poll_.cancel();
    pool_.stop(10s, [this] { finish(); });
  }

  void finish() {
    if (phase_ == Phase::kDone) return;
    phase_ = Phase::kDone;
    const int requeued = jobs_.release_all_running("the server shut down; the job will run again");
    if (requeued > 0) spdlog::info("{} running job(s) handed back to the queue", requeued);
    notifier_.shutdown();
    const auto deadline = std::chrono::system_clock::now() + 2s;
    server_.Shutdown(deadline);
    worker_server_.Shutdown(deadline);
    io_.stop();
  }

  boost::asio::io_context& io_;
  JobService& jobs_;
  Notifier& notifier_;
  WorkerPool& pool_;
  grpc::Server& server_;
  grpc::Server& worker_server_;
  double grace_s_;
  boost::asio::steady_timer poll_;
  Phase phase_ = Phase::kRunning;
  std::chrono::steady_clock::time_point deadline_;
};

// An exclusive lock on data_dir/cellflow.lock for the life of the process:
// two servers on one database would both lease and reap. Returns the fd (kept
// open), or -1 with *message set.
int lock_data_dir(const fs::path& dir, std::string* message) {
  const fs::path path = dir / "cellflow.lock";
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    *message = "cannot open the lock file " + path.string();
    return -1;
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    char holder[32] = {0};
    const ssize_t n = ::pread(fd, holder, sizeof holder - 1, 0);
    std::string pid = n > 0 ? std::string(holder, static_cast<std::size_t>(n)) : "";
    while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
    *message = "data directory " + dir.string() + " is in use by another cellflow-server" +
               (pid.empty() ? "" : " (pid " + pid + ")") + "; stop it or choose another --data-dir";
    ::close(fd);
    return -1;
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, pid.data(), pid.size(), 0);
  return fd;
}

void schedule_reaper(boost::asio::steady_timer& timer, JobService& jobs, std::chrono::milliseconds period) {
  timer.expires_after(period);
  timer.async_wait([&timer, &jobs, period](const boost::system::error_code& error) {
    if (error) return;
    jobs.reap_expired_leases();
    schedule_reaper(timer, jobs, period);
  });
}

}  // namespace

int run_server(const ServerOptions& options) {
  if (Status s = check_listeners(options); !s.ok()) {
    spdlog::error("{}", s.message());
    return 1;
  }
  std::error_code error;
  fs::create_directories(options.data_dir, error);
  if (error) {
    spdlog::error("cannot create data directory {}: {}", options.data_dir, error.message());
    return 1;
  }
  std::string lock_message;
  const int lock_fd = lock_data_dir(options.data_dir, &lock_message);
  if (lock_fd < 0) {
    spdlog::error("{}", lock_message);
    return 1;
  }
  StoreOptions store_options;
  store_options.path = (fs::path(options.data_dir) / "cellflow.sqlite").string();
  store_options.max_attempts = options.max_attempts;
  store_options.synchronous_full = options.sqlite_synchronous_full;
  auto store = Store::open(store_options);
  if (!store.ok()) {
    spdlog::error("{}", store.status().to_string());
    return 1;
  }
  const auto ttl_ms = static_cast<std::int64_t>(options.lease_ttl_s * 1000);
  const auto now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  if (Status s = (*store)->extend_running_leases(now_ms, ttl_ms); !s.ok()) {
    spdlog::error("{}", s.to_string());
    return 1;
  }
  // Jobs RUNNING when the server stopped: their attempt is not charged (a
  // worker's hand-back may not have reached a crashed server).
  if (Status s = (*store)->forgive_running_attempts(); !s.ok()) {
    spdlog::error("{}", s.to_string());
    return 1;
  }
  spdlog::info("database {} (schema version {}): {} queued, {} running", store_options.path,
               (*store)->schema_version(), (*store)->count(v1::Job::QUEUED),
               (*store)->count(v1::Job::RUNNING));

  Notifier notifier;
  JobServiceOptions service_options;
  service_options.data_dir = options.data_dir;
  service_options.memory_limit_bytes =
      options.memory_limit_bytes >= 0 ? options.memory_limit_bytes : physical_memory_bytes() / 10 * 8;
  service_options.lease_ttl_s = options.lease_ttl_s;
  service_options.heartbeat_interval_s = options.heartbeat_interval_s;
  service_options.max_mesh_bytes =
      static_cast<std::uint64_t>(std::max<std::int64_t>(options.max_mesh_bytes, 0));
  service_options.max_run_time_s = options.max_run_time_s;
  service_options.max_checkpoint_bytes = std::max<std::int64_t>(options.max_checkpoint_bytes, 0);
  JobService jobs(**store, notifier, service_options);
  // Authentication: one verdict per call from each listener's interceptor.
  const AuthMode auth_mode = options.auth == "none" ? AuthMode::kNone : AuthMode::kToken;
  Authenticator authenticator((*store).get(), auth_mode);
  // The local workers' credential: random per server start, kept in memory
  // only (as a hash) and handed to them in their environment.
  std::string local_worker_secret;
  if (options.workers > 0) {
    auto secret = generate_token();
    if (!secret.ok()) {
      spdlog::error("{}", secret.status().to_string());
      return 1;
    }
    local_worker_secret = *secret;
    authenticator.set_local_worker_secret(local_worker_secret);
  }
  if (auth_mode == AuthMode::kNone) {
    spdlog::warn("--auth none: no tokens are checked; every caller is the local admin (loopback only)");
  } else if ((*store)->count_tokens() == 0) {
    spdlog::warn(
        "no token exists yet: create one with `cellflow-server token create --user NAME --data-dir {}`",
        options.data_dir);
  }
  CallAuth public_calls, worker_calls;
  // Uploads of the previous run can never finish: the workers upload again.
  if (const int removed = jobs.remove_all_uploads(); removed > 0)
    spdlog::info("removed {} unfinished upload(s)", removed);
  CellflowServiceImpl public_api(jobs, &public_calls);
  WorkerServiceImpl worker_api(jobs, &worker_calls);

  auto credentials = server_credentials(options);
  if (!credentials.ok()) {
    spdlog::error("{}", credentials.status().message());
    return 1;
  }
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  // Two servers: the public API on --listen, the worker API on
  // --worker-listen (and, for the local pool, a private abstract Unix
  // socket), so that reflection and routing of each list only its service.
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(options.listen, *credentials, &port);
  builder.RegisterService(&public_api);
  {
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> interceptors;
    interceptors.push_back(
        std::make_unique<AuthInterceptorFactory>(authenticator, Authenticator::Api::kPublic, public_calls));
    builder.experimental().SetInterceptorCreators(std::move(interceptors));
  }
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    spdlog::error("cannot listen on {}", options.listen);
    return 1;
  }
  grpc::ServerBuilder worker_builder;
  int worker_port = 0;
  worker_builder.AddListeningPort(options.worker_listen, *credentials, &worker_port);
  const std::string local_socket = "unix-abstract:cellflow-workers-" + std::to_string(::getpid()) + "-" +
                                   hash_token(local_worker_secret).substr(0, 16);
  if (options.workers > 0) worker_builder.AddListeningPort(local_socket, grpc::InsecureServerCredentials());
  worker_builder.RegisterService(&worker_api);
  {
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> interceptors;
    interceptors.push_back(
        std::make_unique<AuthInterceptorFactory>(authenticator, Authenticator::Api::kWorker, worker_calls));
    worker_builder.experimental().SetInterceptorCreators(std::move(interceptors));
  }
  std::unique_ptr<grpc::Server> worker_server = worker_builder.BuildAndStart();
  if (!worker_server || worker_port == 0) {
    spdlog::error("cannot listen on {} (--worker-listen)", options.worker_listen);
    return 1;
  }
  const std::string host = host_of(options.listen);
  const char* security = options.tls_cert.empty() ? "plaintext" : "TLS";
  std::cout << "cellflow-server listening on " << host << ":" << port << " (" << security << ", auth "
            << options.auth << "); worker API on " << bound_address(options.worker_listen, worker_port)
            << std::endl;
  if (!options.port_file.empty() && !write_port_file(options.port_file, port)) {
    spdlog::error("cannot write {}", options.port_file);
    return 1;
  }
  if (!options.worker_port_file.empty() && !write_port_file(options.worker_port_file, worker_port)) {
    spdlog::error("cannot write {}", options.worker_port_file);
    return 1;
  }

  boost::asio::io_context io;
  WorkerPoolOptions pool_options;
  pool_options.count = options.workers;
  pool_options.worker_path = options.worker_path.empty() ? default_worker_path() : options.worker_path;
  // Local workers dial the private socket, whatever the listeners are.
  pool_options.server_address = local_socket;
  pool_options.worker_token = local_worker_secret;
  pool_options.extra_args = options.worker_args;
  WorkerPool pool(io, pool_options);
  pool.start();

  // --executor slurm: workers by sbatch while jobs wait and none is free.
  std::unique_ptr<SlurmExecutor> slurm;
  if (options.executor == "slurm") {
    SlurmExecutorOptions slurm_options = options.slurm;
    if (Status s = configure_slurm_executor(
            slurm_options, options.slurm_worker, options.data_dir, default_worker_path(),
            bound_address(options.worker_listen, worker_port), auth_mode == AuthMode::kToken);
        !s.ok()) {
      spdlog::error("{}", s.to_string());
      return 1;
    }
    slurm = std::make_unique<SlurmExecutor>(std::move(slurm_options), [&jobs]() -> SlurmDemand {
      if (jobs.draining()) return {};  // shutting down: no new workers
      return {jobs.queued_jobs(), jobs.waiting_workers()};
    });
    slurm->start();
  }

  boost::asio::steady_timer reaper(io);
  const auto reap_period = std::clamp(std::chrono::milliseconds(ttl_ms / 4), std::chrono::milliseconds(50),
                                      std::chrono::milliseconds(1000));
  schedule_reaper(reaper, jobs, reap_period);

  Shutdown shutdown(io, jobs, notifier, pool, *server, *worker_server, options.grace_s);
  boost::asio::signal_set signals(io, SIGINT, SIGTERM);
  std::function<void()> wait_signal = [&] {
    signals.async_wait([&](const boost::system::error_code& e, int signal_number) {
      if (e) return;
      shutdown.begin(signal_number);
      wait_signal();
    });
  };
  wait_signal();

  io.run();
  if (slurm) slurm->stop();
  server->Wait();
  worker_server->Wait();
  jobs.remove_all_uploads();
  spdlog::info("cellflow-server stopped");
  ::close(lock_fd);
  return 0;
}

}  // namespace cellflow::server
