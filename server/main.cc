// cellflow-server: see server/server.h and deploy/README.md.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>

#include "physics/core/passive_threads.h"
#include "server/auth.h"
#include "server/server.h"
#include "server/store.h"

namespace {

using namespace cellflow;

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string time_text(std::int64_t ms) {
  if (ms == 0) return "-";
  const std::time_t seconds = ms / 1000;
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&seconds));
  return buffer;
}

StatusOr<std::unique_ptr<server::Store>> open_store(const std::string& data_dir) {
  std::error_code error;
  std::filesystem::create_directories(data_dir, error);
  server::StoreOptions options;
  options.path = (std::filesystem::path(data_dir) / "cellflow.sqlite").string();
  return server::Store::open(options);
}

struct TokenCommand {
  std::string user;
  bool admin = false;
  bool worker = false;
  std::int64_t id = 0;
};

// `token create`: the token on stdout, alone, once; only its hash is stored.
int token_create(const std::string& data_dir, const TokenCommand& command) {
  if (!server::valid_user_name(command.user)) {
    std::fprintf(stderr, "cellflow-server: --user must be 1..64 of A-Z a-z 0-9 . _ @ -\n");
    return 1;
  }
  if (command.admin && command.worker) {
    std::fprintf(stderr, "cellflow-server: a token is either --admin or --worker\n");
    return 1;
  }
  auto store = open_store(data_dir);
  if (!store.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", store.status().to_string().c_str());
    return 1;
  }
  auto token = server::generate_token();
  if (!token.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", token.status().to_string().c_str());
    return 1;
  }
  const std::string role = command.worker ? "worker" : command.admin ? "admin" : "user";
  auto id = (*store)->add_token(command.user, role, server::hash_token(*token), now_ms());
  if (!id.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", id.status().to_string().c_str());
    return 1;
  }
  std::printf("%s\n", token->c_str());
  if (::isatty(STDERR_FILENO)) {
    std::fprintf(stderr,
                 "token %lld (%s, %s) created; it is shown only this once. Clients read it from "
                 "CELLFLOW_TOKEN or a 0600 file (~/.config/cellflow/token), workers from "
                 "CELLFLOW_WORKER_TOKEN or --token-file.\n",
                 static_cast<long long>(*id), command.user.c_str(), role.c_str());
  }
  return 0;
}

int token_list(const std::string& data_dir) {
  auto store = open_store(data_dir);
  if (!store.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", store.status().to_string().c_str());
    return 1;
  }
  auto tokens = (*store)->list_tokens();
  if (!tokens.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", tokens.status().to_string().c_str());
    return 1;
  }
  std::printf("%-6s %-24s %-7s %-21s %s\n", "id", "user", "role", "created", "revoked");
  for (const auto& t : *tokens) {
    std::printf("%-6lld %-24s %-7s %-21s %s\n", static_cast<long long>(t.id), t.user.c_str(), t.role.c_str(),
                time_text(t.create_ms).c_str(), time_text(t.revoke_ms).c_str());
  }
  return 0;
}

int token_revoke(const std::string& data_dir, const TokenCommand& command) {
  if ((command.id > 0) == !command.user.empty()) {
    std::fprintf(stderr, "cellflow-server: token revoke needs --user NAME or --id N\n");
    return 1;
  }
  auto store = open_store(data_dir);
  if (!store.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", store.status().to_string().c_str());
    return 1;
  }
  auto revoked = (*store)->revoke_tokens(command.id, command.user, now_ms());
  if (!revoked.ok()) {
    std::fprintf(stderr, "cellflow-server: %s\n", revoked.status().to_string().c_str());
    return 1;
  }
  std::printf("%d token(s) revoked\n", *revoked);
  return *revoked > 0 ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  cellflow::server::ServerOptions options;
  std::string log_level = "info";
  CLI::App app{"cellflow-server: the cellflow job service (gRPC API, SQLite queue, local worker pool)"};
  app.add_option("--listen", options.listen, "address to listen on, host:port (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--data-dir", options.data_dir, "directory of the database and the result files")
      ->capture_default_str();
  app.add_option("--port-file", options.port_file, "write the port listened on to this file");
  app.add_option("--workers", options.workers, "local cellflow-worker processes to run and supervise")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024));
  app.add_option("--worker-path", options.worker_path,
                 "cellflow-worker executable (default: beside this binary)");
  app.add_option("--worker-arg", options.worker_args, "extra argument for local workers (repeatable)")
      ->allow_extra_args(false);
  app.add_option("--lease-ttl-s", options.lease_ttl_s,
                 "a job whose worker stops reporting for this long is requeued")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 3600.0));
  app.add_option("--heartbeat-interval-s", options.heartbeat_interval_s,
                 "how often workers heartbeat (bounds how fast a cancel reaches them)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 60.0));
  app.add_option("--max-attempts", options.max_attempts, "expired leases before a job FAILS")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--memory-limit-bytes", options.memory_limit_bytes,
                 "refuse jobs whose memory estimate exceeds this (-1: 80 % of RAM, 0: no limit)")
      ->capture_default_str();
  app.add_option("--grace-s", options.grace_s, "on SIGTERM, how long running jobs may finish")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_flag("--sqlite-synchronous-full", options.sqlite_synchronous_full,
               "fsync every commit (survives power loss; default survives process crashes)");
  app.add_option("--worker-listen", options.worker_listen,
                 "address of the worker API (its own listener and credential): host:port or unix:PATH")
      ->capture_default_str();
  app.add_option("--worker-port-file", options.worker_port_file,
                 "write the port of the worker listener to this file");
  app.add_option("--auth", options.auth,
                 "token: every call needs a bearer token (cellflow-server token create); none: no "
                 "tokens, every caller is the local admin (only with loopback listeners)")
      ->capture_default_str()
      ->check(CLI::IsMember({"token", "none"}));
  app.add_option("--tls-cert", options.tls_cert, "PEM certificate (chain) of both listeners: serve TLS");
  app.add_option("--tls-key", options.tls_key, "PEM private key of --tls-cert");
  app.add_option("--tls-client-ca", options.tls_client_ca,
                 "PEM CA: clients and workers must present a certificate it signed (mTLS)");
  app.add_flag("--insecure-listen", options.insecure_listen,
               "allow a listener reachable from other hosts without TLS (tokens travel in plaintext)");
  app.add_option("--max-mesh-bytes", options.max_mesh_bytes, "largest mesh UploadMesh accepts")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40));
  app.add_option("--max-checkpoint-bytes", options.max_checkpoint_bytes,
                 "largest checkpoint UploadCheckpoint accepts (0: 4 x the job's memory estimate + 64 MiB)")
      ->capture_default_str();
  app.add_option("--max-run-time-s", options.max_run_time_s,
                 "an attempt running longer loses its lease, heartbeats or not (0: no limit)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  // --executor slurm (deploy/README.md, "Slurm"): workers by sbatch while jobs wait.
  app.add_option("--executor", options.executor,
                 "local: the --workers pool only; slurm: also submit worker job arrays with sbatch when "
                 "jobs are queued and no worker is free")
      ->capture_default_str()
      ->check(CLI::IsMember({"local", "slurm"}));
  app.add_option("--slurm-max-workers", options.slurm.max_workers,
                 "Slurm workers (pending + running) submitted at most")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--slurm-sbatch", options.slurm.sbatch, "sbatch executable")->capture_default_str();
  app.add_option("--slurm-squeue", options.slurm.squeue, "squeue executable")->capture_default_str();
  app.add_option("--slurm-partition", options.slurm.partition, "sbatch --partition of the workers");
  app.add_option("--slurm-arg", options.slurm.sbatch_args,
                 "extra sbatch option, e.g. --slurm-arg=--time=04:00:00 (repeatable)")
      ->allow_extra_args(false);
  app.add_option("--slurm-job-name", options.slurm.job_name, "sbatch --job-name")->capture_default_str();
  app.add_option("--slurm-worker-path", options.slurm_worker.path,
                 "cellflow-worker on the compute nodes (default: beside this binary)");
  app.add_option("--slurm-worker-server", options.slurm_worker.server,
                 "the worker listener as the compute nodes dial it (default: the bound --worker-listen)");
  app.add_option("--slurm-worker-token-file", options.slurm_worker.token_file,
                 "worker token file (mode 0600) as the compute nodes see it");
  app.add_option("--slurm-idle-exit-s", options.slurm_worker.idle_exit_s,
                 "a Slurm worker exits after this long without a job")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1e7));
  app.add_option("--slurm-worker-arg", options.slurm_worker.args,
                 "extra argument for Slurm workers, e.g. --slurm-worker-arg=--threads=8 (repeatable)")
      ->allow_extra_args(false);
  double slurm_poll_s = 2.0;
  app.add_option("--slurm-poll-s", slurm_poll_s, "how often the executor looks at the queue and squeue")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  double slurm_startup_s = 30.0;
  app.add_option("--slurm-startup-s", slurm_startup_s,
                 "a Slurm worker that started this recently counts as free (it is still connecting)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));

  double slurm_min_life_s = 5.0;
  app.add_option("--slurm-min-worker-life-s", slurm_min_life_s,
                 "a Slurm worker that ends sooner failed to start: the next sbatch waits (backoff)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));

  // cellflow-server token create|list|revoke: API tokens in the database of --data-dir.
  auto* token = app.add_subcommand("token", "manage API tokens (in the database of --data-dir)");
  token->require_subcommand(1);
  token->fallthrough();
  TokenCommand command;
  auto* create = token->add_subcommand("create", "create a token and print it (once; only its hash is kept)");
  create->add_option("--user", command.user, "the identity the token stands for (owner of its jobs)")
      ->required();
  create->add_flag("--admin", command.admin, "the token sees and manages every user's jobs");
  create->add_flag("--worker", command.worker, "a worker credential: the worker API only");
  create->fallthrough();
  auto* list =
      token->add_subcommand("list", "list tokens: id, user, role, created, revoked (never the token)");
  list->fallthrough();
  auto* revoke = token->add_subcommand("revoke", "revoke the tokens of a user, or one token by id");
  revoke->add_option("--user", command.user, "revoke every token of this user");
  revoke->add_option("--id", command.id, "revoke the token with this id");
  revoke->fallthrough();

  CLI11_PARSE(app, argc, argv);
  options.slurm.poll_interval = std::chrono::milliseconds(static_cast<std::int64_t>(slurm_poll_s * 1000));
  options.slurm.startup_grace = std::chrono::milliseconds(static_cast<std::int64_t>(slurm_startup_s * 1000));
  options.slurm.min_worker_life =
      std::chrono::milliseconds(static_cast<std::int64_t>(slurm_min_life_s * 1000));
  spdlog::set_level(spdlog::level::from_str(log_level));
  if (create->parsed()) return token_create(options.data_dir, command);
  if (list->parsed()) return token_list(options.data_dir);
  if (revoke->parsed()) return token_revoke(options.data_dir, command);
  return cellflow::server::run_server(options);
}
